#pragma once
// Capturing one target from a sample stream: wait for the dwell, then slide an averaging
// window until the reading is stable. Pure statistics here; the loop is in LinearRun.

#include <span>

#include "mtcal/drivers/instrument.h"

namespace mtcal::acquisition {

struct WindowStats {
  double mean = 0.0;       ///< in the samples' unit (mm for linear and straightness optics, urad for angular)
  double stddev_um = 0.0;  ///< s of the window, in um (urad for angular optics)
  double drift_um = 0.0;   ///< |mean of the second half - mean of the first half|, same unit
  std::size_t beam_lost = 0;
};

/// Statistics of a window of readings. `to_um` converts the samples' unit to the one of the
/// spread: 1000 for readings in mm, 1 for angles in urad. Needs at least 2 samples.
WindowStats windowStats(std::span<const drivers::Sample> window, double to_um = 1000.0);

/// Stable: beam ok throughout, s and drift both within the threshold.
inline bool isStable(const WindowStats& s, double threshold_um) {
  return s.beam_lost == 0 && s.stddev_um <= threshold_um && s.drift_um <= threshold_um;
}

}  // namespace mtcal::acquisition
