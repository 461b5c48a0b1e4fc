#pragma once
// ASCII protocol of the temperature data logger (docs/protocols/logger.md): 8 or 16
// channels of degC at 0.01 K resolution, a status per channel (a sensor out is "OC", never a
// value), one reply line per command, record lines while logging. Lines end in CR LF.
// Both sides of the codec: the driver encodes commands and parses replies, the emulator the
// reverse. Pure functions, no I/O.

#include <cstdint>
#include <string>
#include <vector>

namespace mtcal::drivers::logger {

inline constexpr std::size_t kMaxLineBytes = 512;
inline constexpr std::uint32_t kMaxIntervalS = 86400;

enum class SensorStatus { kOk, kOpen, kOverRange };
const char* statusCode(SensorStatus status);  ///< "OK", "OC", "OR"
const char* statusName(SensorStatus status);  ///< "ok", "open circuit (sensor out)", "over range"

struct Identity {
  std::string maker, model, serial, firmware;
};
struct ChannelInfo {
  int count = 0;  ///< 8 or 16
  double resolution_k = 0.01;
};
struct Reading {
  double value_c = 0.0;  ///< meaningless unless status is kOk
  SensorStatus status = SensorStatus::kOk;
};
/// One conversion of every channel: a READ? reply (index 0) or a logged record.
struct Record {
  std::uint32_t index = 0;   ///< records since logging started; a gap is lost data
  std::int64_t time_ms = 0;  ///< the logger's clock
  std::vector<Reading> channels;
};

std::string encodeIdentify();                     ///< "*IDN?"
std::string encodeChannels();                     ///< "CH?"
std::string encodeRead();                         ///< "READ?"
std::string encodeLog(std::uint32_t interval_s);  ///< "LOG n"; 0: "LOG OFF"

// Replies. DeviceError for "ERR code text", ProtocolError (quoting the line) for anything malformed.
Identity parseIdentity(const std::string& line);             ///< "IDN maker,model,serial,firmware"
ChannelInfo parseChannels(const std::string& line);          ///< "CH count resolution_k"
Record parseReading(const std::string& line, int channels);  ///< "T time_ms v s ..."
Record parseRecord(const std::string& line, int channels);   ///< "R index time_ms v s ..."
void parseOk(const std::string& line);                       ///< "OK"
bool isRecordLine(const std::string& line);

std::string formatIdentity(const Identity& identity);
std::string formatChannels(const ChannelInfo& info);
std::string formatReading(const Record& record);
std::string formatRecord(const Record& record);
std::string formatOk();
std::string formatError(int code, const std::string& text);

struct Command {
  enum class Kind { kIdentify, kChannels, kRead, kLog } kind;
  std::uint32_t interval_s = 0;  ///< kLog: 0 stops
};
/// @throws ProtocolError for an unknown or malformed command
Command parseCommand(const std::string& line);

}  // namespace mtcal::drivers::logger
