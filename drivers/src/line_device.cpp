#include "mtcal/drivers/line_device.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <array>

#include "mtcal/error.h"
#include "stream_read.h"

namespace mtcal::drivers {
namespace {
constexpr std::size_t kReadChunk = 4096;
std::string trimmed(const std::string& command) { return command.substr(0, command.find_first_of("\r\n")); }
}  // namespace

LineDevice::LineDevice(std::unique_ptr<Transport> transport, std::string uri, LineTimeouts timeouts,
                       std::size_t max_line_bytes)
    : transport_(std::move(transport)), uri_(std::move(uri)), timeouts_(timeouts), decoder_(max_line_bytes) {}

LineDevice::~LineDevice() = default;  // reader_ stops and joins a reader still running

std::string LineDevice::readLine(std::chrono::steady_clock::time_point deadline, const std::string& command) {
  std::array<std::uint8_t, kReadChunk> buffer{};
  for (;;) {
    if (auto line = decoder_.next()) return *line;
    const auto left =
        std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
    if (left.count() <= 0)
      throw TimeoutError(fmt::format("{}: no reply to '{}' within {} ms", uri_, command, timeouts_.command.count()));
    try {
      decoder_.feed({buffer.data(), transport_->read(buffer, left)});
    } catch (const TimeoutError&) {
      throw TimeoutError(fmt::format("{}: no reply to '{}' within {} ms", uri_, command, timeouts_.command.count()));
    }
  }
}

std::string LineDevice::transact(const std::string& command) {
  std::lock_guard command_lock(command_mutex_);
  const auto deadline = std::chrono::steady_clock::now() + timeouts_.command;
  const std::string name = trimmed(command);
  transport_->write({reinterpret_cast<const std::uint8_t*>(command.data()), command.size()}, timeouts_.command);
  if (streaming_) {
    std::unique_lock lock(reply_mutex_);
    if (!reply_cv_.wait_until(lock, deadline, [&] { return !replies_.empty() || reader_.failed(); })) {
      throw TimeoutError(fmt::format("{}: no reply to '{}' within {} ms", uri_, name, timeouts_.command.count()));
    }
    // The reader failed: its error stays kept until stopReader(), on this thread.
    if (replies_.empty()) reader_.rethrowIfFailed();
    std::string reply = std::move(replies_.front());
    replies_.pop_front();
    return reply;
  }
  for (;;) {
    std::string line = readLine(deadline, name);
    if (!isStreamLine(line)) return line;  // stream lines sent before a stop belong to nobody
  }
}

void LineDevice::startReader(const char* thread_name, SampleSink& sink,
                             std::optional<std::chrono::milliseconds> stall) {
  sink_ = &sink;
  reader_stall_ = stall.value_or(timeouts_.stall);
  next_seq_.reset();
  streaming_ = true;
  reader_.start(
      thread_name, [this] { readerLoop(); },
      [this] {
        // Under the lock: a command between its check of failed() and its wait is not missed.
        std::lock_guard lock(reply_mutex_);
        reply_cv_.notify_all();
      });
}

void LineDevice::readerLoop() {
  std::array<std::uint8_t, kReadChunk> buffer{};
  auto last_line = std::chrono::steady_clock::now();
  while (!reader_.stopping()) {
    // Lines that came with the reply that started the stream are in the decoder already.
    while (auto line = decoder_.next()) {
      last_line = std::chrono::steady_clock::now();
      if (!isStreamLine(*line)) {
        std::lock_guard lock(reply_mutex_);
        replies_.push_back(std::move(*line));
        reply_cv_.notify_all();
        continue;
      }
      try {
        onStreamLine(*line);
      } catch (const ProtocolError& e) {
        ++bad_lines_;  // a garbled line is lost data, counted like a gap
        spdlog::debug("{}: {}", uri_, e.what());
      }
    }
    const std::size_t n = readOrStall(*transport_, buffer, timeouts_.read, reader_stall_, last_line, uri_);
    decoder_.feed({buffer.data(), n});
  }
}

void LineDevice::stopReader(const std::string& stop_command,
                            const std::function<void(const std::string&)>& check_reply) {
  std::exception_ptr failure;
  try {
    check_reply(transact(stop_command));
  } catch (...) {
    failure = std::current_exception();
  }
  // The reader's error explains the stop command's failure (or its own): it wins.
  if (auto reader_failure = reader_.stopAndTakeError()) failure = reader_failure;
  streaming_ = false;
  {
    std::lock_guard lock(reply_mutex_);
    replies_.clear();
  }
  if (failure) std::rethrow_exception(failure);
}

void LineDevice::deliver(std::uint32_t seq, std::span<const Sample> samples) {
  if (next_seq_ && seq != *next_seq_) lost_ += seq - *next_seq_;
  next_seq_ = seq + 1;
  sink_->push(samples);
  lines_ += 1;
}

StreamStats LineDevice::stats() const {
  StreamStats s;
  s.samples = lines_;
  s.lost_samples = lost_ + bad_lines_;
  s.crc_errors = bad_lines_;
  s.discarded_bytes = decoder_.overlongLines();
  return s;
}

void LineDevice::poll() { reader_.rethrowIfFailed(); }

}  // namespace mtcal::drivers
