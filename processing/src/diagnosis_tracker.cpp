// The candidate catalogue of gantry tests with a laser tracker: the residuals of the head's
// targets about their rigid motion per hole and of the rotary sweeps about their circles, and
// the causes left in them (SMR centring, axis wobble).
#include <fmt/format.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>
#include <utility>
#include <vector>

#include "diagnosis_internal.h"
#include "mtcal/error.h"
#include "mtcal/processing/diagnosis.h"
#include "mtcal/processing/geometry3d.h"

namespace mtcal::processing {

using detail::candidate;
using detail::shape;
using detail::varies;
using detail::vec;

namespace {

Eigen::Matrix3d skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return m;
}

/// The sweep's axial deviations (um) and angles (deg, from its first point) about its circle.
void sweepAxial(const std::vector<Eigen::Vector3d>& sweep, const char* what, std::vector<double>& axial_um,
                std::vector<double>& angle_deg) {
  const auto circle = fitCircle3d(sweep, what);
  Eigen::Vector3d e1 = sweep.front() - circle.centre;
  e1 -= e1.dot(circle.normal) * circle.normal;
  e1.normalize();
  const Eigen::Vector3d e2 = circle.normal.cross(e1);
  double previous = 0.0, turns = 0.0;
  for (std::size_t k = 0; k < sweep.size(); ++k) {
    const Eigen::Vector3d d = sweep[k] - circle.centre;
    axial_um.push_back(1000.0 * d.dot(circle.normal));
    double a = std::atan2(d.dot(e2), d.dot(e1)) * 180.0 / std::numbers::pi + turns;
    if (k > 0 && a < previous - 180.0) {
      turns += 360.0;
      a += 360.0;
    }
    previous = a;
    angle_deg.push_back(a);
  }
}

}  // namespace

DiagnosisData trackerDiagnosisData(const TrackerRunInput& in) {
  const std::size_t targets = in.initial_targets.size();
  if (targets < 3)
    throw InputError(
        fmt::format("{}: {} targets in the initial state; the rigid fit needs 3 or more", in.source, targets));
  std::vector<double> y, los, hole_of, sweep_c, sweep_a, angle_c, angle_a;
  int absorbed = 0;
  // Targets: the head's target pattern and its rigid motion into every set (the initial state
  // and each hole) by generalised Procrustes (the pattern the mean of all sets brought back,
  // so no one set's noise is taken as the truth); what is left in each set is projected off
  // its motion's (linearised) directions. The line-of-sight change of each target is treated
  // the same way: u_ik - R_k mean_k(R_k^T u_ik).
  std::vector<std::vector<Eigen::Vector3d>> sets{in.initial_targets};
  for (std::size_t j = 0; j < in.hole_targets.size(); ++j) {
    if (in.hole_targets[j].size() != targets) {
      throw InputError(fmt::format("{}: hole {} has {} targets, the initial state {}", in.source, j + 1,
                                   in.hole_targets[j].size(), targets));
    }
    sets.push_back(in.hole_targets[j]);
  }
  std::vector<Eigen::Vector3d> pattern = in.initial_targets;
  std::vector<Eigen::Isometry3d> motion(sets.size());
  for (int iteration = 0; iteration < 10; ++iteration) {
    std::vector<Eigen::Vector3d> mean(targets, Eigen::Vector3d::Zero());
    for (std::size_t k = 0; k < sets.size(); ++k) {
      motion[k] = rigidFit(pattern, sets[k]).transform;
      for (std::size_t i = 0; i < targets; ++i)
        mean[i] += motion[k].inverse() * sets[k][i] / static_cast<double>(sets.size());
    }
    pattern = mean;
  }
  std::vector<Eigen::Vector3d> mean_sight(targets, Eigen::Vector3d::Zero());
  for (std::size_t k = 0; k < sets.size(); ++k) {
    for (std::size_t i = 0; i < targets; ++i)
      mean_sight[i] += motion[k].linear().transpose() * sets[k][i].normalized() / static_cast<double>(sets.size());
  }
  if (!in.hole_targets.empty()) {
    for (std::size_t k = 0; k < sets.size(); ++k) {
      const auto rows = static_cast<Eigen::Index>(3 * targets);
      Eigen::MatrixXd jacobian(rows, 6);
      Eigen::VectorXd residual(rows), sight(rows);
      Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
      for (const auto& p : sets[k]) centroid += p / static_cast<double>(targets);
      for (std::size_t i = 0; i < targets; ++i) {
        const auto row = static_cast<Eigen::Index>(3 * i);
        const Eigen::Vector3d fitted = motion[k] * pattern[i];
        jacobian.block(row, 0, 3, 3) = Eigen::Matrix3d::Identity();
        jacobian.block(row, 3, 3, 3) = -skew(fitted - centroid) * 1000.0;
        residual.segment(row, 3) = 1000.0 * (sets[k][i] - fitted);
        sight.segment(row, 3) = sets[k][i].normalized() - motion[k].linear() * mean_sight[i];
      }
      const Eigen::MatrixXd q = jacobian.householderQr().householderQ() * Eigen::MatrixXd::Identity(rows, 6);
      residual -= q * (q.transpose() * residual);
      sight -= q * (q.transpose() * sight);
      for (Eigen::Index r = 0; r < rows; ++r) {
        y.push_back(residual(r));
        los.push_back(sight(r));
        hole_of.push_back(static_cast<double>(k));
        sweep_c.push_back(0.0);
        sweep_a.push_back(0.0);
        angle_c.push_back(0.0);
        angle_a.push_back(0.0);
      }
    }
    absorbed += static_cast<int>(6 * sets.size() + 3 * targets) - 6;  // motions and the pattern, less the common gauge
  }
  // Sweeps: the axial deviation from each circle's plane (the plane's 3 parameters fitted).
  std::vector<std::string> notes;
  for (const auto* sweep : {&in.c_sweep, &in.a_sweep}) {
    const bool c = sweep == &in.c_sweep;
    if (sweep->size() < 12) {
      if (!sweep->empty())
        notes.push_back(fmt::format("the {} sweep has {} points: a wobble needs 12 or more to be tested", c ? "C" : "A",
                                    sweep->size()));
      continue;
    }
    std::vector<double> axial, angle;
    sweepAxial(*sweep, c ? "C sweep" : "A sweep", axial, angle);
    for (std::size_t k = 0; k < axial.size(); ++k) {
      y.push_back(axial[k]);
      los.push_back(0.0);
      hole_of.push_back(-1.0);
      sweep_c.push_back(c ? 1.0 : 0.0);
      sweep_a.push_back(c ? 0.0 : 1.0);
      angle_c.push_back(c ? angle[k] : 0.0);
      angle_a.push_back(c ? 0.0 : angle[k]);
    }
    absorbed += 3;
  }
  if (y.size() < 8) throw InputError(fmt::format("{}: {} residuals; a diagnosis needs 8 or more", in.source, y.size()));
  DiagnosisData d;
  d.kind = "tracker";
  d.source = in.source;
  d.value_name = "residual";
  d.main_variable = "hole";
  d.measured = vec(y);
  d.simulated = Eigen::VectorXd::Zero(d.measured.size());
  d.model_description = "rigid motion of the head's targets per hole; a circle per rotary sweep";
  d.baseline = Eigen::MatrixXd(d.measured.size(), 0);
  d.baseline_description = fmt::format("nothing more: {} parameters were fitted to make the residuals", absorbed);
  d.absorbed_dof = absorbed;
  d.notes = notes;
  d.variables = {{"hole", "", vec(hole_of)},           {"line_of_sight_change", "", vec(los)},
                 {"c_sweep", "", vec(sweep_c)},        {"a_sweep", "", vec(sweep_a)},
                 {"c_angle_deg", "deg", vec(angle_c)}, {"a_angle_deg", "deg", vec(angle_a)}};
  // Folds: five groups of holes, and five sectors of each sweep.
  d.fold.resize(d.measured.size());
  const double holes = static_cast<double>(std::max<std::size_t>(1, in.hole_targets.size() + 1));
  for (Eigen::Index i = 0; i < d.measured.size(); ++i) {
    if (hole_of[static_cast<std::size_t>(i)] >= 0.0) {
      d.fold(i) = static_cast<int>(5.0 * hole_of[static_cast<std::size_t>(i)] / holes);
    } else {
      const double a = sweep_c[static_cast<std::size_t>(i)] > 0.0 ? angle_c[static_cast<std::size_t>(i)]
                                                                  : angle_a[static_cast<std::size_t>(i)];
      const double span = sweep_c[static_cast<std::size_t>(i)] > 0.0
                              ? std::max(1e-9, *std::max_element(angle_c.begin(), angle_c.end()))
                              : std::max(1e-9, *std::max_element(angle_a.begin(), angle_a.end()));
      d.fold(i) = std::min(4, static_cast<int>(5.0 * a / (span + 1e-9)));
    }
  }
  d.fold_description = "five groups of holes and five sectors of each sweep, each left out in turn";
  if (!in.hole_targets.empty()) {
    d.candidates.push_back(
        candidate("target_offset", "line_of_sight_change",
                  "the reflector's optical centre is off its sphere's centre (SMR centring): every point reads shifted "
                  "along the beam, which the targets' rigid motion cannot follow as the head turns",
                  {shape("linear", {"line_of_sight_change"})}, {{"centring_error", "um", 1.0, 100.0}}));
    d.candidates.back().of_setup = true;
  }
  for (const auto& [axis, name] : {std::pair{"C", "c"}, std::pair{"A", "a"}}) {
    const std::string sweep = std::string(name) + "_sweep", angle = std::string(name) + "_angle_deg";
    if (!varies(d, sweep)) continue;
    d.candidates.push_back(candidate(
        "wobble", angle,
        fmt::format("the {} axis wobbles: its tilt changes twice per turn, moving the target out of the "
                    "circle's plane",
                    axis),
        {shape(std::string("harmonic*") + sweep, {angle}, 1.0, 0.0, 180.0)}, {{"sin", "um", 1.0}, {"cos", "um", 1.0}}));
  }
  d.notes.push_back(
      "the targets after their rigid motion per hole: a motion of the whole head (a translation or rotation, the "
      "positioning and angular errors of the axes) is absorbed and not diagnosed here (docs/gantry.md evaluates "
      "it); a reflector's centring error along the beam shows only as the scale of the pattern's spread");
  return d;
}

}  // namespace mtcal::processing
