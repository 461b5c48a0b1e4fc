#pragma once
// The small, fast circular test the suite runs on the simulated machine: 50 mm radius at
// (300, 300, 300) mm, 2000 mm/min, 30 deg overshoot, 0.5 s settling, both directions, the bar
// zeroed at its 50 mm length.

#include "mtcal/acquisition/circle_plan.h"

namespace mtcal::testing {

inline acquisition::CirclePlan quickCirclePlan() {
  acquisition::CirclePlan p;
  p.name = "quick";
  p.radius_mm = 50.0;
  p.centre_mm = Eigen::Vector3d(300.0, 300.0, 300.0);
  p.feed_mm_per_min = 2000.0;
  p.overshoot_deg = 30.0;
  p.settle_s = 0.5;
  p.calibrator_length_mm = p.radius_mm;  // the 50 mm bar zeroed in its own calibrator
  return p;
}

}  // namespace mtcal::testing
