#pragma once
// Whole numbers read from stored JSON (a damaged or hand-edited archive may hold anything):
// checked before they become an int, where a float beyond the range would be undefined.

#include <cmath>
#include <nlohmann/json.hpp>
#include <string>

#include "mtcal/error.h"

namespace mtcal::processing {

/// @throws InputError naming `what` unless `v` is a whole number in [lo, hi]
inline int wholeNumber(const nlohmann::json& v, const std::string& what, int lo, int hi) {
  const double d = v.is_number() ? v.get<double>() : std::nan("");
  if (!(d >= lo && d <= hi) || d != std::floor(d))
    throw InputError(what + ": " + v.dump() + " is not a whole number from " + std::to_string(lo) + " to " +
                     std::to_string(hi));
  return static_cast<int>(d);
}

}  // namespace mtcal::processing
