#pragma once
// Evaluation of positioning accuracy and repeatability of a numerically controlled axis
// per ISO 230-2:2014, clause 3 (definitions) and clause 7 (evaluation).
// Pure function, thread-safe.

#include <optional>
#include <span>
#include <vector>

namespace mtcal::processing {

/// Approach direction of a target: kUp is the positive direction of the axis.
enum class Direction { kUp, kDown };

/// One error value x_ij = P_ij - P_i (measured minus target) at one target and one cycle.
struct PositionDeviation {
  double target_mm = 0.0;
  Direction direction = Direction::kUp;
  int cycle = 0;  ///< j, 1-based; only used to check each (target, direction, cycle) is unique
  double deviation_um = 0.0;
};

/// Results at one target position P_i. Values of a direction that was not measured are empty.
struct Iso230Position {
  double target_mm = 0.0;
  int cycles_up = 0, cycles_down = 0;
  std::optional<double> mean_up_um, mean_down_um;                    ///< x_i up / down (mean over the cycles)
  std::optional<double> s_up_um, s_down_um;                          ///< s_i up / down (n - 1 in the denominator)
  std::optional<double> mean_um;                                     ///< x_i = (x_i up + x_i down) / 2
  std::optional<double> reversal_um;                                 ///< B_i = x_i up - x_i down
  std::optional<double> repeatability_up_um, repeatability_down_um;  ///< R_i = 4 s_i
  std::optional<double> repeatability_um;  ///< R_i = max(2 s_up + 2 s_down + |B_i|, R_i up, R_i down)
};

/// Axis results, clause 3.4 to 3.21 of ISO 230-2:2014. Bidirectional values need both directions.
struct Iso230Result {
  std::vector<Iso230Position> positions;  ///< sorted by target
  int min_cycles = 0;                     ///< fewest cycles at any target and direction
  std::optional<double> B_um, B_mean_um;  ///< max |B_i| and mean of B_i
  std::optional<double> R_up_um, R_down_um, R_um;
  std::optional<double> E_up_um, E_down_um, E_um;
  std::optional<double> M_um;
  std::optional<double> A_up_um, A_down_um, A_um;
};

/// Evaluates a set of deviations. Targets closer than 1 nm are one target.
/// @throws InputError when a target and direction has fewer than 2 cycles (no s), a cycle
///         number repeats, one target lacks a direction the others have, or there are
///         fewer than 2 targets.
Iso230Result evaluateIso230_2(std::span<const PositionDeviation> deviations);

}  // namespace mtcal::processing
