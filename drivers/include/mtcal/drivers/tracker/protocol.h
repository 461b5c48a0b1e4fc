#pragma once
// Line protocol of the laser tracker over TCP (docs/protocols/tracker.md), version 1.x:
//
//   host -> tracker   "<tag> <VERB> [arg ...]\n"         tag: 1..4294967295, echoed in the reply
//   tracker -> host   "<tag> OK [field ...]\n"           the command is done
//                     "<tag> ERR <code> <text>\n"        it failed (codes below)
//                     "<tag> BUSY\n"                     the tracker is busy (initialising,
//                                                        going home): ask again later
//                     "! <EVENT> [field ...]\n"          unsolicited: stream points, beam state
//
// Fields are separated by single spaces; numbers use '.' and no thousands separator. The
// version is negotiated by HELLO: a tracker of another major version is refused; a newer
// minor version may append fields to any reply or event, which this parser ignores (the
// rule that keeps 1.x parsers compatible). Both sides of the codec live here: pure
// functions, no I/O.

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

namespace mtcal::drivers::tracker {

inline constexpr int kProtocolMajor = 1;
inline constexpr int kProtocolMinor = 0;
inline constexpr std::size_t kMaxLineBytes = 1024;
inline constexpr std::uint32_t kMaxRateHz = 1000;
inline constexpr int kMaxIntegrationMs = 60000;

/// Error codes of ERR replies.
enum class ErrorCode : int {
  kUnknownCommand = 1,
  kBadArgument = 2,
  kNotInitialised = 3,
  kBeamBroken = 4,  ///< no reflector locked
  kOutOfRange = 5,  ///< a value outside what the tracker accepts
  kStreaming = 6,   ///< not allowed during continuous measurement
  kInternal = 7,
};
const char* errorName(int code);  ///< "unknown command", ... ("error" for other codes)

struct Request {
  std::uint32_t tag = 0;
  std::string verb;
  std::vector<std::string> args;
};

struct Reply {
  enum class Kind { kOk, kError, kBusy } kind = Kind::kOk;
  std::uint32_t tag = 0;
  std::vector<std::string> fields;  ///< OK: the payload; ERR: code then the text's words
  int error_code() const;           ///< ERR only
  std::string error_text() const;   ///< ERR only: the text after the code
};

struct Event {
  std::string kind;  ///< "PT", "BEAM", ...
  std::vector<std::string> fields;
};

using Message = std::variant<Reply, Event>;

std::string formatRequest(const Request& request);
/// @throws ProtocolError quoting the line (no tag, no verb, over-long)
Request parseRequest(std::string_view line);
std::string formatReply(const Reply& reply);
std::string formatEvent(const Event& event);
/// @throws ProtocolError quoting the line
Message parseMessage(std::string_view line);

// Payloads. Parsers throw ProtocolError naming the field; they ignore trailing fields.

struct Hello {
  int major = kProtocolMajor, minor = kProtocolMinor;
  std::string model, serial, firmware;
};
/// "MTCAL-TRACKER PROTO <major>.<minor> MODEL <m> SERIAL <s> FW <f>"
std::vector<std::string> helloFields(const Hello& hello);
/// @throws ProtocolError for another major version ("speaks protocol 2.0, this parser reads 1.x")
Hello parseHello(const std::vector<std::string>& fields);

/// A stationary measurement: reflector centre in the tracker's frame (mm), the spread of the
/// readings averaged (um), the tracker's time of the middle of the integration (s), readings.
struct Point {
  std::array<double, 3> xyz_mm{};
  double rms_um = 0.0;
  double time_s = 0.0;
  int readings = 0;
};
/// "PT x y z rms_um time_s readings"
std::vector<std::string> pointFields(const Point& p);
Point parsePoint(const std::vector<std::string>& fields);

/// A point of the continuous measurement: event "PT seq time_s x y z".
struct StreamPoint {
  std::uint32_t seq = 0;
  double time_s = 0.0;
  std::array<double, 3> xyz_mm{};
};
Event streamPointEvent(const StreamPoint& p);
StreamPoint parseStreamPoint(const Event& event);

struct Status {
  std::string state;  ///< READY, BUSY, NOINIT, STREAMING
  bool beam_locked = false;
  std::string reflector;
  double air_temp_c = 20.0, pressure_hpa = 1013.25, humidity_pct = 50.0;
};
/// "STATUS <state> BEAM LOCKED|BROKEN REFLECTOR <name> ENV <t> <p> <h>"
std::vector<std::string> statusFields(const Status& s);
Status parseStatus(const std::vector<std::string>& fields);

/// Radius (mm) of the spherically mounted reflectors v1 knows: RRR1.5, RRR0.875, RRR0.5;
/// none for another name.
std::optional<double> reflectorRadiusMm(const std::string& name);

/// Number in a field, named in errors. @throws ProtocolError
double parseNumber(const std::string& field, const char* what);
/// A whole number field within int. @throws ProtocolError naming `what`
int parseInteger(const std::string& field, const char* what);

}  // namespace mtcal::drivers::tracker
