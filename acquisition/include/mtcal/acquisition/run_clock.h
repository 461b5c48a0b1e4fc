#pragma once
// How a run lets the instruments' time go on.
//
// Real instruments keep their own time: a run waits for their readings to arrive while the
// machine moves on. A simulated world runs in lock step with the run instead: only as far as
// the run has asked, and holds there. A command of the run then falls at the world time the
// run chose, never at one the host's load chose, so a seeded simulation gives the same values
// however busy the computer is (pacing stays in scaled wall-clock time).
//
// The runs call advanceTo with the device time of the last reading they wait for, computed
// from the readings they already have, so asking again while readings are on their way never
// moves the world further.

#include <optional>

namespace mtcal::acquisition {

class RunClock {
 public:
  virtual ~RunClock() = default;
  /// The run needs every reading time-stamped up to `device_time_s` (s of the instruments'
  /// clock): a simulated world runs there and holds. Real instruments: nothing to do.
  virtual void advanceTo(double device_time_s) = 0;
  /// The instruments' time now, when the run can know it (a simulated world, held where the
  /// run left it); nothing for real instruments.
  virtual std::optional<double> nowS() const = 0;
};

/// Real instruments: their readings come by themselves.
RunClock& realTime();

}  // namespace mtcal::acquisition
