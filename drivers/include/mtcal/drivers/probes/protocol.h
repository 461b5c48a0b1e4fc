#pragma once
// ASCII protocol of the inductive probe interface box (docs/protocols/probes.md): one
// command per line, one reply line per command, stream lines while streaming. Lines end in
// CR LF; fields are separated by single spaces; values are mm with 7 decimals.
// Both sides of the codec live here: the driver encodes commands and parses replies, the
// emulator the reverse. Pure functions, no I/O.

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace mtcal::drivers::probes {

inline constexpr std::size_t kMaxLineBytes = 512;
inline constexpr std::uint32_t kMaxRateHz = 1000;

enum class ChannelStatus { kOk, kUnderRange, kOverRange, kNoProbe };
/// "OK", "UR", "OR", "NP"
const char* statusCode(ChannelStatus status);
/// Human-readable: "ok", "under range", "over range", "no probe".
const char* statusName(ChannelStatus status);

struct Identity {
  std::string maker, model, serial, firmware;
};
struct ChannelInfo {
  int count = 0;
  double range_mm = 0.0;  ///< each probe reads -range_mm .. +range_mm
};
struct Reading {
  double value_mm = 0.0;
  ChannelStatus status = ChannelStatus::kOk;
};
struct StreamLine {
  std::uint32_t seq = 0;
  std::int64_t time_us = 0;
  std::vector<Reading> channels;
  bool latched = false;  ///< "L": latched by the trigger input (seq counts pulses); "D": streamed
};

// Host -> device. Channels are numbered from 1; 0 means all.
std::string encodeIdentify();                   ///< "*IDN?"
std::string encodeChannels();                   ///< "CH?"
std::string encodeRead(int channel);            ///< "READ? ALL" | "READ? n"
std::string encodeZero(int channel);            ///< "ZERO ALL" | "ZERO n"
std::string encodeRate(std::uint32_t rate_hz);  ///< "RATE n"
std::string encodeStream(bool on);              ///< "STREAM ON" | "STREAM OFF"
std::string encodeTrigger(bool on);             ///< "TRIG ON" | "TRIG OFF": latch on the trigger input

// Device -> host replies. Every parser throws DeviceError for an "ERR code text" line and
// ProtocolError (quoting the line) for anything malformed.
Identity parseIdentity(const std::string& line);                          ///< "IDN maker,model,serial,firmware"
ChannelInfo parseChannels(const std::string& line);                       ///< "CH count range_mm"
std::vector<Reading> parseValues(const std::string& line, int expected);  ///< "VAL v s [v s ...]"
void parseOk(const std::string& line);                                    ///< "OK"
StreamLine parseStreamLine(const std::string& line, int channels);        ///< "D seq time_us v s ..." or "L ..."
bool isStreamLine(const std::string& line);                               ///< a D or an L line

// Device side.
std::string formatIdentity(const Identity& identity);
std::string formatChannels(const ChannelInfo& info);
std::string formatValues(const std::vector<Reading>& readings);
std::string formatStreamLine(const StreamLine& line);
std::string formatOk();
std::string formatError(int code, const std::string& text);

/// A parsed host command (device side). @throws ProtocolError for an unknown or malformed one
struct Command {
  enum class Kind { kIdentify, kChannels, kRead, kZero, kRate, kStream, kTrigger } kind;
  int channel = 0;  ///< read, zero: 0 = all
  std::uint32_t rate_hz = 0;
  bool on = false;  ///< stream, trigger
};
Command parseCommand(const std::string& line);

}  // namespace mtcal::drivers::probes
