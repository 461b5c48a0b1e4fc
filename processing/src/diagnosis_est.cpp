// The candidate catalogue of error separation (three-probe stepping runs): probe 3 predicted by
// the two-probe separation of probes 1 and 2, interleaved folds, and the method's broken
// assumptions (unequal probe zeros, spacing error, carriage yaw).
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "diagnosis_internal.h"
#include "mtcal/error.h"
#include "mtcal/processing/diagnosis.h"

namespace mtcal::processing {

using detail::candidate;
using detail::shape;

DiagnosisData estDiagnosisData(const EstRunInput& in) {
  const std::size_t steps = in.position_mm.size();
  if (in.v1_um.size() != steps || in.v2_um.size() != steps || in.v3_um.size() != steps) {
    throw InputError(fmt::format("{}: three probes needed at every step ({} steps, {} / {} / {} readings)", in.source,
                                 steps, in.v1_um.size(), in.v2_um.size(), in.v3_um.size()));
  }
  if (!(in.spacing_mm > 0.0)) throw InputError(fmt::format("{}: the probe spacing must be positive", in.source));
  for (std::size_t k = 1; k < steps; ++k) {
    if (std::abs(in.position_mm[k] - in.position_mm[k - 1] - in.spacing_mm) > 1e-6) {
      throw InputError(
          fmt::format("{}: step {} moves {} mm; the two-probe prediction needs steps of the probe spacing {} mm",
                      in.source, k, in.position_mm[k] - in.position_mm[k - 1], in.spacing_mm));
    }
  }
  if (steps < 9) throw InputError(fmt::format("{}: {} steps; a diagnosis needs 9 or more", in.source, steps));
  const std::size_t n = steps - 1;
  const double d_mm = in.spacing_mm;
  // Two-probe profile: m(x_{k+1}) - m(x_k) = v2_k - v1_k; probe 3 reads m(x_k + 2d) - e_k.
  std::vector<double> profile(steps + 1, 0.0);
  for (std::size_t k = 0; k < steps; ++k) profile[k + 1] = profile[k] + in.v2_um[k] - in.v1_um[k];
  DiagnosisData data;
  data.kind = "est";
  data.source = in.source;
  data.main_variable = "position_mm";
  data.value_name = "probe 3 reading";
  data.measured.resize(static_cast<Eigen::Index>(n));
  data.simulated.resize(data.measured.size());
  Eigen::VectorXd x(data.measured.size()), next(x.size()), slope(x.size()), step(x.size());
  for (std::size_t k = 0; k < n; ++k) {
    const auto i = static_cast<Eigen::Index>(k);
    data.measured(i) = in.v3_um[k];
    data.simulated(i) = (in.v2_um[k] - in.v1_um[k]) + (in.v2_um[k + 1] - in.v1_um[k + 1]) + in.v1_um[k];
    x(i) = in.position_mm[k];
    next(i) = in.position_mm[k + 1];
    step(i) = static_cast<double>(k);
    // Slope of the profile at probe 3 (x_k + 2d), by the central difference.
    const std::size_t c = std::min(k + 2, steps);
    slope(i) = (profile[std::min(c + 1, steps)] - profile[c - 1]) / ((std::min(c + 1, steps) - (c - 1)) * d_mm);
  }
  data.model_description =
      "the two-probe separation of probes 1 and 2 (no carriage yaw, exact probe zeros and spacing)";
  data.variables = {{"position_mm", "mm", x},
                    {"step", "", step},
                    {"next_position_mm", "mm", next},
                    {"profile_slope", "um/mm", slope}};
  data.baseline = Eigen::MatrixXd(static_cast<Eigen::Index>(n), 0);
  data.baseline_description = "nothing free: the prediction of probe 3 is fixed by probes 1 and 2";
  // Interleaved folds: the extensions are local along the guideway (the yaw's spline), so a
  // block of steps left out would be extrapolated; every step's residual is independent of
  // its neighbours' (the carriage's motion cancels in the prediction).
  data.fold.resize(static_cast<Eigen::Index>(n));
  for (std::size_t k = 0; k < n; ++k) data.fold(static_cast<Eigen::Index>(k)) = static_cast<int>(k % 4);
  data.fold_description = "every fourth step (four interleaved sets), each set left out in turn";
  data.candidates.push_back(candidate(
      "probe_offset", "step", "the probes' zeros are not equal: a constant c1 - 2 c2 + c3 on probe 3's prediction",
      {shape("constant", {})}, {{"zero_combination", "um", 1.0}}));
  data.candidates.push_back(
      candidate("scale_error", "profile_slope",
                "probe spacing error: probe 3 is not at twice the spacing, so its reading carries the profile's slope",
                {shape("linear", {"profile_slope"})}, {{"spacing_error", "mm", 1.0}}));
  auto yaw = candidate(
      "carriage_yaw", "position_mm",
      "the carriage turns (yaws) as it moves, which the two-probe method takes for straightness: probe 3 sees d times "
      "the change of yaw per step",
      {shape("step_difference", {"position_mm", "next_position_mm"}, d_mm * 1e-3)}, {});
  yaw.shapes.front().spans = std::clamp(static_cast<int>(n) / 5, 1, 12);
  yaw.shapes.front().range = {x.minCoeff(), next.maxCoeff()};
  data.candidates.push_back(yaw);
  return data;
}

}  // namespace mtcal::processing
