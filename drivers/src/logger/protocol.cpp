#include "mtcal/drivers/logger/protocol.h"

#include <fmt/format.h>

#include <cmath>
#include <sstream>

#include "../ascii_fields.h"
#include "mtcal/error.h"

namespace mtcal::drivers::logger {
namespace {

const ascii::Replies kReplies("temperature logger");
using ascii::fields;
using ascii::line;

SensorStatus parseStatus(const std::string& code, const std::string& line) {
  if (code == "OK") return SensorStatus::kOk;
  if (code == "OC") return SensorStatus::kOpen;
  if (code == "OR") return SensorStatus::kOverRange;
  kReplies.malformed(line, "unknown sensor status '" + code + "'");
}
std::vector<Reading> readings(const std::vector<std::string>& f, std::size_t from, int expected,
                              const std::string& text) {
  return kReplies.pairs<Reading>(f, from, expected, text, parseStatus);
}

std::string formatReadings(const std::vector<Reading>& readings) {
  std::string out;
  for (const auto& r : readings) out += fmt::format(" {:.2f} {}", r.value_c, statusCode(r.status));
  return out;
}

}  // namespace

const char* statusCode(SensorStatus status) {
  switch (status) {
    case SensorStatus::kOk:
      return "OK";
    case SensorStatus::kOpen:
      return "OC";
    case SensorStatus::kOverRange:
      return "OR";
  }
  return "?";
}
const char* statusName(SensorStatus status) {
  switch (status) {
    case SensorStatus::kOk:
      return "ok";
    case SensorStatus::kOpen:
      return "open circuit (sensor out)";
    case SensorStatus::kOverRange:
      return "over range";
  }
  return "?";
}

std::string encodeIdentify() { return line("*IDN?"); }
std::string encodeChannels() { return line("CH?"); }
std::string encodeRead() { return line("READ?"); }
std::string encodeLog(std::uint32_t interval_s) {
  return line(interval_s == 0 ? "LOG OFF" : fmt::format("LOG {}", interval_s));
}

Identity parseIdentity(const std::string& text) {
  const auto [maker, model, serial, firmware] = kReplies.identity(text);
  return {maker, model, serial, firmware};
}

ChannelInfo parseChannels(const std::string& text) {
  kReplies.checkError(text);
  const auto f = ascii::fields(text);
  if (f.size() != 3 || f[0] != "CH") kReplies.malformed(text, "expected CH count resolution_k");
  ChannelInfo info{kReplies.number<int>(f[1], text), kReplies.number<double>(f[2], text)};
  if ((info.count != 8 && info.count != 16) || !(info.resolution_k > 0.0))
    kReplies.malformed(text, "a logger has 8 or 16 channels");
  return info;
}

Record parseReading(const std::string& text, int channels) {
  kReplies.checkError(text);
  const auto f = ascii::fields(text);
  if (f.size() < 2 || f[0] != "T") kReplies.malformed(text, "expected T time_ms values");
  return {0, kReplies.number<std::int64_t>(f[1], text), readings(f, 2, channels, text)};
}

bool isRecordLine(const std::string& text) { return text.rfind("R ", 0) == 0; }

Record parseRecord(const std::string& text, int channels) {
  const auto f = ascii::fields(text);
  if (f.size() < 3 || f[0] != "R") kReplies.malformed(text, "expected R index time_ms values");
  return {kReplies.number<std::uint32_t>(f[1], text), kReplies.number<std::int64_t>(f[2], text),
          readings(f, 3, channels, text)};
}

void parseOk(const std::string& text) {
  kReplies.checkError(text);
  if (text != "OK") kReplies.malformed(text, "expected OK");
}

std::string formatIdentity(const Identity& id) {
  return ascii::identityLine(id.maker, id.model, id.serial, id.firmware);
}
std::string formatChannels(const ChannelInfo& info) {
  return line(fmt::format("CH {} {:.2f}", info.count, info.resolution_k));
}
std::string formatReading(const Record& r) { return line(fmt::format("T {}", r.time_ms) + formatReadings(r.channels)); }
std::string formatRecord(const Record& r) {
  return line(fmt::format("R {} {}", r.index, r.time_ms) + formatReadings(r.channels));
}
std::string formatOk() { return line("OK"); }
std::string formatError(int code, const std::string& text) { return line(fmt::format("ERR {} {}", code, text)); }

Command parseCommand(const std::string& text) {
  const auto f = ascii::fields(text);
  auto bad = [&](const std::string& why) -> Command {
    throw ProtocolError("temperature logger: command '" + text + "': " + why);
  };
  if (f.empty()) return bad("empty");
  if (f[0] == "*IDN?" && f.size() == 1) return {Command::Kind::kIdentify};
  if (f[0] == "CH?" && f.size() == 1) return {Command::Kind::kChannels};
  if (f[0] == "READ?" && f.size() == 1) return {Command::Kind::kRead};
  if (f[0] == "LOG" && f.size() == 2) {
    if (f[1] == "OFF") return {Command::Kind::kLog, 0};
    const auto interval = ascii::number<std::uint32_t>(f[1], [&](const std::string& why) { bad(why); });
    if (interval < 1 || interval > kMaxIntervalS) return bad("interval must be 1..86400 s");
    return {Command::Kind::kLog, interval};
  }
  return bad("unknown command");
}

}  // namespace mtcal::drivers::logger
