#pragma once
// Splitting and number parsing shared by the ASCII line protocols (probe box, temperature
// logger): whitespace-separated fields, numbers that must use the whole field.

#include <charconv>
#include <cmath>
#include <sstream>
#include <string>
#include <type_traits>
#include <vector>

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

}  // namespace mtcal::drivers::ascii
