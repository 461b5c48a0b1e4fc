#include "mtcal/drivers/probes/driver.h"

#include <fmt/format.h>
#include <pthread.h>
#include <spdlog/spdlog.h>

#include <array>

#include "../stream_read.h"
#include "mtcal/error.h"

namespace mtcal::drivers::probes {
namespace {
constexpr std::size_t kReadChunk = 4096;

std::span<const std::uint8_t> bytes(const std::string& text) {
  return {reinterpret_cast<const std::uint8_t*>(text.data()), text.size()};
}
std::string trimmed(const std::string& command) { return command.substr(0, command.find_first_of("\r\n")); }
}  // namespace

ProbeBoxDevice::ProbeBoxDevice(std::unique_ptr<Transport> transport, std::string uri, Timeouts timeouts)
    : transport_(std::move(transport)), uri_(std::move(uri)), timeouts_(timeouts) {
  // A stream left running by an earlier session: stop it (its lines before the OK are skipped).
  parseOk(transact(encodeStream(false)));
  identity_ = parseIdentity(transact(encodeIdentify()));
  channels_ = parseChannels(transact(encodeChannels()));
  spdlog::info("{}: {} {} serial {} firmware {}, {} channels of +-{} mm", uri_, identity_.maker, identity_.model,
               identity_.serial, identity_.firmware, channels_.count, channels_.range_mm);
}

ProbeBoxDevice::~ProbeBoxDevice() {
  if (streaming_) {
    try {
      stopStream();
    } catch (...) {  // NOLINT(bugprone-empty-catch): destructor; the error was the caller's to fetch
    }
  }
}

DeviceInfo ProbeBoxDevice::info() const { return {uri_, "probes", identity_.model, identity_.serial, identity_.firmware}; }

std::string ProbeBoxDevice::readLine(std::chrono::steady_clock::time_point deadline, const std::string& command) {
  std::array<std::uint8_t, kReadChunk> buffer{};
  for (;;) {
    if (auto line = decoder_.next()) return *line;
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
    if (left.count() <= 0) {
      throw TimeoutError(fmt::format("{}: no reply to '{}' within {} ms", uri_, command, timeouts_.command.count()));
    }
    try {
      decoder_.feed({buffer.data(), transport_->read(buffer, left)});
    } catch (const TimeoutError&) {
      throw TimeoutError(fmt::format("{}: no reply to '{}' within {} ms", uri_, command, timeouts_.command.count()));
    }
  }
}

std::string ProbeBoxDevice::transact(const std::string& command) {
  std::lock_guard command_lock(command_mutex_);
  const auto deadline = std::chrono::steady_clock::now() + timeouts_.command;
  const std::string name = trimmed(command);
  transport_->write(bytes(command), timeouts_.command);
  if (streaming_) {
    std::unique_lock lock(reply_mutex_);
    if (!reply_cv_.wait_until(lock, deadline, [&] { return !replies_.empty() || reader_error_; })) {
      throw TimeoutError(fmt::format("{}: no reply to '{}' within {} ms", uri_, name, timeouts_.command.count()));
    }
    if (replies_.empty()) std::rethrow_exception(reader_error_);
    std::string reply = std::move(replies_.front());
    replies_.pop_front();
    return reply;
  }
  for (;;) {
    std::string line = readLine(deadline, name);
    if (!isStreamLine(line)) return line;  // stream lines sent before a stop belong to nobody

  }
}

std::vector<double> ProbeBoxDevice::readAll() {
  const auto readings = parseValues(transact(encodeRead(0)), channels_.count);
  std::vector<double> out;
  for (std::size_t i = 0; i < readings.size(); ++i) {
    if (readings[i].status != ChannelStatus::kOk) {
      throw DeviceError(fmt::format("{}: channel {}: {} ({:.4f} mm)", uri_, i + 1, statusName(readings[i].status),
                                    readings[i].value_mm));
    }
    out.push_back(readings[i].value_mm);
  }
  return out;
}

void ProbeBoxDevice::zero(int channel) { parseOk(transact(encodeZero(channel))); }

void ProbeBoxDevice::startStream(std::uint32_t rate_hz, SampleSink& sink) {
  if (streaming_) throw DeviceError(uri_ + ": already streaming");
  if (rate_hz < 1 || rate_hz > kMaxRateHz) throw InputError(fmt::format("{}: rate {} Hz is not 1..{}", uri_, rate_hz, kMaxRateHz));
  parseOk(transact(encodeRate(rate_hz)));
  parseOk(transact(encodeStream(true)));
  sink_ = &sink;
  next_seq_.reset();
  reader_error_ = nullptr;
  stop_reader_ = false;
  streaming_ = true;
  reader_ = std::thread([this] { readerLoop(); });
}

void ProbeBoxDevice::readerLoop() {
  pthread_setname_np(pthread_self(), "mtcal-probe-rd");
  std::array<std::uint8_t, kReadChunk> buffer{};
  auto last_line = std::chrono::steady_clock::now();
  std::vector<Sample> samples;
  try {
    while (!stop_reader_) {
      const std::size_t n = readOrStall(*transport_, buffer, timeouts_.read, timeouts_.stall, last_line, uri_);
      if (n == 0) continue;
      decoder_.feed({buffer.data(), n});
      while (auto line = decoder_.next()) {
        last_line = std::chrono::steady_clock::now();
        if (!isStreamLine(*line)) {
          std::lock_guard lock(reply_mutex_);
          replies_.push_back(std::move(*line));
          reply_cv_.notify_all();
          continue;
        }
        StreamLine s;
        try {
          s = parseStreamLine(*line, channels_.count);
        } catch (const ProtocolError& e) {
          ++bad_lines_;  // a garbled line is lost data, counted like a gap
          spdlog::debug("{}: {}", uri_, e.what());
          continue;
        }
        if (next_seq_ && s.seq != *next_seq_) lost_ += s.seq - *next_seq_;
        next_seq_ = s.seq + 1;
        samples.clear();
        for (std::size_t c = 0; c < s.channels.size(); ++c) {
          Sample sample;
          sample.seq = s.seq;
          sample.device_time_ns = s.time_us * 1000;
          sample.value = s.channels[c].value_mm;
          sample.channel = static_cast<int>(c) + 1;
          sample.beam_ok = s.channels[c].status == ChannelStatus::kOk;
          samples.push_back(sample);
        }
        sink_->push(samples);
        samples_ += 1;
      }
    }
  } catch (...) {
    std::lock_guard lock(reply_mutex_);
    reader_error_ = std::current_exception();
    reply_cv_.notify_all();
  }
}

StreamStats ProbeBoxDevice::stopStream() {
  if (!streaming_) return stats();
  std::exception_ptr failure;
  try {
    parseOk(transact(encodeStream(false)));
  } catch (...) {
    failure = std::current_exception();
  }
  stop_reader_ = true;
  if (reader_.joinable()) reader_.join();
  streaming_ = false;
  {
    std::lock_guard lock(reply_mutex_);
    replies_.clear();
    if (reader_error_) failure = reader_error_;
    reader_error_ = nullptr;
  }
  if (failure) std::rethrow_exception(failure);
  return stats();
}

void ProbeBoxDevice::poll() {
  std::lock_guard lock(reply_mutex_);
  if (reader_error_) std::rethrow_exception(reader_error_);
}

StreamStats ProbeBoxDevice::stats() const {
  StreamStats s;
  s.samples = samples_;
  s.lost_samples = lost_ + bad_lines_;
  s.crc_errors = bad_lines_;
  s.discarded_bytes = decoder_.overlongLines();
  return s;
}

}  // namespace mtcal::drivers::probes
