#include "mtcal/drivers/logger/driver.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <limits>

#include "mtcal/error.h"

namespace mtcal::drivers::logger {

TemperatureLoggerDevice::TemperatureLoggerDevice(std::unique_ptr<Transport> transport, std::string uri,
                                                 LineTimeouts timeouts)
    : LineDevice(std::move(transport), std::move(uri), timeouts, kMaxLineBytes) {
  parseOk(transact(encodeLog(0)));
  identity_ = parseIdentity(transact(encodeIdentify()));
  channels_ = parseChannels(transact(encodeChannels()));
  spdlog::info("{}: {} {} serial {} firmware {}, {} channels at {} K", this->uri(), identity_.maker, identity_.model,
               identity_.serial, identity_.firmware, channels_.count, channels_.resolution_k);
}

TemperatureLoggerDevice::~TemperatureLoggerDevice() {
  if (streaming()) {
    try {
      stopStream();
    } catch (...) {  // NOLINT(bugprone-empty-catch): destructor; the error was the caller's to fetch
    }
  }
}

DeviceInfo TemperatureLoggerDevice::info() const {
  return {uri(), "logger", identity_.model, identity_.serial, identity_.firmware};
}

Record TemperatureLoggerDevice::read() { return parseReading(transact(encodeRead()), channels_.count); }

void TemperatureLoggerDevice::startLogging(std::chrono::seconds interval, SampleSink& sink) {
  if (streaming()) throw DeviceError(uri() + ": already logging");
  if (interval.count() < 1 || interval.count() > kMaxIntervalS) {
    throw InputError(fmt::format("{}: logging interval {} s is not 1..{} s", uri(), interval.count(), kMaxIntervalS));
  }
  if (timeouts().stall <= interval) {
    throw InputError(fmt::format("{}: the stall timeout ({} ms) must exceed the logging interval ({} s)", uri(),
                                 timeouts().stall.count(), interval.count()));
  }
  parseOk(transact(encodeLog(static_cast<std::uint32_t>(interval.count()))));
  startReader("mtcal-logger-rd", sink);
}

void TemperatureLoggerDevice::startStream(std::uint32_t rate_hz, SampleSink& sink) {
  if (rate_hz != 1)
    throw InputError(fmt::format("{}: a temperature logger logs at most once a second, not {} Hz", uri(), rate_hz));
  startLogging(std::chrono::seconds(1), sink);
}

bool TemperatureLoggerDevice::isStreamLine(const std::string& line) const { return isRecordLine(line); }

void TemperatureLoggerDevice::onStreamLine(const std::string& line) {
  const Record r = parseRecord(line, channels_.count);
  samples_buffer_.clear();
  for (std::size_t c = 0; c < r.channels.size(); ++c) {
    Sample s;
    s.seq = r.index;
    s.device_time_ns = r.time_ms * 1'000'000;
    s.beam_ok = r.channels[c].status == SensorStatus::kOk;
    s.value = s.beam_ok ? r.channels[c].value_c : std::numeric_limits<double>::quiet_NaN();
    s.channel = static_cast<int>(c) + 1;
    samples_buffer_.push_back(s);
  }
  deliver(r.index, samples_buffer_);
}

StreamStats TemperatureLoggerDevice::stopStream() {
  if (!streaming()) return stats();
  stopReader(encodeLog(0), parseOk);
  return stats();
}

std::vector<StreamChannel> TemperatureLoggerDevice::streamChannels() const {
  std::vector<StreamChannel> out;
  for (int c = 1; c <= channels_.count; ++c) {
    out.push_back({c, fmt::format("ch{}", c), "temperature", "degC", "", ""});
  }
  return out;
}

}  // namespace mtcal::drivers::logger
