#include "mtcal/drivers/ballbar/driver.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <array>

#include "../stream_read.h"
#include "mtcal/error.h"

namespace mtcal::drivers::ballbar {

BallbarDevice::BallbarDevice(std::unique_ptr<HidTransport> transport, std::string uri, Timeouts timeouts)
    : transport_(std::move(transport)), uri_(std::move(uri)), timeouts_(timeouts) {
  auto buffer = featureBuffer(ReportId::kIdentify);
  buffer.resize(transport_->getFeature(buffer));
  identity_ = parseIdentity(buffer);
  if (status().flags & kStreaming) command(encodeStream(false), "stop a stream left running");
  spdlog::info("{}: {} serial {} firmware {}, {} mm bar, range +-{} um", uri_, identity_.model, identity_.serial,
               identity_.firmware, identity_.nominal_length_mm, identity_.range_um);
}

BallbarDevice::~BallbarDevice() {
  if (streaming_) {
    try {
      stopStream();
    } catch (...) {  // NOLINT(bugprone-empty-catch): destructor; the error was the caller's to fetch
    }
  }
}

DeviceInfo BallbarDevice::info() const {
  return {uri_, "ballbar", identity_.model, identity_.serial, identity_.firmware};
}

Status BallbarDevice::status() {
  auto buffer = featureBuffer(ReportId::kStatus);
  buffer.resize(transport_->getFeature(buffer));
  return parseStatus(buffer);
}

void BallbarDevice::command(const std::vector<std::uint8_t>& report, const char* what) {
  transport_->setFeature(report);
  const Status s = status();
  if (static_cast<std::uint8_t>(s.last_command) != report[0]) {
    throw ProtocolError(fmt::format("{}: {}: the status reports command 0x{:02x} as the last, not 0x{:02x}", uri_, what,
                                    static_cast<unsigned>(s.last_command), report[0]));
  }
  if (s.result != Result::kOk) throw DeviceError(fmt::format("{}: {}: refused: {}", uri_, what, resultName(s.result)));
}

void BallbarDevice::zero(double reference_length_mm) {
  if (streaming_) throw DeviceError(uri_ + ": zero: not while streaming");
  command(encodeZero(reference_length_mm), fmt::format("zero at {} mm", reference_length_mm).c_str());
}

void BallbarDevice::startStream(std::uint32_t rate_hz, SampleSink& sink) {
  if (streaming_) throw DeviceError(uri_ + ": already streaming");
  if (rate_hz < 1 || rate_hz > kMaxRateHz)
    throw InputError(fmt::format("{}: rate {} Hz is not 1..{}", uri_, rate_hz, kMaxRateHz));
  command(encodeRate(rate_hz), "set rate");
  flushInput();
  sink_ = &sink;
  next_seq_.reset();
  command(encodeStream(true), "start stream");
  streaming_ = true;
  reader_.start("mtcal-bbar-rd", [this] { readerLoop(); });
}

void BallbarDevice::flushInput() {
  std::array<std::uint8_t, kInputReportSize> buffer{};
  for (std::size_t i = 0; i < 4096; ++i) {  // bounded: a device that never stops is not ours to wait for
    try {
      transport_->read(buffer, std::chrono::milliseconds(0));
    } catch (const TimeoutError&) {
      return;
    }
  }
}

void BallbarDevice::readerLoop() {
  std::array<std::uint8_t, kInputReportSize> buffer{};
  auto last_report = std::chrono::steady_clock::now();
  std::vector<Sample> samples;
  while (!reader_.stopping()) {
    const std::size_t n = readOrStall(*transport_, buffer, timeouts_.read, timeouts_.stall, last_report, uri_);
    if (n == 0) continue;
    last_report = std::chrono::steady_clock::now();
    SampleBlock block;
    try {
      block = parseSamples({buffer.data(), n});
    } catch (const ProtocolError& e) {
      ++bad_reports_;  // a malformed report is lost data: counted, not guessed at
      spdlog::debug("{}: {}", uri_, e.what());
      continue;
    }
    if (next_seq_) {
      const auto gap = static_cast<std::int32_t>(block.first_seq - *next_seq_);
      if (gap < 0) {  // a report from before the gap we already counted: out of order
        ++bad_reports_;
        continue;
      }
      lost_ += static_cast<std::uint64_t>(gap);
    }
    next_seq_ = block.first_seq + static_cast<std::uint32_t>(block.deviation_um.size());
    {
      std::lock_guard lock(state_mutex_);
      condition_ = {block.temperature_c, block.battery_pct, (block.flags & kBatteryLow) != 0,
                    (block.flags & kNotZeroed) == 0};
    }
    // The device clock is 32-bit microseconds (wraps after 71.6 min): extended here.
    if (last_time_us_ && block.device_time_us<*last_time_us_&& * last_time_us_ - block.device_time_us>(1u << 31)) {
      time_epoch_us_ += std::int64_t{1} << 32;
    }
    last_time_us_ = block.device_time_us;
    const std::int64_t first_us = time_epoch_us_ + block.device_time_us;
    samples.clear();
    for (std::size_t i = 0; i < block.deviation_um.size(); ++i) {
      Sample s;
      s.seq = block.first_seq + static_cast<std::uint32_t>(i);
      s.device_time_ns = (first_us + static_cast<std::int64_t>(i) * block.period_us) * 1000;
      s.value = block.deviation_um[i].value_or(0.0) / 1000.0;
      s.beam_ok = block.deviation_um[i].has_value();
      s.signal_pct = block.battery_pct;
      samples.push_back(s);
    }
    sink_->push(samples);
    samples_ += samples.size();
  }
}

StreamStats BallbarDevice::stopStream() {
  if (!streaming_) return stats();
  std::exception_ptr failure;
  try {
    command(encodeStream(false), "stop stream");  // the reader takes what was sent before
  } catch (...) {
    failure = std::current_exception();
  }
  // The reader's error explains the stop command's failure (or its own): it wins.
  if (auto reader_failure = reader_.stopAndTakeError()) failure = reader_failure;
  streaming_ = false;
  if (failure) std::rethrow_exception(failure);
  return stats();
}

void BallbarDevice::poll() { reader_.rethrowIfFailed(); }

StreamStats BallbarDevice::stats() const {
  StreamStats s;
  s.samples = samples_;
  s.lost_samples = lost_;
  s.crc_errors = bad_reports_;
  return s;
}

std::vector<StreamChannel> BallbarDevice::streamChannels() const {
  return {{0, "deviation", "length deviation", "mm", "battery", "%"}};
}

Condition BallbarDevice::condition() const {
  std::lock_guard lock(state_mutex_);
  return condition_;
}

}  // namespace mtcal::drivers::ballbar
