#include "mtcal/drivers/probes/protocol.h"

#include <fmt/format.h>

#include <charconv>
#include <cmath>
#include <sstream>

#include "../ascii_fields.h"
#include "mtcal/error.h"

namespace mtcal::drivers::probes {
namespace {

const ascii::Replies kReplies("probe box");
using ascii::fields;
using ascii::line;

ChannelStatus parseStatus(const std::string& code, const std::string& line) {
  if (code == "OK") return ChannelStatus::kOk;
  if (code == "UR") return ChannelStatus::kUnderRange;
  if (code == "OR") return ChannelStatus::kOverRange;
  if (code == "NP") return ChannelStatus::kNoProbe;
  kReplies.malformed(line, "unknown channel status '" + code + "'");
}

std::vector<Reading> readings(const std::vector<std::string>& f, std::size_t from, int expected,
                              const std::string& text) {
  return kReplies.pairs<Reading>(f, from, expected, text, parseStatus);
}

std::string formatReadings(const std::vector<Reading>& readings) {
  std::string out;
  for (const auto& r : readings) out += fmt::format(" {:.7f} {}", r.value_mm, statusCode(r.status));
  return out;
}

}  // namespace

const char* statusCode(ChannelStatus status) {
  switch (status) {
    case ChannelStatus::kOk:
      return "OK";
    case ChannelStatus::kUnderRange:
      return "UR";
    case ChannelStatus::kOverRange:
      return "OR";
    case ChannelStatus::kNoProbe:
      return "NP";
  }
  return "?";
}

const char* statusName(ChannelStatus status) {
  switch (status) {
    case ChannelStatus::kOk:
      return "ok";
    case ChannelStatus::kUnderRange:
      return "under range";
    case ChannelStatus::kOverRange:
      return "over range";
    case ChannelStatus::kNoProbe:
      return "no probe";
  }
  return "?";
}

std::string encodeIdentify() { return line("*IDN?"); }
std::string encodeChannels() { return line("CH?"); }
std::string encodeRead(int channel) { return line(channel == 0 ? "READ? ALL" : fmt::format("READ? {}", channel)); }
std::string encodeZero(int channel) { return line(channel == 0 ? "ZERO ALL" : fmt::format("ZERO {}", channel)); }
std::string encodeRate(std::uint32_t rate_hz) { return line(fmt::format("RATE {}", rate_hz)); }
std::string encodeStream(bool on) { return line(on ? "STREAM ON" : "STREAM OFF"); }
std::string encodeTrigger(bool on) { return line(on ? "TRIG ON" : "TRIG OFF"); }

Identity parseIdentity(const std::string& text) {
  const auto [maker, model, serial, firmware] = kReplies.identity(text);
  return {maker, model, serial, firmware};
}

ChannelInfo parseChannels(const std::string& text) {
  kReplies.checkError(text);
  const auto f = fields(text);
  if (f.size() != 3 || f[0] != "CH") kReplies.malformed(text, "expected CH count range_mm");
  ChannelInfo info{kReplies.number<int>(f[1], text), kReplies.number<double>(f[2], text)};
  if (info.count < 1 || info.count > 16 || !(info.range_mm > 0.0))
    kReplies.malformed(text, "channel count or range out of bounds");
  return info;
}

std::vector<Reading> parseValues(const std::string& text, int expected) {
  kReplies.checkError(text);
  const auto f = fields(text);
  if (f.empty() || f[0] != "VAL") kReplies.malformed(text, "expected VAL");
  return readings(f, 1, expected, text);
}

void parseOk(const std::string& text) {
  kReplies.checkError(text);
  if (text != "OK") kReplies.malformed(text, "expected OK");
}

bool isStreamLine(const std::string& text) { return text.rfind("D ", 0) == 0 || text.rfind("L ", 0) == 0; }

StreamLine parseStreamLine(const std::string& text, int channels) {
  const auto f = fields(text);
  if (f.size() < 3 || (f[0] != "D" && f[0] != "L")) kReplies.malformed(text, "expected D|L seq time_us values");
  StreamLine s;
  s.latched = f[0] == "L";
  s.seq = kReplies.number<std::uint32_t>(f[1], text);
  s.time_us = kReplies.number<std::int64_t>(f[2], text);
  s.channels = readings(f, 3, channels, text);
  return s;
}

std::string formatIdentity(const Identity& id) {
  return ascii::identityLine(id.maker, id.model, id.serial, id.firmware);
}
std::string formatChannels(const ChannelInfo& info) {
  return line(fmt::format("CH {} {:.3f}", info.count, info.range_mm));
}
std::string formatValues(const std::vector<Reading>& r) { return line("VAL" + formatReadings(r)); }
std::string formatStreamLine(const StreamLine& s) {
  return line(fmt::format("{} {} {}", s.latched ? "L" : "D", s.seq, s.time_us) + formatReadings(s.channels));
}
std::string formatOk() { return line("OK"); }
std::string formatError(int code, const std::string& text) { return line(fmt::format("ERR {} {}", code, text)); }

Command parseCommand(const std::string& text) {
  const auto f = fields(text);
  auto bad = [&](const std::string& why) -> Command {
    throw ProtocolError("probe box: command '" + text + "': " + why);
  };
  if (f.empty()) return bad("empty");
  auto channel = [&](const std::string& c) {
    if (c == "ALL") return 0;
    int n = 0;
    const auto [ptr, ec] = std::from_chars(c.data(), c.data() + c.size(), n);
    if (ec != std::errc() || ptr != c.data() + c.size() || n < 1) bad("channel must be ALL or 1..n");
    return n;
  };
  if (f[0] == "*IDN?" && f.size() == 1) return {Command::Kind::kIdentify};
  if (f[0] == "CH?" && f.size() == 1) return {Command::Kind::kChannels};
  if (f[0] == "READ?" && f.size() == 2) return {Command::Kind::kRead, channel(f[1])};
  if (f[0] == "ZERO" && f.size() == 2) return {Command::Kind::kZero, channel(f[1])};
  if (f[0] == "RATE" && f.size() == 2) {
    std::uint32_t rate = 0;
    const auto [ptr, ec] = std::from_chars(f[1].data(), f[1].data() + f[1].size(), rate);
    if (ec != std::errc() || ptr != f[1].data() + f[1].size()) return bad("rate must be a whole number of Hz");
    Command c{Command::Kind::kRate};
    c.rate_hz = rate;
    return c;
  }
  if ((f[0] == "STREAM" || f[0] == "TRIG") && f.size() == 2 && (f[1] == "ON" || f[1] == "OFF")) {
    Command c{f[0] == "STREAM" ? Command::Kind::kStream : Command::Kind::kTrigger};
    c.on = f[1] == "ON";
    return c;
  }
  return bad("unknown command");
}

}  // namespace mtcal::drivers::probes
