#pragma once
// Wire protocol of the mtcal laser interferometer (docs/protocols/interferometer.md).
// Pure codec: bytes <-> messages, no I/O. Used by the driver (host side) and by the
// emulator in mocks/ (device side). Every multi-byte field is little-endian.
//
// Frame: A5 5A | type u8 | length u16 | payload[length] | crc u16
// crc = CRC-16/CCITT-FALSE over type, length and payload.

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace mtcal::drivers::interferometer {

inline constexpr std::uint8_t kSync0 = 0xA5;
inline constexpr std::uint8_t kSync1 = 0x5A;
inline constexpr std::size_t kHeaderSize = 5;   ///< sync(2) + type(1) + length(2)
inline constexpr std::size_t kTrailerSize = 2;  ///< crc
inline constexpr std::size_t kMaxPayload = 4096;
inline constexpr std::uint16_t kProtocolVersion = 1;
inline constexpr std::uint32_t kMaxRateHz = 50000;
inline constexpr std::size_t kSampleSize = 9;  ///< i64 value + u8 signal
inline constexpr std::size_t kDataHeaderSize = 18;
inline constexpr std::size_t kMaxSamplesPerFrame = (kMaxPayload - kDataHeaderSize) / kSampleSize;
inline constexpr std::size_t kMaxMaterialSensors = 3;

enum class MessageType : std::uint8_t {
  // host -> device
  kIdentify = 0x01,
  kSetOptics = 0x02,
  kStartStream = 0x03,
  kStopStream = 0x04,
  kReadEnvironment = 0x05,
  kSetDatum = 0x06,
  // device -> host
  kAck = 0x80,
  kIdentity = 0x81,
  kEnvironment = 0x85,
  kData = 0x90,
  kNak = 0xE0,
};

/// Optics set-up. Only linear displacement is evaluated by mtcal so far; the codes of the
/// others are reserved so that angular and straightness kits fit the same stream format.
enum class Optics : std::uint8_t { kLinear = 1, kAngular = 2, kStraightnessShort = 3, kStraightnessLong = 4 };

enum class NakCode : std::uint8_t {
  kUnknownCommand = 1,
  kBadParameter = 2,
  kBusy = 3,
  kBeamLost = 4,
  kNotReady = 5,
};

struct Frame {
  MessageType type{};
  std::vector<std::uint8_t> payload;
};

struct Identity {
  std::uint16_t protocol_version = kProtocolVersion;
  double vacuum_wavelength_nm = 632.990577;  ///< stabilised HeNe
  std::string model, serial, firmware;
};

struct Environment {
  double air_temp_c = 20.0;
  double air_pressure_pa = 101325.0;
  double humidity_pct = 50.0;
  bool air_temp_ok = true, pressure_ok = true, humidity_ok = true;
  std::vector<double> material_temps_c;  ///< 0..3 sensors
};

/// One reading. `value` is in picometres of optical path computed with the vacuum
/// wavelength (uncompensated) in linear mode; in nanoradians in angular mode.
struct RawSample {
  std::int64_t value = 0;
  std::uint8_t signal_pct = 0;  ///< 0..100
  bool beam_ok = true;
};

struct DataBlock {
  std::uint32_t first_seq = 0;
  std::uint64_t first_time_ns = 0;
  std::uint32_t period_ns = 0;
  std::vector<RawSample> samples;
};

struct Nak {
  MessageType refused{};
  NakCode code{};
  std::string text;
};

// ---- framing ----
std::vector<std::uint8_t> encodeFrame(MessageType type, std::span<const std::uint8_t> payload);

/// Incremental decoder for a byte stream that may split or join frames arbitrarily and may
/// contain garbage. Bad frames (CRC, length) are skipped by resynchronising on the next
/// sync pattern and counted; nothing is ever thrown.
class FrameDecoder {
 public:
  void feed(std::span<const std::uint8_t> bytes);
  /// The next complete, valid frame, if one is buffered.
  std::optional<Frame> next();
  std::uint64_t crcErrors() const { return crc_errors_; }
  std::uint64_t discardedBytes() const { return discarded_bytes_; }
  std::size_t buffered() const { return buffer_.size() - start_; }

 private:
  std::vector<std::uint8_t> buffer_;
  std::size_t start_ = 0;
  std::uint64_t crc_errors_ = 0;
  std::uint64_t discarded_bytes_ = 0;
};

// ---- host -> device ----
std::vector<std::uint8_t> encodeIdentify();
std::vector<std::uint8_t> encodeSetOptics(Optics optics);
std::vector<std::uint8_t> encodeStartStream(std::uint32_t rate_hz);
std::vector<std::uint8_t> encodeStopStream();
std::vector<std::uint8_t> encodeReadEnvironment();
std::vector<std::uint8_t> encodeSetDatum();

// ---- device -> host ----
std::vector<std::uint8_t> encodeAck(MessageType acked);
std::vector<std::uint8_t> encodeNak(const Nak& nak);
std::vector<std::uint8_t> encodeIdentity(const Identity& identity);
std::vector<std::uint8_t> encodeEnvironment(const Environment& env);
/// @throws ProtocolError when the block holds more than kMaxSamplesPerFrame samples.
std::vector<std::uint8_t> encodeData(const DataBlock& block);

// ---- payload parsers: each @throws ProtocolError naming the message and the defect ----
MessageType parseAck(const Frame& frame);
Nak parseNak(const Frame& frame);
Identity parseIdentity(const Frame& frame);
Environment parseEnvironment(const Frame& frame);
DataBlock parseData(const Frame& frame);
Optics parseSetOptics(const Frame& frame);
std::uint32_t parseStartStream(const Frame& frame);

std::string messageName(MessageType type);

}  // namespace mtcal::drivers::interferometer
