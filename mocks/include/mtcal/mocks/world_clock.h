#pragma once
// Time of the simulated world, in seconds. Scaled real time: the world runs `time_scale`
// times faster than the steady clock, so a campaign of an hour of machine time can run in
// seconds while the instrument still streams in (scaled) real time.

#include <chrono>

namespace mtcal::mocks {

class WorldClock {
 public:
  explicit WorldClock(double time_scale = 1.0) : time_scale_(time_scale), start_(std::chrono::steady_clock::now()) {}
  double nowS() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count() * time_scale_;
  }
  /// Wall-clock duration of a world-time interval.
  std::chrono::nanoseconds toWall(double world_s) const {
    return std::chrono::nanoseconds(static_cast<long long>(world_s / time_scale_ * 1e9));
  }

 private:
  double time_scale_;
  std::chrono::steady_clock::time_point start_;
};

}  // namespace mtcal::mocks
