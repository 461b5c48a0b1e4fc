#include "mtcal/drivers/interferometer/protocol.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdio>
#include <cstring>

#include "../byte_order.h"
#include "mtcal/drivers/crc.h"
#include "mtcal/error.h"

namespace mtcal::drivers::interferometer {
namespace {
using byte_order::Reader;
using byte_order::Writer;

void expectType(const Frame& frame, MessageType type) {
  if (frame.type != type) {
    throw ProtocolError("expected " + messageName(type) + ", got " + messageName(frame.type));
  }
}

std::vector<std::uint8_t> encodeEmpty(MessageType type) { return encodeFrame(type, {}); }

bool knownType(std::uint8_t t) {
  switch (static_cast<MessageType>(t)) {
    case MessageType::kIdentify:
    case MessageType::kSetOptics:
    case MessageType::kStartStream:
    case MessageType::kStopStream:
    case MessageType::kReadEnvironment:
    case MessageType::kSetDatum:
    case MessageType::kAck:
    case MessageType::kIdentity:
    case MessageType::kEnvironment:
    case MessageType::kData:
    case MessageType::kNak:
      return true;
  }
  return false;
}

}  // namespace

std::string messageName(MessageType type) {
  switch (type) {
    case MessageType::kIdentify:
      return "IDENTIFY";
    case MessageType::kSetOptics:
      return "SET_OPTICS";
    case MessageType::kStartStream:
      return "START_STREAM";
    case MessageType::kStopStream:
      return "STOP_STREAM";
    case MessageType::kReadEnvironment:
      return "READ_ENVIRONMENT";
    case MessageType::kSetDatum:
      return "SET_DATUM";
    case MessageType::kAck:
      return "ACK";
    case MessageType::kIdentity:
      return "IDENTITY";
    case MessageType::kEnvironment:
      return "ENVIRONMENT";
    case MessageType::kData:
      return "DATA";
    case MessageType::kNak:
      return "NAK";
  }
  char buf[16];
  std::snprintf(buf, sizeof buf, "type 0x%02X", static_cast<unsigned>(type));
  return buf;
}

std::vector<std::uint8_t> encodeFrame(MessageType type, std::span<const std::uint8_t> payload) {
  if (payload.size() > kMaxPayload) {
    throw ProtocolError(messageName(type) + ": payload of " + std::to_string(payload.size()) + " bytes exceeds " +
                        std::to_string(kMaxPayload));
  }
  std::vector<std::uint8_t> out;
  out.reserve(kHeaderSize + payload.size() + kTrailerSize);
  const auto n = static_cast<std::uint16_t>(payload.size());
  out.insert(out.end(), {kSync0, kSync1, static_cast<std::uint8_t>(type), static_cast<std::uint8_t>(n & 0xFF),
                         static_cast<std::uint8_t>(n >> 8)});
  out.insert(out.end(), payload.begin(), payload.end());
  const std::uint16_t crc = crc16Ccitt(std::span(out).subspan(2));
  out.push_back(static_cast<std::uint8_t>(crc & 0xFF));
  out.push_back(static_cast<std::uint8_t>(crc >> 8));
  return out;
}

void FrameDecoder::feed(std::span<const std::uint8_t> bytes) {
  // Compact once the consumed prefix dominates, so the buffer does not grow without bound.
  if (start_ > 0 && start_ * 2 > buffer_.size()) {
    buffer_.erase(buffer_.begin(), buffer_.begin() + static_cast<std::ptrdiff_t>(start_));
    start_ = 0;
  }
  buffer_.insert(buffer_.end(), bytes.begin(), bytes.end());
}

std::optional<Frame> FrameDecoder::next() {
  for (;;) {
    // Find the sync pattern.
    std::size_t i = start_;
    while (i + 1 < buffer_.size() && !(buffer_[i] == kSync0 && buffer_[i + 1] == kSync1)) ++i;
    if (i + 1 >= buffer_.size() && !(i < buffer_.size() && buffer_[i] == kSync0)) i = buffer_.size();
    discarded_bytes_ += i - start_;
    start_ = i;
    if (buffer_.size() - start_ < kHeaderSize) return std::nullopt;
    const std::uint8_t type = buffer_[start_ + 2];
    const std::size_t length = buffer_[start_ + 3] | (static_cast<std::size_t>(buffer_[start_ + 4]) << 8);
    if (length > kMaxPayload || !knownType(type)) {
      // Not a frame start after all: skip this sync byte and look again.
      ++crc_errors_;
      ++discarded_bytes_;
      ++start_;
      continue;
    }
    const std::size_t total = kHeaderSize + length + kTrailerSize;
    if (buffer_.size() - start_ < total) return std::nullopt;
    const auto body = std::span(buffer_).subspan(start_ + 2, 3 + length);
    const std::uint16_t crc =
        static_cast<std::uint16_t>(buffer_[start_ + total - 2] | (buffer_[start_ + total - 1] << 8));
    if (crc16Ccitt(body) != crc) {
      ++crc_errors_;
      ++discarded_bytes_;
      ++start_;
      continue;
    }
    Frame frame;
    frame.type = static_cast<MessageType>(type);
    frame.payload.assign(buffer_.begin() + static_cast<std::ptrdiff_t>(start_ + kHeaderSize),
                         buffer_.begin() + static_cast<std::ptrdiff_t>(start_ + kHeaderSize + length));
    start_ += total;
    return frame;
  }
}

std::vector<std::uint8_t> encodeIdentify() { return encodeEmpty(MessageType::kIdentify); }
std::vector<std::uint8_t> encodeStopStream() { return encodeEmpty(MessageType::kStopStream); }
std::vector<std::uint8_t> encodeReadEnvironment() { return encodeEmpty(MessageType::kReadEnvironment); }
std::vector<std::uint8_t> encodeSetDatum() { return encodeEmpty(MessageType::kSetDatum); }

std::vector<std::uint8_t> encodeSetOptics(Optics optics) {
  const std::uint8_t payload[] = {static_cast<std::uint8_t>(optics)};
  return encodeFrame(MessageType::kSetOptics, payload);
}

std::vector<std::uint8_t> encodeStartStream(std::uint32_t rate_hz) {
  Writer w;
  w.put(rate_hz);
  return encodeFrame(MessageType::kStartStream, w.bytes());
}

std::vector<std::uint8_t> encodeAck(MessageType acked) {
  const std::uint8_t payload[] = {static_cast<std::uint8_t>(acked)};
  return encodeFrame(MessageType::kAck, payload);
}

std::vector<std::uint8_t> encodeNak(const Nak& nak) {
  Writer w;
  w.put(static_cast<std::uint8_t>(nak.refused)).put(static_cast<std::uint8_t>(nak.code)).putString(nak.text);
  return encodeFrame(MessageType::kNak, w.bytes());
}

std::vector<std::uint8_t> encodeIdentity(const Identity& id) {
  Writer w;
  w.put(id.protocol_version)
      .putDouble(id.vacuum_wavelength_nm)
      .putString(id.model)
      .putString(id.serial)
      .putString(id.firmware);
  return encodeFrame(MessageType::kIdentity, w.bytes());
}

std::vector<std::uint8_t> encodeEnvironment(const Environment& env) {
  if (env.material_temps_c.size() > kMaxMaterialSensors) {
    throw ProtocolError("ENVIRONMENT: at most 3 material sensors");
  }
  Writer w;
  w.put(static_cast<std::int32_t>(std::lround(env.air_temp_c * 1000.0)))
      .put(static_cast<std::uint32_t>(std::lround(env.air_pressure_pa * 10.0)))
      .put(static_cast<std::uint16_t>(std::lround(env.humidity_pct * 100.0)))
      .put(static_cast<std::uint8_t>((env.air_temp_ok ? 1 : 0) | (env.pressure_ok ? 2 : 0) | (env.humidity_ok ? 4 : 0)))
      .put(static_cast<std::uint8_t>(env.material_temps_c.size()));
  for (double t : env.material_temps_c) w.put(static_cast<std::int32_t>(std::lround(t * 1000.0)));
  return encodeFrame(MessageType::kEnvironment, w.bytes());
}

std::vector<std::uint8_t> encodeData(const DataBlock& block) {
  if (block.samples.size() > kMaxSamplesPerFrame) {
    throw ProtocolError("DATA: " + std::to_string(block.samples.size()) + " samples exceed " +
                        std::to_string(kMaxSamplesPerFrame) + " per frame");
  }
  Writer w;
  w.bytes().reserve(kDataHeaderSize + kSampleSize * block.samples.size());
  w.put(block.first_seq)
      .put(block.first_time_ns)
      .put(block.period_ns)
      .put(static_cast<std::uint16_t>(block.samples.size()));
  for (const auto& s : block.samples) {
    w.put(s.value).put(static_cast<std::uint8_t>((s.beam_ok ? 0x80 : 0x00) | (s.signal_pct & 0x7F)));
  }
  return encodeFrame(MessageType::kData, w.bytes());
}

MessageType parseAck(const Frame& frame) {
  expectType(frame, MessageType::kAck);
  Reader r(frame.payload, "ACK");
  auto acked = r.get<std::uint8_t>();
  r.end();
  return static_cast<MessageType>(acked);
}

Nak parseNak(const Frame& frame) {
  expectType(frame, MessageType::kNak);
  Reader r(frame.payload, "NAK");
  Nak nak;
  nak.refused = static_cast<MessageType>(r.get<std::uint8_t>());
  nak.code = static_cast<NakCode>(r.get<std::uint8_t>());
  nak.text = r.getString();
  r.end();
  return nak;
}

Identity parseIdentity(const Frame& frame) {
  expectType(frame, MessageType::kIdentity);
  Reader r(frame.payload, "IDENTITY");
  Identity id;
  id.protocol_version = r.get<std::uint16_t>();
  id.vacuum_wavelength_nm = r.getDouble();
  id.model = r.getString();
  id.serial = r.getString();
  id.firmware = r.getString();
  r.end();
  if (!(id.vacuum_wavelength_nm > 300.0 && id.vacuum_wavelength_nm < 1700.0)) {
    throw ProtocolError("IDENTITY: vacuum wavelength " + std::to_string(id.vacuum_wavelength_nm) +
                        " nm is not plausible");
  }
  return id;
}

Environment parseEnvironment(const Frame& frame) {
  expectType(frame, MessageType::kEnvironment);
  Reader r(frame.payload, "ENVIRONMENT");
  Environment env;
  env.air_temp_c = r.get<std::int32_t>() / 1000.0;
  env.air_pressure_pa = r.get<std::uint32_t>() / 10.0;
  env.humidity_pct = r.get<std::uint16_t>() / 100.0;
  const auto status = r.get<std::uint8_t>();
  env.air_temp_ok = status & 1;
  env.pressure_ok = status & 2;
  env.humidity_ok = status & 4;
  const auto n = r.get<std::uint8_t>();
  if (n > kMaxMaterialSensors) {
    throw ProtocolError("ENVIRONMENT: " + std::to_string(n) + " material sensors announced, at most 3 exist");
  }
  for (int i = 0; i < n; ++i) env.material_temps_c.push_back(r.get<std::int32_t>() / 1000.0);
  r.end();
  return env;
}

DataBlock parseData(const Frame& frame) {
  expectType(frame, MessageType::kData);
  Reader r(frame.payload, "DATA");
  DataBlock block;
  block.first_seq = r.get<std::uint32_t>();
  block.first_time_ns = r.get<std::uint64_t>();
  block.period_ns = r.get<std::uint32_t>();
  const auto count = r.get<std::uint16_t>();
  if (frame.payload.size() != kDataHeaderSize + kSampleSize * count) {
    throw ProtocolError("DATA: announces " + std::to_string(count) + " samples but carries " +
                        std::to_string(frame.payload.size()) + " payload bytes");
  }
  block.samples.resize(count);
  for (auto& s : block.samples) {
    s.value = r.get<std::int64_t>();
    const auto flags = r.get<std::uint8_t>();
    s.beam_ok = flags & 0x80;
    s.signal_pct = flags & 0x7F;
  }
  return block;
}

Optics parseSetOptics(const Frame& frame) {
  expectType(frame, MessageType::kSetOptics);
  Reader r(frame.payload, "SET_OPTICS");
  auto optics = r.get<std::uint8_t>();
  r.end();
  if (optics < 1 || optics > 4) throw ProtocolError("SET_OPTICS: unknown optics code " + std::to_string(optics));
  return static_cast<Optics>(optics);
}

std::uint32_t parseStartStream(const Frame& frame) {
  expectType(frame, MessageType::kStartStream);
  Reader r(frame.payload, "START_STREAM");
  auto rate = r.get<std::uint32_t>();
  r.end();
  return rate;
}

}  // namespace mtcal::drivers::interferometer
