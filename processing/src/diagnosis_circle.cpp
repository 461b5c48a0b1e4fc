// The candidate catalogue of circular tests (ballbar): the nominal circle with the bar's length
// free, folds by sectors, and the causes a circle shows (eccentricity, squareness, scale
// mismatch, reversal steps, servo mismatch, drift).
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <numbers>

#include "diagnosis_internal.h"
#include "mtcal/error.h"
#include "mtcal/processing/diagnosis.h"
#include "mtcal/processing/plane.h"

namespace mtcal::processing {

using detail::candidate;
using detail::checkSizes;
using detail::foldsByBlocks;
using detail::linearDrift;
using detail::shape;
using detail::varies;
using detail::vec;

namespace {

/// The angle past an axis's reversal on a circle of radius_mm in which the axis moves travel_um
/// back from its extreme: R (1 - cos a) = travel (180 deg where the circle is too small).
double angleOfTravelAfterReversalDeg(double travel_um, double radius_mm) {
  return std::acos(std::max(-1.0, 1.0 - travel_um / (1000.0 * radius_mm))) * 180.0 / std::numbers::pi;
}

}  // namespace

DiagnosisData circleDiagnosisData(const CircleRunInput& in) {
  const std::size_t n = in.angle_deg.size();
  checkSizes(n, {in.deviation_um.size(), in.direction.size()}, in.source);
  if (!(in.radius_mm > 0.0) || !(in.feed_mm_per_min > 0.0))
    throw InputError(fmt::format("{}: radius and feed must be positive", in.source));
  DiagnosisData d;
  d.kind = "circle";
  d.source = in.source;
  d.main_variable = "angle_deg";
  d.measured = vec(in.deviation_um);
  d.simulated = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(n));
  d.model_description = "a perfect circle";
  Eigen::VectorXd dir(static_cast<Eigen::Index>(n));
  for (std::size_t i = 0; i < n; ++i) dir(static_cast<Eigen::Index>(i)) = in.direction[i] >= 0 ? 1.0 : -1.0;
  d.variables = {{"angle_deg", "deg", vec(in.angle_deg)}, {"direction", "", dir}};
  if (!in.time_s.empty()) {
    if (in.time_s.size() != n)
      throw InputError(fmt::format("{}: {} times for {} points", in.source, in.time_s.size(), n));
    d.variables.push_back({"time_s", "s", vec(in.time_s)});
  }
  d.baseline = Eigen::MatrixXd::Ones(static_cast<Eigen::Index>(n), 1);
  d.baseline_description = "the nominal circle with the bar's length free";
  Eigen::VectorXd wrapped = vec(in.angle_deg);
  for (auto& a : wrapped) a = std::fmod(std::fmod(a, 360.0) + 360.0, 360.0);
  d.fold = foldsByBlocks(wrapped, 8);
  const bool both_directions = (dir.array() > 0.0).any() && (dir.array() < 0.0).any();
  d.fold_description = fmt::format("eight 45 deg sectors ({}), each left out in turn",
                                   both_directions ? "both directions" : "one direction");
  const double r = in.radius_mm;
  // An axis reverses where it is at its extreme: the plane's first at 0 and 180 deg, its second
  // at 90 and 270. Within a few degrees of it, as it takes up its lost motion or its friction,
  // it reads a spike no smooth cause describes: 3 deg, or, on a circle under 29 mm in radius,
  // the angle in which the axis moves 40 um after reversing, R (1 - cos a); and after it, in the
  // direction of travel, by the angle the circle turns in a servo lag: an axis reverses that much
  // after the programmed angle (0.1 s, a position loop's gain of 10 1/s, about the lowest in
  // use: 9.5 deg at F5000 on R 50 mm).
  constexpr double kLongestServoLagS = 0.1;
  const double reversal_window_deg = std::max(3.0, angleOfTravelAfterReversalDeg(40.0, r));
  const double v_mm_s = in.feed_mm_per_min / 60.0;
  const double servo_lag_deg = v_mm_s / r * kLongestServoLagS * 180.0 / std::numbers::pi;
  d.reversal_at.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    const double past_deg = dir(static_cast<Eigen::Index>(i)) * std::remainder(in.angle_deg[i], 90.0);
    const auto quarter = static_cast<long>(std::lround(in.angle_deg[i] / 90.0));
    d.reversal_at[i] = past_deg >= -reversal_window_deg && past_deg <= reversal_window_deg + servo_lag_deg
                           ? static_cast<int>(((quarter % 4) + 4) % 4)
                           : -1;
  }
  d.candidates.push_back(
      candidate("eccentricity", "angle_deg",
                "the circle's centre is off the bar's pivot (the set-up; on a grinder, the centres' eccentricity): "
                "m and n, the offset along the plane's first and second axis",
                {shape("cos", {"angle_deg"}, 1.0, 0.0, 360.0), shape("sin", {"angle_deg"}, 1.0, 0.0, 360.0)},
                {{"m", "um", 1.0}, {"n", "um", 1.0}}));
  d.candidates.back().of_setup = true;
  // The squareness is the angle between the axes' + directions less 90 deg (docs/conventions.md,
  // as `analyze ballbar` reports it): an x error of a y reads +(a R / 2) sin 2a and makes that
  // angle smaller, so the squareness is -a.
  d.candidates.push_back(
      candidate("squareness", "angle_deg", "the two axes are out of square: the circle is an ellipse at 45 deg",
                {shape("sin", {"angle_deg"}, 1.0, 0.0, 180.0)}, {{"squareness", "urad", -2000.0 / r}}));
  d.candidates.push_back(
      candidate("scale_error", "angle_deg", "the two axes' scales differ: the circle is an ellipse along an axis",
                {shape("cos", {"angle_deg"}, 1.0, 0.0, 180.0)}, {{"scale_mismatch", "ppm", 2000.0 / r}}));
  // Both need both directions: in one, a servo mismatch is a squareness's ellipse and a lost
  // motion a fixed pattern of the angle (analyze ballbar does not estimate them either).
  if (both_directions) {
    // An axis that lags its command by half its lost motion in the direction it moves reads, on
    // the bar, a step of that motion where it reverses: reversal_x and reversal_y are the lost
    // motions of the plane's first and second axis. The step is not read (predicted as 0) where
    // the motor is still crossing the play after a reversal (the table stays until it has), nor
    // where a machine's axis reverses a servo lag after the programmed angle: within the angle in
    // which the axis moves kTakeUpUm, R (1 - cos a) (read there, the step came out 3 % small: 2.915
    // for a lost motion of 3 um taken up as the axis moves; a ramp over the play a first fit reads
    // missed the lag: docs/ballbar.md).
    constexpr double kTakeUpUm = 20.0;
    const double take_up_deg = angleOfTravelAfterReversalDeg(kTakeUpUm, r);
    d.candidates.push_back(candidate("backlash", "angle_deg",
                                     "reversal steps where an axis changes direction (lost motion)",
                                     {shape("sign_sin_cos", {"angle_deg"}, 1.0, take_up_deg),
                                      shape("sign_cos_sin", {"angle_deg"}, 1.0, take_up_deg)},
                                     {{"reversal_x", "um", 2.0}, {"reversal_y", "um", -2.0}}));
    if (!in.plane.empty()) {
      const auto axes = planeAxes(parsePlane(in.plane));
      const char* names = "XYZ";
      auto& reversals = d.candidates.back().parameters;
      reversals[0].quantity = detail::lostMotion(std::string(1, names[axes.first]));
      reversals[1].quantity = detail::lostMotion(std::string(1, names[axes.second]));
    }
    d.candidates.push_back(candidate(
        "servo_mismatch", "angle_deg",
        "the position loops of the two axes lag differently: an ellipse at 45 deg that turns with the direction",
        {shape("sin*direction", {"angle_deg"}, 1.0, 0.0, 180.0)}, {{"lag_difference", "ms", 2.0 / v_mm_s}}));
  } else {
    d.notes.push_back(
        "one direction only: a lost motion (backlash) and a servo mismatch show in the difference between the "
        "directions; with one direction, a servo mismatch reads as a squareness: measure both directions");
  }
  if (varies(d, "time_s")) d.candidates.push_back(linearDrift());
  d.notes.push_back(
      "a circular test reads only the bar's length: it cannot see an error along the path (tangential) nor one "
      "across the plane (both second order), an error the same at every angle other than as the radius (and that "
      "only when the bar was zeroed on its calibrator), nor the machine's position: the same circle elsewhere in "
      "the volume may differ");
  return d;
}

}  // namespace mtcal::processing
