#include "mtcal/drivers/probes/driver.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "mtcal/error.h"

namespace mtcal::drivers::probes {

ProbeBoxDevice::ProbeBoxDevice(std::unique_ptr<Transport> transport, std::string uri, Timeouts timeouts)
    : LineDevice(std::move(transport), std::move(uri), timeouts, kMaxLineBytes) {
  // A stream or triggered latching left running by an earlier session: stop it (its lines
  // before the OK are skipped).
  parseOk(transact(encodeStream(false)));
  parseOk(transact(encodeTrigger(false)));
  identity_ = parseIdentity(transact(encodeIdentify()));
  channels_ = parseChannels(transact(encodeChannels()));
  spdlog::info("{}: {} {} serial {} firmware {}, {} channels of +-{} mm", this->uri(), identity_.maker, identity_.model,
               identity_.serial, identity_.firmware, channels_.count, channels_.range_mm);
}

ProbeBoxDevice::~ProbeBoxDevice() {
  if (streaming()) {
    try {
      stopStream();
    } catch (...) {  // NOLINT(bugprone-empty-catch): destructor; the error was the caller's to fetch
    }
  }
}

DeviceInfo ProbeBoxDevice::info() const {
  return {uri(), "probes", identity_.model, identity_.serial, identity_.firmware};
}

std::vector<double> ProbeBoxDevice::readAll() {
  const auto readings = parseValues(transact(encodeRead(0)), channels_.count);
  std::vector<double> out;
  for (std::size_t i = 0; i < readings.size(); ++i) {
    if (readings[i].status != ChannelStatus::kOk) {
      throw DeviceError(fmt::format("{}: channel {}: {} ({:.4f} mm)", uri(), i + 1, statusName(readings[i].status),
                                    readings[i].value_mm));
    }
    out.push_back(readings[i].value_mm);
  }
  return out;
}

void ProbeBoxDevice::zero(int channel) { parseOk(transact(encodeZero(channel))); }

void ProbeBoxDevice::startStream(std::uint32_t rate_hz, SampleSink& sink) {
  if (streaming()) throw DeviceError(uri() + ": already streaming");
  if (rate_hz < 1 || rate_hz > kMaxRateHz)
    throw InputError(fmt::format("{}: rate {} Hz is not 1..{}", uri(), rate_hz, kMaxRateHz));
  parseOk(transact(encodeRate(rate_hz)));
  parseOk(transact(encodeStream(true)));
  triggered_ = false;
  startReader("mtcal-probe-rd", sink);
}

void ProbeBoxDevice::startTriggered(SampleSink& sink) {
  if (streaming()) throw DeviceError(uri() + ": already streaming");
  parseOk(transact(encodeTrigger(true)));
  triggered_ = true;
  // Latches come when the trigger does (a logger's record every 1 s .. 1 day): no stall
  // shorter than that; the caller watches for a late latch itself.
  startReader("mtcal-probe-rd", sink, kMaxTriggerGap);
}

bool ProbeBoxDevice::isStreamLine(const std::string& line) const { return probes::isStreamLine(line); }

void ProbeBoxDevice::onStreamLine(const std::string& line) {
  const StreamLine s = parseStreamLine(line, channels_.count);
  samples_buffer_.clear();
  for (std::size_t c = 0; c < s.channels.size(); ++c) {
    Sample sample;
    sample.seq = s.seq;
    sample.device_time_ns = s.time_us * 1000;
    sample.value = s.channels[c].value_mm;
    sample.channel = static_cast<int>(c) + 1;
    sample.beam_ok = s.channels[c].status == ChannelStatus::kOk;
    samples_buffer_.push_back(sample);
  }
  deliver(s.seq, samples_buffer_);
}

StreamStats ProbeBoxDevice::stopStream() {
  if (!streaming()) return stats();
  stopReader(triggered_ ? encodeTrigger(false) : encodeStream(false), parseOk);
  return stats();
}

std::vector<StreamChannel> ProbeBoxDevice::streamChannels() const {
  std::vector<StreamChannel> out;
  for (int c = 1; c <= channels_.count; ++c) {
    out.push_back({c, fmt::format("ch{}", c), "displacement", "mm", "", ""});
  }
  return out;
}

}  // namespace mtcal::drivers::probes
