#pragma once
// What the ASCII line protocols (probe box, temperature logger) share: whitespace-separated
// fields, numbers that must use the whole field, the ERR reply, the IDN reply, value/status
// pairs, and the messages naming the device and the line.

#include <fmt/format.h>

#include <array>
#include <charconv>
#include <cmath>
#include <sstream>
#include <string>
#include <type_traits>
#include <vector>

#include "mtcal/error.h"

namespace mtcal::drivers::ascii {

inline std::vector<std::string> fields(const std::string& line) {
  std::vector<std::string> out;
  std::istringstream in(line);
  std::string f;
  while (in >> f) out.push_back(f);
  return out;
}

/// The field as a number of type T; calls `malformed(why)` (which must throw) otherwise.
template <typename T, typename Malformed>
T number(const std::string& text, Malformed&& malformed) {
  T v{};
  const auto [ptr, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
  if (ec != std::errc() || ptr != text.data() + text.size()) malformed("'" + text + "' is not a number");
  if constexpr (std::is_floating_point_v<T>) {
    if (!std::isfinite(v)) malformed("'" + text + "' is not finite");
  }
  return v;
}

/// A line as sent: the text and CR LF.
inline std::string line(const std::string& text) { return text + "\r\n"; }

/// The reply parsing of one device, its errors naming it.
class Replies {
 public:
  explicit Replies(const char* device) : device_(device) {}

  /// @throws ProtocolError "DEVICE: malformed reply 'LINE': WHY"
  [[noreturn]] void malformed(const std::string& line, const std::string& why) const {
    throw ProtocolError(fmt::format("{}: malformed reply '{}': {}", device_, line, why));
  }
  /// @throws DeviceError "DEVICE refused: ERR code text" for an error reply
  void checkError(const std::string& line) const {
    if (line.rfind("ERR", 0) == 0) throw DeviceError(fmt::format("{} refused: {}", device_, line));
  }
  template <typename T>
  T number(const std::string& text, const std::string& line) const {
    return ascii::number<T>(text, [&](const std::string& why) { malformed(line, why); });
  }
  /// "IDN maker,model,serial,firmware"
  std::array<std::string, 4> identity(const std::string& text) const {
    checkError(text);
    if (text.rfind("IDN ", 0) != 0) malformed(text, "expected IDN");
    std::vector<std::string> parts;
    std::stringstream in(text.substr(4));
    std::string part;
    while (std::getline(in, part, ',')) parts.push_back(part);
    if (parts.size() != 4) malformed(text, "expected maker,model,serial,firmware");
    return {parts[0], parts[1], parts[2], parts[3]};
  }
  /// `expected` value/status pairs from field `from` on; `status(code, line)` parses a status.
  template <typename Reading, typename Status>
  std::vector<Reading> pairs(const std::vector<std::string>& f, std::size_t from, int expected, const std::string& line,
                             Status&& status) const {
    if (f.size() != from + 2 * static_cast<std::size_t>(expected)) {
      malformed(line, fmt::format("{} channel fields, expected {}", f.size() - from, 2 * expected));
    }
    std::vector<Reading> out;
    for (std::size_t i = from; i < f.size(); i += 2)
      out.push_back({number<double>(f[i], line), status(f[i + 1], line)});
    return out;
  }

 private:
  const char* device_;
};

/// "IDN maker,model,serial,firmware" as sent.
inline std::string identityLine(const std::string& maker, const std::string& model, const std::string& serial,
                                const std::string& firmware) {
  return line(fmt::format("IDN {},{},{},{}", maker, model, serial, firmware));
}

}  // namespace mtcal::drivers::ascii
