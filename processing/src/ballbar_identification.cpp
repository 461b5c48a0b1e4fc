#include "mtcal/processing/ballbar_identification.h"

#include <fmt/format.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>

#include "mtcal/error.h"

namespace mtcal::processing {
namespace {

int coordinateIndex(const MultibodyModel& model, const std::string& name) {
  const auto& c = model.coordinates();
  const auto it = std::find(c.begin(), c.end(), name);
  if (it == c.end()) throw InputError("machine '" + model.name() + "' has no coordinate '" + name + "'");
  return static_cast<int>(it - c.begin());
}

double conditionOf(const Eigen::MatrixXd& a) {
  if (a.cols() == 0) return 1.0;
  Eigen::MatrixXd scaled = a;
  for (Eigen::Index c = 0; c < a.cols(); ++c) {
    const double n = a.col(c).norm();
    if (n > 0.0) scaled.col(c) /= n;
  }
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(scaled);
  const auto s = svd.singularValues();
  return s(s.size() - 1) > 0.0 ? s(0) / s(s.size() - 1) : std::numeric_limits<double>::infinity();
}

}  // namespace

std::vector<double> ballbarLengthsMm(const MultibodyModel& model, const BallbarSetup& setup, double value,
                                     const Eigen::VectorXd& errors, const Eigen::Vector2d& tool_ball_offset_um) {
  Eigen::VectorXd q = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(model.coordinates().size()));
  q(coordinateIndex(model, setup.coordinate)) = value;
  std::vector<double> out;
  for (const auto& p : setup.pairs) {
    const Eigen::Vector3d tool = p.tool_ball_mm + Eigen::Vector3d(tool_ball_offset_um.x(), tool_ball_offset_um.y(), 0.0) / 1000.0;
    out.push_back((model.actualPoint(q, errors, tool) - p.work_ball_mm).norm());
  }
  return out;
}

BallbarIdentification identifyFromBallbar(const MultibodyModel& model, const BallbarSetup& setup,
                                          const std::vector<BallbarReadings>& readings) {
  const int axis = coordinateIndex(model, setup.coordinate);
  if (readings.size() < 2) throw InputError("ballbar identification: at least two axis positions (the first is the reference)");
  const auto k = static_cast<Eigen::Index>(setup.pairs.size());
  for (std::size_t j = 0; j < readings.size(); ++j) {
    if (static_cast<Eigen::Index>(readings[j].delta_length_um.size()) != k) {
      throw InputError(fmt::format("ballbar identification: position {} has {} length(s) for {} ball placements", j + 1,
                                   readings[j].delta_length_um.size(), k));
    }
  }
  // The axis' motion errors, in the model's order.
  std::vector<int> axis_terms;
  for (std::size_t t = 0; t < model.terms().size(); ++t) {
    const auto& term = model.terms()[t];
    if (term.motion && model.coordinateOfJoint(term.joint) == axis) axis_terms.push_back(static_cast<int>(t));
  }
  const auto n_terms = static_cast<Eigen::Index>(model.terms().size());
  const Eigen::Vector2d no_offset = Eigen::Vector2d::Zero();
  auto lengths = [&](double value, const Eigen::VectorXd& e, const Eigen::Vector2d& off) {
    return Eigen::Map<const Eigen::VectorXd>(ballbarLengthsMm(model, setup, value, e, off).data(), k).eval();
  };
  // Which errors this layout sees: a position's block of length sensitivities (um per um or
  // urad), terms taken in order while the block stays well conditioned.
  const double probe_at = readings[readings.size() / 2].coordinate;
  Eigen::MatrixXd block(k, static_cast<Eigen::Index>(axis_terms.size()));
  const Eigen::VectorXd base = lengths(probe_at, Eigen::VectorXd::Zero(n_terms), no_offset);
  for (std::size_t i = 0; i < axis_terms.size(); ++i) {
    Eigen::VectorXd e = Eigen::VectorXd::Zero(n_terms);
    e(axis_terms[i]) = 1.0;
    block.col(static_cast<Eigen::Index>(i)) = (lengths(probe_at, e, no_offset) - base) * 1000.0;
  }
  BallbarIdentification out;
  std::vector<int> used;  // indexes into axis_terms
  Eigen::MatrixXd chosen(k, 0);
  for (std::size_t i = 0; i < axis_terms.size(); ++i) {
    Eigen::MatrixXd trial(k, chosen.cols() + 1);
    trial << chosen, block.col(static_cast<Eigen::Index>(i));
    if (block.col(static_cast<Eigen::Index>(i)).norm() > 1e-6 && conditionOf(trial) < setup.max_condition_number) {
      chosen = trial;
      used.push_back(static_cast<int>(i));
      out.terms.push_back(model.terms()[static_cast<std::size_t>(axis_terms[i])].name);
    } else {
      out.not_determined.push_back(model.terms()[static_cast<std::size_t>(axis_terms[i])].name);
    }
  }
  out.condition_number = conditionOf(chosen);
  const auto m = static_cast<Eigen::Index>(used.size());
  const Eigen::Index extra = setup.unknown_tool_ball_offset ? 2 : 0;
  const auto positions = static_cast<Eigen::Index>(readings.size()) - 1;
  if (k * positions < m * positions + extra || k < m) {
    throw InputError(fmt::format("ballbar identification: {} ball placements cannot give {} errors per position{}", k, m,
                                 extra ? " and the tool ball's offset" : ""));
  }
  // Unknowns: the used errors at every position after the reference, then the offset (um).
  Eigen::VectorXd u = Eigen::VectorXd::Zero(m * positions + extra);
  Eigen::VectorXd measured(k * positions);
  for (Eigen::Index j = 0; j < positions; ++j) {
    for (Eigen::Index p = 0; p < k; ++p) measured(j * k + p) = readings[static_cast<std::size_t>(j + 1)].delta_length_um[static_cast<std::size_t>(p)];
  }
  auto model_changes = [&](const Eigen::VectorXd& x) {
    const Eigen::Vector2d off = extra ? Eigen::Vector2d(x(m * positions), x(m * positions + 1)) : no_offset;
    const Eigen::VectorXd reference = lengths(readings.front().coordinate, Eigen::VectorXd::Zero(n_terms), off);
    Eigen::VectorXd r(k * positions);
    for (Eigen::Index j = 0; j < positions; ++j) {
      Eigen::VectorXd e = Eigen::VectorXd::Zero(n_terms);
      for (Eigen::Index i = 0; i < m; ++i) e(axis_terms[static_cast<std::size_t>(used[static_cast<std::size_t>(i)])]) = x(j * m + i);
      r.segment(j * k, k) = (lengths(readings[static_cast<std::size_t>(j + 1)].coordinate, e, off) - reference) * 1000.0;
    }
    return r;
  };
  for (int iteration = 0; iteration < 6; ++iteration) {
    const Eigen::VectorXd f = model_changes(u) - measured;
    Eigen::MatrixXd jac(f.size(), u.size());
    for (Eigen::Index c = 0; c < u.size(); ++c) {
      Eigen::VectorXd hi = u, lo = u;
      hi(c) += 0.5;
      lo(c) -= 0.5;
      jac.col(c) = model_changes(hi) - model_changes(lo);
    }
    if (iteration == 0 && extra > 0 && conditionOf(jac) > setup.max_condition_number) {
      // A fixed offset of the tool-side ball reads, position by position, as the axis'
      // translations (for C, EXC and EYC turning with the head), which are free at every
      // position but the reference: nothing in the lengths tells them apart.
      throw InputError(fmt::format(
          "ballbar identification: the tool-side ball's offset (the tailstock eccentricity m, n) cannot be separated from "
          "the {} axis' translation errors (condition number {:.3g}): at every position a fixed offset reads as those "
          "errors. Measure m, n by other means (e.g. an indicator on the tailstock centre) or identify without them: "
          "the translations then carry the eccentricity",
          setup.coordinate, conditionOf(jac)));
    }
    const Eigen::VectorXd step = jac.colPivHouseholderQr().solve(-f);
    u += step;
    if (step.norm() < 1e-9) break;
  }
  const Eigen::VectorXd residual = model_changes(u) - measured;
  out.rms_residual_um = std::sqrt(residual.squaredNorm() / static_cast<double>(residual.size()));
  out.coordinate.push_back(readings.front().coordinate);
  out.values = Eigen::MatrixXd::Zero(positions + 1, m);
  for (Eigen::Index j = 0; j < positions; ++j) {
    out.coordinate.push_back(readings[static_cast<std::size_t>(j + 1)].coordinate);
    out.values.row(j + 1) = u.segment(j * m, m).transpose();
  }
  if (extra) out.tool_ball_offset_um = Eigen::Vector2d(u(m * positions), u(m * positions + 1));
  return out;
}

}  // namespace mtcal::processing
