#pragma once
// Reading plan files: what every plan type shares (messages "SOURCE: key 'k': why").

#include <fmt/format.h>

#include <Eigen/Core>
#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <set>
#include <string>
#include <type_traits>

#include "mtcal/error.h"

namespace mtcal::acquisition::plan_json {

[[noreturn]] inline void bad(const std::string& source, const std::string& key, const std::string& why) {
  throw InputError(source + ": key '" + key + "': " + why);
}

template <typename T>
void read(const nlohmann::json& j, const char* key, T& out, const std::string& source) {
  if (!j.contains(key)) return;
  const auto& v = j[key];
  if constexpr (std::is_same_v<T, bool>) {
    if (!v.is_boolean()) bad(source, key, "must be true or false");
  } else if constexpr (std::is_same_v<T, std::string>) {
    if (!v.is_string()) bad(source, key, "must be a string");
  } else if constexpr (std::is_integral_v<T>) {
    if (!v.is_number_integer()) bad(source, key, "must be an integer");
    if constexpr (std::is_unsigned_v<T>) {
      if (v.get<long long>() < 0) bad(source, key, "must not be negative");
    }
  } else {
    if (!v.is_number()) bad(source, key, "must be a number");
  }
  out = v.get<T>();
}

inline void positive(double value, const std::string& source, const char* key) {
  if (!(value > 0.0) || !std::isfinite(value)) bad(source, key, "must be > 0 (got " + fmt::format("{}", value) + ")");
}
inline void nonNegative(double value, const std::string& source, const char* key) {
  if (!(value >= 0.0) || !std::isfinite(value)) bad(source, key, "must be >= 0 (got " + fmt::format("{}", value) + ")");
}

/// A machine coordinate lies within this of the origin (100 m): a value beyond is in um, not mm
/// (a plan's points, a line's position, a circle's centre, given in a plan or an option).
inline constexpr double kMaxMachineCoordinateMm = 1e5;

/// A point or an offset [x, y, z] in mm: three finite numbers, each within `max_abs_mm` of
/// `from` (a value beyond is in um, not mm). @throws InputError naming the coordinate
inline Eigen::Vector3d pointMm(const nlohmann::json& j, const std::string& source, const std::string& key,
                               double max_abs_mm, const char* from) {
  if (!j.is_array() || j.size() != 3) bad(source, key, "must be [x, y, z] in mm");
  Eigen::Vector3d p;
  for (std::size_t i = 0; i < 3; ++i) {
    const char axis = "xyz"[i];
    if (!j[i].is_number() || !std::isfinite(j[i].get<double>()))
      bad(source, key, fmt::format("its {} is not a finite number (mm)", axis));
    p(static_cast<Eigen::Index>(i)) = j[i].get<double>();
    if (std::abs(j[i].get<double>()) > max_abs_mm)
      bad(source, key,
          fmt::format("its {} is {:g} mm: beyond {:g} m of {} (mm, not um)", axis, j[i].get<double>(),
                      max_abs_mm / 1000.0, from));
  }
  return p;
}

/// Checks a plan is of `type` (circle, est, gantry, linear, thermal) and has only that type's
/// keys. A plan of another type (by its "type" key, or without one by its keys) is named with
/// the command that runs it; an unknown key gets the nearest known one suggested.
/// @throws InputError "SOURCE: key 'k': why"
void checkTypeAndKeys(const nlohmann::json& j, const std::string& source, const std::string& type);

}  // namespace mtcal::acquisition::plan_json
