#include "mtcal/drivers/tracker/protocol.h"

#include <fmt/format.h>

#include <charconv>
#include <cmath>
#include <limits>

#include "mtcal/error.h"

namespace mtcal::drivers::tracker {
namespace {

std::vector<std::string> split(std::string_view line) {
  std::vector<std::string> words;
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && line[i] == ' ') ++i;
    const std::size_t start = i;
    while (i < line.size() && line[i] != ' ') ++i;
    if (i > start) words.emplace_back(line.substr(start, i - start));
  }
  return words;
}

std::string_view trimEnd(std::string_view line) {
  while (!line.empty() && (line.back() == '\n' || line.back() == '\r')) line.remove_suffix(1);
  return line;
}

[[noreturn]] void malformed(std::string_view line, const std::string& why) {
  throw ProtocolError(fmt::format("tracker line '{}': {}", line.substr(0, 120), why));
}

std::uint32_t parseTag(std::string_view word, std::string_view line) {
  std::uint32_t tag = 0;
  const auto [end, ec] = std::from_chars(word.data(), word.data() + word.size(), tag);
  if (ec != std::errc() || end != word.data() + word.size() || tag == 0)
    malformed(line, "the tag must be a number 1..4294967295");
  return tag;
}

std::string joined(const std::vector<std::string>& words) {
  std::string out;
  for (const auto& w : words) {
    if (!out.empty()) out += ' ';
    out += w;
  }
  return out;
}

const std::string& field(const std::vector<std::string>& fields, std::size_t i, const char* what) {
  if (i >= fields.size()) throw ProtocolError(fmt::format("tracker reply '{}': {} missing", joined(fields), what));
  return fields[i];
}

void expectWord(const std::vector<std::string>& fields, std::size_t i, const char* word) {
  if (field(fields, i, word) != word) {
    throw ProtocolError(fmt::format("tracker reply '{}': expected '{}' at field {}", joined(fields), word, i + 1));
  }
}

std::string number(double v) { return fmt::format("{:.6f}", v); }

}  // namespace

const char* errorName(int code) {
  switch (static_cast<ErrorCode>(code)) {
    case ErrorCode::kUnknownCommand:
      return "unknown command";
    case ErrorCode::kBadArgument:
      return "bad argument";
    case ErrorCode::kNotInitialised:
      return "not initialised";
    case ErrorCode::kBeamBroken:
      return "beam broken";
    case ErrorCode::kOutOfRange:
      return "out of range";
    case ErrorCode::kStreaming:
      return "continuous measurement running";
    case ErrorCode::kInternal:
      return "internal error";
  }
  return "error";
}

std::optional<double> reflectorRadiusMm(const std::string& name) {
  if (name == "RRR1.5") return 19.05;
  if (name == "RRR0.875") return 11.1125;
  if (name == "RRR0.5") return 6.35;
  return std::nullopt;
}

int Reply::error_code() const { return fields.empty() ? 0 : parseInteger(fields[0], "error code"); }

std::string Reply::error_text() const {
  return fields.size() < 2 ? std::string() : joined(std::vector<std::string>(fields.begin() + 1, fields.end()));
}

double parseNumber(const std::string& text, const char* what) {
  double v = 0.0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
  if (ec != std::errc() || end != text.data() + text.size() || !std::isfinite(v)) {
    throw ProtocolError(fmt::format("tracker: {} '{}' is not a number", what, text));
  }
  return v;
}

int parseInteger(const std::string& text, const char* what) {
  const double v = parseNumber(text, what);
  if (!(v >= std::numeric_limits<int>::min() && v <= std::numeric_limits<int>::max()) || v != std::floor(v))
    throw ProtocolError(fmt::format("tracker: {} '{}' is not a whole number in range", what, text));
  return static_cast<int>(v);
}

namespace {

/// "<head> field field ...\n"
std::string line(std::string head, const std::vector<std::string>& fields) {
  for (const auto& f : fields) head += " " + f;
  return head + "\n";
}

}  // namespace

std::string formatRequest(const Request& r) { return line(fmt::format("{} {}", r.tag, r.verb), r.args); }

/// The words of a received line (at least two). @throws ProtocolError
std::vector<std::string> wordsOf(std::string_view raw, const char* expected) {
  const auto text = trimEnd(raw);
  if (text.size() > kMaxLineBytes) malformed(text, fmt::format("longer than {} bytes", kMaxLineBytes));
  auto words = split(text);
  if (words.size() < 2) malformed(text, std::string("expected ") + expected);
  return words;
}

Request parseRequest(std::string_view raw) {
  const auto line = trimEnd(raw);
  const auto words = wordsOf(raw, "'<tag> <VERB> [args]'");
  Request r;
  r.tag = parseTag(words[0], line);
  r.verb = words[1];
  r.args.assign(words.begin() + 2, words.end());
  return r;
}

std::string formatReply(const Reply& r) {
  const char* kind = r.kind == Reply::Kind::kOk ? "OK" : r.kind == Reply::Kind::kError ? "ERR" : "BUSY";
  return line(fmt::format("{} {}", r.tag, kind), r.fields);
}

std::string formatEvent(const Event& e) { return line("! " + e.kind, e.fields); }

Message parseMessage(std::string_view raw) {
  const auto line = trimEnd(raw);
  const auto words = wordsOf(raw, "'<tag> OK|ERR|BUSY ...' or '! EVENT ...'");
  if (words[0] == "!") return Event{words[1], std::vector<std::string>(words.begin() + 2, words.end())};
  Reply r;
  r.tag = parseTag(words[0], line);
  if (words[1] == "OK") {
    r.kind = Reply::Kind::kOk;
  } else if (words[1] == "ERR") {
    r.kind = Reply::Kind::kError;
    if (words.size() < 3) malformed(line, "ERR without a code");
  } else if (words[1] == "BUSY") {
    r.kind = Reply::Kind::kBusy;
  } else {
    malformed(line, "the reply kind must be OK, ERR or BUSY");
  }
  r.fields.assign(words.begin() + 2, words.end());
  return r;
}

std::vector<std::string> helloFields(const Hello& h) {
  return {"MTCAL-TRACKER", "PROTO", fmt::format("{}.{}", h.major, h.minor), "MODEL", h.model, "SERIAL", h.serial, "FW",
          h.firmware};
}

Hello parseHello(const std::vector<std::string>& f) {
  expectWord(f, 0, "MTCAL-TRACKER");
  expectWord(f, 1, "PROTO");
  const std::string& version = field(f, 2, "protocol version");
  const auto dot = version.find('.');
  Hello h;
  if (dot == std::string::npos)
    throw ProtocolError(fmt::format("tracker: protocol version '{}' is not major.minor", version));
  h.major = parseInteger(version.substr(0, dot), "protocol major version");
  h.minor = parseInteger(version.substr(dot + 1), "protocol minor version");
  if (h.major != kProtocolMajor) {
    throw ProtocolError(fmt::format("tracker speaks protocol {}.{}, this parser reads {}.x (docs/protocols/tracker.md)",
                                    h.major, h.minor, kProtocolMajor));
  }
  expectWord(f, 3, "MODEL");
  h.model = field(f, 4, "model");
  expectWord(f, 5, "SERIAL");
  h.serial = field(f, 6, "serial");
  expectWord(f, 7, "FW");
  h.firmware = field(f, 8, "firmware");
  return h;
}

std::vector<std::string> pointFields(const Point& p) {
  return {"PT",
          number(p.xyz_mm[0]),
          number(p.xyz_mm[1]),
          number(p.xyz_mm[2]),
          fmt::format("{:.3f}", p.rms_um),
          number(p.time_s),
          std::to_string(p.readings)};
}

Point parsePoint(const std::vector<std::string>& f) {
  expectWord(f, 0, "PT");
  Point p;
  for (int k = 0; k < 3; ++k)
    p.xyz_mm[static_cast<std::size_t>(k)] =
        parseNumber(field(f, 1 + static_cast<std::size_t>(k), "coordinate"), "coordinate");
  p.rms_um = parseNumber(field(f, 4, "rms"), "rms");
  p.time_s = parseNumber(field(f, 5, "time"), "time");
  p.readings = parseInteger(field(f, 6, "readings"), "readings");
  return p;
}

Event streamPointEvent(const StreamPoint& p) {
  return {"PT",
          {std::to_string(p.seq), number(p.time_s), number(p.xyz_mm[0]), number(p.xyz_mm[1]), number(p.xyz_mm[2])}};
}

StreamPoint parseStreamPoint(const Event& e) {
  if (e.kind != "PT") throw ProtocolError("tracker: event '" + e.kind + "' is not a stream point");
  StreamPoint p;
  const double seq = parseNumber(field(e.fields, 0, "sequence"), "sequence");
  if (seq < 0 || seq > 4294967295.0 || seq != std::floor(seq))
    throw ProtocolError("tracker: stream point sequence out of range");
  p.seq = static_cast<std::uint32_t>(seq);
  p.time_s = parseNumber(field(e.fields, 1, "time"), "time");
  for (int k = 0; k < 3; ++k)
    p.xyz_mm[static_cast<std::size_t>(k)] =
        parseNumber(field(e.fields, 2 + static_cast<std::size_t>(k), "coordinate"), "coordinate");
  return p;
}

std::vector<std::string> statusFields(const Status& s) {
  return {"STATUS",
          s.state,
          "BEAM",
          s.beam_locked ? "LOCKED" : "BROKEN",
          "REFLECTOR",
          s.reflector.empty() ? "-" : s.reflector,
          "ENV",
          fmt::format("{:.2f}", s.air_temp_c),
          fmt::format("{:.2f}", s.pressure_hpa),
          fmt::format("{:.1f}", s.humidity_pct)};
}

Status parseStatus(const std::vector<std::string>& f) {
  expectWord(f, 0, "STATUS");
  Status s;
  s.state = field(f, 1, "state");
  expectWord(f, 2, "BEAM");
  const std::string& beam = field(f, 3, "beam state");
  if (beam != "LOCKED" && beam != "BROKEN")
    throw ProtocolError("tracker: beam state '" + beam + "' is not LOCKED or BROKEN");
  s.beam_locked = beam == "LOCKED";
  expectWord(f, 4, "REFLECTOR");
  s.reflector = field(f, 5, "reflector");
  expectWord(f, 6, "ENV");
  s.air_temp_c = parseNumber(field(f, 7, "air temperature"), "air temperature");
  s.pressure_hpa = parseNumber(field(f, 8, "pressure"), "pressure");
  s.humidity_pct = parseNumber(field(f, 9, "humidity"), "humidity");
  return s;
}

}  // namespace mtcal::drivers::tracker
