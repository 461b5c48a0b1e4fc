// The candidate catalogue of error separation (three-probe stepping runs): probe 3 predicted by
// the two-probe separation of probes 1 and 2, interleaved folds, and the method's broken
// assumptions (unequal probe zeros, spacing error, carriage yaw).
#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

#include "diagnosis_internal.h"
#include "mtcal/error.h"
#include "mtcal/processing/diagnosis.h"

namespace mtcal::processing {

using detail::candidate;
using detail::shape;

namespace {

/// The noise of probe 3's residual (v3_k - v2_k - v2_k+1 + v1_k+1, each a step's mean) as the
/// probes' scatter over the readings averaged at each step states it: each probe's variance of
/// one reading pooled over the steps (n - 1 degrees of freedom each), through the mean of the
/// four readings' variances (s^2 / n) along the run; its degrees of freedom by Satterthwaite's
/// approximation. Nothing where a probe's scatter is not known.
void stateNoiseFromProbeScatter(const EstRunInput& in, DiagnosisData& data) {
  const std::size_t steps = in.position_mm.size();
  const auto pooled = pooledProbeScatter(in);
  // A probe whose every step read once states nothing; one whose readings never changed at a
  // step (its resolution) states a noise of zero, which would make any residual significant.
  for (std::size_t p = 0; p < 3; ++p)
    if (!(pooled.dof[p] > 0.0) || !(pooled.variance_um2[p] > 0.0)) return;
  const auto& variance = pooled.variance_um2;
  const auto& dof = pooled.dof;
  // Each reading's share of the residual's variance: 1 / n of its step, averaged along the run.
  // Neighbouring residuals share probe 2's reading of the later step: their covariance.
  std::array<double, 3> share{};
  double shared = 0.0;
  for (std::size_t k = 0; k + 1 < steps; ++k) {
    const double now = 1.0 / in.readings[k], next = 1.0 / in.readings[k + 1];
    share[0] += next;
    share[1] += now + next;
    share[2] += now;
    if (k + 2 < steps) shared += next;
  }
  double stated = 0.0, spread = 0.0;
  for (std::size_t p = 0; p < 3; ++p) {
    const double part = share[p] / static_cast<double>(steps - 1) * variance[p];
    stated += part;
    spread += part * part / dof[p];
  }
  data.stated_noise_variance = stated;
  data.stated_noise_dof = stated * stated / spread;
  // The correlation follows the probes' scatter (1/4 for equal probes; below 1/2 while probes 1
  // and 3 scatter at all, held below 0.45 where steps' counts differ wildly).
  data.lag1_correlation = std::min(0.45, shared / static_cast<double>(steps - 2) * variance[1] / stated);
  data.stated_noise_description = "the probes' scatter over the readings averaged at each step";
}

/// The slopes of a profile sampled every `spacing_mm` (h), at its samples, by the natural cubic
/// spline through them: its first derivatives solve s_{j-1} + 4 s_j + s_{j+1} =
/// 3 (y_{j+1} - y_{j-1}) / h, with 2 s_0 + s_1 = 3 (y_1 - y_0) / h and its mirror at the far end
/// (Thomas' algorithm). A central difference over two steps reads a wave's slope at sin(w) / w of
/// its size (w = 2 pi h / wavelength: 0.64 for a wave of four steps, 0.19 for one of 2.4), the
/// spline at 3 sin(w) / (w (2 + cos w)) (0.95 and 0.50).
std::vector<double> splineSlopes(const std::vector<double>& y, double spacing_mm) {
  const std::size_t m = y.size();  // the off-diagonals are all 1
  std::vector<double> diagonal(m, 4.0), right(m);
  diagonal.front() = diagonal.back() = 2.0;
  right.front() = 3.0 * (y[1] - y[0]) / spacing_mm;
  right.back() = 3.0 * (y[m - 1] - y[m - 2]) / spacing_mm;
  for (std::size_t j = 1; j + 1 < m; ++j) right[j] = 3.0 * (y[j + 1] - y[j - 1]) / spacing_mm;
  for (std::size_t j = 1; j < m; ++j) {  // eliminate below the diagonal
    diagonal[j] -= 1.0 / diagonal[j - 1];
    right[j] -= right[j - 1] / diagonal[j - 1];
  }
  std::vector<double> slope(m);
  slope[m - 1] = right[m - 1] / diagonal[m - 1];
  for (std::size_t j = m - 1; j-- > 0;) slope[j] = (right[j] - slope[j + 1]) / diagonal[j];
  return slope;
}

}  // namespace

ProbeScatter pooledProbeScatter(const EstRunInput& in) {
  const std::size_t steps = in.position_mm.size();
  ProbeScatter out;
  if (std::all_of(in.scatter_um.begin(), in.scatter_um.end(), [](const auto& s) { return s.empty(); }) &&
      in.readings.empty())
    return out;
  const std::size_t probes = in.v3_um.empty() ? 2 : 3;
  if (in.readings.size() != steps || std::any_of(in.scatter_um.begin(), in.scatter_um.begin() + probes,
                                                 [&](const auto& s) { return s.size() != steps; })) {
    throw InputError(
        fmt::format("{}: the probes' scatter and readings per step must be given for all {} steps", in.source, steps));
  }
  for (std::size_t p = 0; p < probes; ++p) {
    double sum_of_squares = 0.0;
    for (std::size_t k = 0; k < steps; ++k) {
      const int n = in.readings[k];
      const double s = in.scatter_um[p][k];
      if (n < 1) throw InputError(fmt::format("{}: step {} averaged {} readings", in.source, k, n));
      if (n < 2 || std::isnan(s)) continue;
      if (!(s >= 0.0) || !std::isfinite(s))
        throw InputError(fmt::format("{}: step {}: probe {}'s scatter {} um", in.source, k, p + 1, s));
      sum_of_squares += (n - 1) * s * s;
      out.dof[p] += n - 1;
    }
    if (out.dof[p] > 0.0) out.variance_um2[p] = sum_of_squares / out.dof[p];
  }
  return out;
}

DiagnosisData estDiagnosisData(const EstRunInput& in) {
  const std::size_t steps = in.position_mm.size();
  if (in.v1_um.size() != steps || in.v2_um.size() != steps || in.v3_um.size() != steps) {
    throw InputError(fmt::format("{}: three probes needed at every step ({} steps, {} / {} / {} readings)", in.source,
                                 steps, in.v1_um.size(), in.v2_um.size(), in.v3_um.size()));
  }
  if (!(in.spacing_mm > 0.0)) throw InputError(fmt::format("{}: the probe spacing must be positive", in.source));
  for (std::size_t k = 0; k < steps; ++k) {
    if (!std::isfinite(in.position_mm[k])) throw InputError(fmt::format("{}: step {} has no position", in.source, k));
  }
  for (std::size_t k = 1; k < steps; ++k) {
    if (std::abs(in.position_mm[k] - in.position_mm[k - 1] - in.spacing_mm) > 1e-6) {
      throw InputError(fmt::format(
          "{}: step {} (x {} mm) moves {} mm from x {} mm; the two-probe prediction needs steps of the probe "
          "spacing {} mm",
          in.source, k, in.position_mm[k], in.position_mm[k] - in.position_mm[k - 1], in.position_mm[k - 1],
          in.spacing_mm));
    }
  }
  if (steps < 9)
    throw InputError(
        fmt::format("{}: {} step{}; a diagnosis needs 9 or more", in.source, steps, steps == 1 ? "" : "s"));
  const std::size_t n = steps - 1;
  const double d_mm = in.spacing_mm;
  // Two-probe profile: m(x_{k+1}) - m(x_k) = v2_k - v1_k; probe 3 reads m(x_k + 2d) - e_k.
  std::vector<double> profile(steps + 1, 0.0);
  for (std::size_t k = 0; k < steps; ++k) profile[k + 1] = profile[k] + in.v2_um[k] - in.v1_um[k];
  const std::vector<double> profile_slope = splineSlopes(profile, in.spacing_mm);
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
    slope(i) = profile_slope[k + 2];  // at probe 3 (x_k + 2d)
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
  data.candidates.back().of_setup = true;
  // The slope about its mean: the mean slope (the line's tilt) times a spacing error is a
  // constant on probe 3, which the zeros' combination is too: only the slope's changes tell it.
  // Probe 3 off by more than a tenth of the spacing would be seen with a rule: a fit asking for
  // more is another cause whose course the slope's resembles.
  data.candidates.push_back(
      candidate("scale_error", "profile_slope",
                "probe spacing error: probe 3 is not at twice the spacing, so its reading carries the profile's slope",
                {shape("linear", {"profile_slope"}, 1.0, slope.mean())}, {{"spacing_error", "mm", 1.0, 0.1 * d_mm}}));
  data.candidates.back().of_setup = true;
  // The yaw as a smooth curve along the run: 2, 4, 8 ... spans up to one per five steps, so
  // that a smooth yaw is not fitted with more freedom (and noise) than it needs.
  const int most_spans = std::clamp(static_cast<int>(n) / 5, 1, 12);
  for (int spans = std::min(2, most_spans);; spans = std::min(2 * spans, most_spans)) {
    auto yaw = candidate(
        "carriage_yaw", "position_mm",
        fmt::format("the carriage turns (yaws) as it moves, which the two-probe method takes for straightness: probe "
                    "3 sees d times the change of yaw per step (the yaw a cubic spline of {} spans along the run)",
                    spans),
        {shape("step_difference", {"position_mm", "next_position_mm"}, d_mm * 1e-3)}, {});
    yaw.shapes.front().spans = spans;
    yaw.shapes.front().range = {x.minCoeff(), next.maxCoeff()};
    data.candidates.push_back(yaw);
    if (spans == most_spans) break;
  }
  const auto yaw_range = data.candidates.back().shapes.front().range;
  // A yaw in one wave of the guideway: a sine of the position, its wavelength searched from
  // `shortest_mm` to `longest_mm` (frequencies a third of the run's apart).
  const double span_mm = next.maxCoeff() - x.minCoeff();
  const auto addWave = [&](const std::string& kind, const std::string& cause, double shortest_mm, double longest_mm) {
    auto wave =
        candidate("carriage_yaw", "position_mm", cause, {shape(kind, {"position_mm", "next_position_mm"}, d_mm * 1e-3)},
                  {{"sin", "urad", 1.0}, {"cos", "urad", 1.0}});
    wave.shapes.front().range = yaw_range;
    const double df = 1.0 / (3.0 * span_mm);
    for (double f = 1.0 / longest_mm; f <= 1.0 / shortest_mm; f += df) wave.search.push_back(1.0 / f);
    wave.independent_tries = std::max(1.0, wave.search.size() / 3.0);
    wave.shapes.front().searched = wave.search.front();
    wave.searched_name = "wavelength";
    wave.searched_unit = "mm";
    data.candidates.push_back(wave);
  };
  // A yaw that changes within a few steps (following the rail's short waviness) is beyond the
  // spline's spans: from 2.2 steps (shorter waves alias: the steps sample the yaw once per
  // spacing) up to where the spline's most spans take over (10 steps or more: at most one span
  // per five steps). It keeps its own mean rate.
  const double spline_takes_over_mm = 2.0 * span_mm / most_spans;
  addWave("harmonic_difference",
          "the carriage yaws in a short wave along the guideway (following the rail's waviness), which the "
          "two-probe method takes for straightness",
          2.2 * d_mm, spline_takes_over_mm);
  // A yaw in one long wave (a wavelength of the run or so): from twice the run down to the short
  // wave's longest or half the run, whichever is shorter (on runs of fewer than 25 steps the two
  // waves' ranges overlap; they differ in the mean rate). Two terms where a spline bending as
  // often needs more. Its change is taken about its mean, as the spline's is: the wave's mean
  // rate reads as the zeros.
  addWave("harmonic_difference_about_mean",
          "the carriage yaws in a long wave along the guideway, which the two-probe method takes for straightness",
          std::min(spline_takes_over_mm, span_mm / 2.0), 2.0 * span_mm);
  // Probe 3's reading less the two-probe prediction shares probe 2's reading of the next step
  // with its neighbour: with equal noise on the probes, the residuals' correlation is 1/4.
  data.lag1_correlation = 0.25;
  stateNoiseFromProbeScatter(in, data);  // and the correlation its probes' scatter gives
  data.notes.push_back(
      "three probes cannot see a carriage yaw that is constant along the run or changes at a constant rate: the "
      "first is a tilt of the probe line, the second reads as a constant on probe 3, the probes' zero combination "
      "(zero the probes on a reference flat); a yaw that repeats every step (wavelength the spacing) reads nothing; a "
      "spacing error shows only where the profile's slope changes (on a straight, tilted line it is a constant, "
      "taken for the zeros)");
  return data;
}

}  // namespace mtcal::processing
