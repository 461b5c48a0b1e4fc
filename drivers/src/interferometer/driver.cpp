#include "mtcal/drivers/interferometer/driver.h"

#include <spdlog/spdlog.h>

#include <array>

#include "../stream_read.h"
#include "mtcal/error.h"

namespace mtcal::drivers::interferometer {
namespace {
constexpr std::size_t kReadChunk = 16384;  // a multiple of every USB max packet size
}

InterferometerDevice::InterferometerDevice(std::unique_ptr<Transport> transport, std::string uri, Timeouts timeouts)
    : transport_(std::move(transport)), uri_(std::move(uri)), timeouts_(timeouts) {
  // A previous session may have left the device streaming: stop it and drop what it sent.
  // Its ACK is skipped by transact() as the reply of another command.
  transport_->write(encodeStopStream(), timeouts_.command);
  identity_ = parseIdentity(transact(encodeIdentify(), MessageType::kIdentity));
  spdlog::info("{}: {} serial {} firmware {}, vacuum wavelength {} nm", uri_, identity_.model, identity_.serial,
               identity_.firmware, identity_.vacuum_wavelength_nm);
  if (identity_.protocol_version != kProtocolVersion) {
    throw ProtocolError(uri_ + ": device speaks protocol v" + std::to_string(identity_.protocol_version) +
                        ", this driver v" + std::to_string(kProtocolVersion));
  }
}

InterferometerDevice::~InterferometerDevice() {
  if (streaming_) {
    try {
      stopStream();
    } catch (...) {  // NOLINT(bugprone-empty-catch): destructor; the error was the caller's to fetch
    }
  }
}

DeviceInfo InterferometerDevice::info() const {
  return {uri_, "interferometer", identity_.model, identity_.serial, identity_.firmware};
}

Frame InterferometerDevice::transact(const std::vector<std::uint8_t>& request, MessageType expected) {
  std::lock_guard command_lock(command_mutex_);
  const auto deadline = std::chrono::steady_clock::now() + timeouts_.command;
  const auto request_type = static_cast<MessageType>(request[2]);
  transport_->write(request, timeouts_.command);

  auto accept = [&](Frame frame) -> std::optional<Frame> {
    if (frame.type == MessageType::kNak) {
      Nak nak = parseNak(frame);
      throw DeviceError(uri_ + ": " + messageName(nak.refused) + " refused (code " +
                        std::to_string(static_cast<int>(nak.code)) + "): " + nak.text);
    }
    if (frame.type == expected) return frame;
    return std::nullopt;  // a stale reply of an earlier command: skip
  };

  if (streaming_) {
    std::unique_lock lock(reply_mutex_);
    for (;;) {
      if (!reply_cv_.wait_until(lock, deadline, [&] { return reply_.has_value() || reader_.failed(); })) {
        throw TimeoutError(uri_ + ": no reply to " + messageName(request_type) + " within " +
                           std::to_string(timeouts_.command.count()) + " ms");
      }
      // The reader failed; poll() cannot take its error meanwhile, it waits for reply_mutex_.
      if (!reply_) reader_.rethrowIfFailed();
      Frame frame = std::move(*reply_);
      reply_.reset();
      if (auto ok = accept(std::move(frame))) return *ok;
    }
  }

  std::array<std::uint8_t, kReadChunk> buffer{};
  for (;;) {
    while (auto frame = decoder_.next()) {
      if (frame->type == MessageType::kData) continue;  // stale stream data from before STOP
      if (auto ok = accept(std::move(*frame))) return *ok;
    }
    const auto left =
        std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
    if (left.count() <= 0) {
      throw TimeoutError(uri_ + ": no reply to " + messageName(request_type) + " within " +
                         std::to_string(timeouts_.command.count()) + " ms");
    }
    std::size_t n = 0;
    try {
      n = transport_->read(buffer, left);
    } catch (const TimeoutError&) {
      continue;  // the deadline check above decides
    }
    decoder_.feed(std::span(buffer).first(n));
  }
}

void InterferometerDevice::setOptics(Optics optics) {
  transact(encodeSetOptics(optics), MessageType::kAck);
  optics_ = optics;
}

void InterferometerDevice::setDatum() { transact(encodeSetDatum(), MessageType::kAck); }

Environment InterferometerDevice::readEnvironment() {
  return parseEnvironment(transact(encodeReadEnvironment(), MessageType::kEnvironment));
}

void InterferometerDevice::startStream(std::uint32_t rate_hz, SampleSink& sink) {
  if (streaming_) throw DeviceError(uri_ + ": stream already running");
  if (rate_hz < 1 || rate_hz > kMaxRateHz) {
    throw InputError(uri_ + ": stream rate " + std::to_string(rate_hz) + " Hz is outside 1.." +
                     std::to_string(kMaxRateHz));
  }
  transact(encodeStartStream(rate_hz), MessageType::kAck);
  spdlog::debug("{}: stream started at {} Hz", uri_, rate_hz);
  sink_ = &sink;
  next_seq_.reset();
  reply_.reset();
  streaming_ = true;
  reader_.start(
      "mtcal-ifm-read", [this] { readerLoop(); },  // the name is visible in top, gdb and perf
      [this] {
        // A waiting command sees the error instead of timing out. The lock: one between its
        // check of failed() and its wait is not missed.
        { std::lock_guard lock(reply_mutex_); }
        reply_cv_.notify_all();
      });
}

StreamStats InterferometerDevice::stopStream() {
  if (!streaming_) {
    poll();
    return stats();
  }
  std::exception_ptr stop_error;
  try {
    // The ACK arrives after the last DATA frame, so everything sent is delivered by then.
    if (!reader_.failed()) transact(encodeStopStream(), MessageType::kAck);
  } catch (...) {
    stop_error = std::current_exception();
  }
  const std::exception_ptr reader_error = reader_.stopAndTakeError();
  streaming_ = false;
  sink_ = nullptr;
  if (reader_error) std::rethrow_exception(reader_error);  // the cause of a failed stop too
  if (stop_error) std::rethrow_exception(stop_error);
  const StreamStats s = stats();
  spdlog::debug("{}: stream stopped: {} samples, {} lost, {} bad frames", uri_, s.samples, s.lost_samples,
                s.crc_errors);
  return s;
}

void InterferometerDevice::poll() {
  // Unlike the other drivers this hands the error over: a second poll() does not throw.
  std::lock_guard lock(reply_mutex_);
  if (auto error = reader_.takeError()) std::rethrow_exception(error);
}

StreamStats InterferometerDevice::stats() const {
  return {samples_.load(), lost_.load(), crc_errors_.load(), discarded_bytes_.load()};
}

std::vector<StreamChannel> InterferometerDevice::streamChannels() const {
  // The units of handleData()'s scaling.
  StreamChannel c{0, "linear", "uncompensated displacement", "mm", "beam signal", "%"};
  switch (optics_) {
    case Optics::kLinear:
      break;
    case Optics::kAngular:
      c.name = "angular";
      c.quantity = "angle";
      c.unit = "urad";
      break;
    case Optics::kStraightnessShort:
    case Optics::kStraightnessLong:
      c.name = optics_ == Optics::kStraightnessShort ? "straightness-short" : "straightness-long";
      c.quantity = "straightness";
      break;
  }
  return {c};
}

void InterferometerDevice::deliverReply(Frame frame) {
  {
    std::lock_guard lock(reply_mutex_);
    reply_ = std::move(frame);
  }
  reply_cv_.notify_all();
}

void InterferometerDevice::handleData(const Frame& frame) {
  DataBlock block = parseData(frame);
  if (next_seq_ && block.first_seq != *next_seq_) {
    // Unsigned difference handles the 32-bit wrap of the sequence counter.
    lost_ += static_cast<std::uint32_t>(block.first_seq - *next_seq_);
  }
  next_seq_ = block.first_seq + static_cast<std::uint32_t>(block.samples.size());
  // Linear: pm -> mm; angular: nrad -> urad.
  const double scale = optics_ == Optics::kAngular ? 1e-3 : 1e-9;
  scratch_.resize(block.samples.size());
  for (std::size_t i = 0; i < block.samples.size(); ++i) {
    const auto& raw = block.samples[i];
    scratch_[i] = Sample{block.first_seq + static_cast<std::uint32_t>(i),
                         static_cast<std::int64_t>(block.first_time_ns + std::uint64_t{block.period_ns} * i),
                         static_cast<double>(raw.value) * scale, raw.signal_pct, raw.beam_ok};
  }
  sink_->push(scratch_);
  samples_ += block.samples.size();
}

void InterferometerDevice::readerLoop() {
  std::array<std::uint8_t, kReadChunk> buffer{};
  auto last_data = std::chrono::steady_clock::now();
  try {
    while (!reader_.stopping()) {
      const std::size_t n = readOrStall(*transport_, buffer, timeouts_.read, timeouts_.stall, last_data, uri_);
      if (n == 0) continue;
      last_data = std::chrono::steady_clock::now();
      decoder_.feed(std::span(buffer).first(n));
      bool stopped = false;
      while (auto frame = decoder_.next()) {
        if (frame->type == MessageType::kData) {
          handleData(*frame);
        } else {
          // The STOP_STREAM acknowledgement follows the last DATA frame: the stream is over.
          stopped = frame->type == MessageType::kAck && parseAck(*frame) == MessageType::kStopStream;
          deliverReply(std::move(*frame));
        }
      }
      crc_errors_ = decoder_.crcErrors();
      discarded_bytes_ = decoder_.discardedBytes();
      if (stopped) break;
    }
  } catch (const std::exception& e) {
    spdlog::warn("{}: reader thread stopped: {}", uri_, e.what());
    throw;  // kept by reader_
  }
}

}  // namespace mtcal::drivers::interferometer
