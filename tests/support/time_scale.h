#pragma once
// Simulated-world speed for tests. The simulation runs in scaled real time, so a build that
// runs the code 10x slower (sanitizers) must slow the world down as much: set
// MTCAL_TEST_SLOWDOWN (the sanitizer builds' ctest does, see tests/CMakeLists.txt).

#include <cstdlib>
#include <string>

namespace mtcal::testing {

inline double slowdown() {
  const char* text = std::getenv("MTCAL_TEST_SLOWDOWN");
  const double value = text ? std::atof(text) : 1.0;
  return value >= 1.0 ? value : 1.0;
}

/// World seconds per wall second for a test written for `nominal` on a normal build.
inline double timeScale(double nominal) { return nominal / slowdown(); }
inline std::string timeScaleArg(double nominal) { return std::to_string(timeScale(nominal)); }

}  // namespace mtcal::testing
