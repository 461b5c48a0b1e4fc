#include "mtcal/processing/ballbar_identification.h"

#include <fmt/format.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>

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

// A ball pair's centre distance (mm) at coordinates q with these errors, the tool ball moved
// by `tool_offset_mm`.
double pairLengthMm(const MultibodyModel& model, const Eigen::VectorXd& q, const Eigen::VectorXd& errors,
                    const BallPair& pair, const Eigen::Vector3d& tool_offset_mm = Eigen::Vector3d::Zero()) {
  return (model.actualPoint(q, errors, pair.tool_ball_mm + tool_offset_mm) - pair.work_ball_mm).norm();
}

// The length changes' least-squares solution shared by the identifications: unknowns are
// `per_position` terms at every position after the reference, then `tied` groups of static
// terms (each group one value), then the tool ball's offset (x, y um) when asked; `known`
// gives every other error at a position. Gauss-Newton with central differences.
struct LengthProblem {
  const MultibodyModel* model = nullptr;
  /// Passes of the bar: each its pairs, measured at its positions (the same count in every
  /// pass; position j of every pass shares the per-position unknowns), its first the reference.
  struct Pass {
    std::vector<BallPair> pairs;
    std::vector<Eigen::VectorXd> q;
  };
  std::vector<Pass> passes;
  Eigen::VectorXd measured;            ///< pass by pass, (positions - 1) x pairs, um
  std::vector<int> per_position;       ///< term indexes
  std::vector<std::vector<int>> tied;  ///< term index groups
  bool offset = false;
  std::function<Eigen::VectorXd(const Eigen::VectorXd&)> known;
  Eigen::Index positions() const { return static_cast<Eigen::Index>(passes.front().q.size()) - 1; }
};

struct LengthSolution {
  Eigen::VectorXd u;
  double rms_residual_um = 0.0;
  double condition_number = 0.0;  ///< of the whole system (columns scaled)
};

Eigen::VectorXd lengthChanges(const LengthProblem& p, const Eigen::VectorXd& u) {
  const auto m = static_cast<Eigen::Index>(p.per_position.size());
  const Eigen::Index positions = p.positions();
  const Eigen::Index statics = m * positions;
  const Eigen::Index off_at = statics + static_cast<Eigen::Index>(p.tied.size());
  Eigen::Vector3d off = Eigen::Vector3d::Zero();
  if (p.offset) off = Eigen::Vector3d(u(off_at), u(off_at + 1), 0.0) / 1000.0;
  Eigen::VectorXd r(p.measured.size());
  Eigen::Index row = 0;
  for (const auto& pass : p.passes) {
    const auto k = static_cast<Eigen::Index>(pass.pairs.size());
    auto lengths = [&](Eigen::Index j) {
      const auto& q = pass.q[static_cast<std::size_t>(j)];
      Eigen::VectorXd e =
          p.known ? p.known(q) : Eigen::VectorXd::Zero(static_cast<Eigen::Index>(p.model->terms().size()));
      if (j > 0) {
        for (Eigen::Index i = 0; i < m; ++i) e(p.per_position[static_cast<std::size_t>(i)]) = u((j - 1) * m + i);
      }
      for (std::size_t g = 0; g < p.tied.size(); ++g) {
        for (int t : p.tied[g]) e(t) = u(statics + static_cast<Eigen::Index>(g));
      }
      Eigen::VectorXd l(k);
      for (Eigen::Index b = 0; b < k; ++b) {
        const auto& pair = pass.pairs[static_cast<std::size_t>(b)];
        l(b) = pairLengthMm(*p.model, q, e, pair, off);
      }
      return l;
    };
    const Eigen::VectorXd reference = lengths(0);
    for (Eigen::Index j = 1; j <= positions; ++j) {
      r.segment(row, k) = (lengths(j) - reference) * 1000.0;
      row += k;
    }
  }
  return r;
}

LengthSolution solveLengths(const LengthProblem& p, double max_condition, const std::string& offset_refusal) {
  const Eigen::Index positions = p.positions();
  const Eigen::Index unknowns = static_cast<Eigen::Index>(p.per_position.size()) * positions +
                                static_cast<Eigen::Index>(p.tied.size()) + (p.offset ? 2 : 0);
  if (p.measured.size() < unknowns) {
    throw InputError(
        fmt::format("ballbar identification: {} length changes cannot give {} unknowns", p.measured.size(), unknowns));
  }
  LengthSolution s;
  s.u = Eigen::VectorXd::Zero(unknowns);
  for (int iteration = 0; iteration < 6; ++iteration) {
    const Eigen::VectorXd f = lengthChanges(p, s.u) - p.measured;
    Eigen::MatrixXd jac(f.size(), s.u.size());
    for (Eigen::Index c = 0; c < s.u.size(); ++c) {
      Eigen::VectorXd hi = s.u, lo = s.u;
      hi(c) += 0.5;
      lo(c) -= 0.5;
      jac.col(c) = lengthChanges(p, hi) - lengthChanges(p, lo);
    }
    if (iteration == 0) {
      s.condition_number = conditionOf(jac);
      if (s.condition_number > max_condition)
        throw InputError(fmt::format("{} (condition number {:.3g})", offset_refusal, s.condition_number));
    }
    const Eigen::VectorXd step = jac.colPivHouseholderQr().solve(-f);
    s.u += step;
    if (step.norm() < 1e-9) break;
  }
  const Eigen::VectorXd residual = lengthChanges(p, s.u) - p.measured;
  s.rms_residual_um = std::sqrt(residual.squaredNorm() / static_cast<double>(residual.size()));
  return s;
}

}  // namespace

std::vector<double> ballbarLengthsMm(const MultibodyModel& model, const BallbarSetup& setup, double value,
                                     const Eigen::VectorXd& errors, const Eigen::Vector2d& tool_ball_offset_um) {
  Eigen::VectorXd q = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(model.coordinates().size()));
  q(coordinateIndex(model, setup.coordinate)) = value;
  std::vector<double> out;
  const Eigen::Vector3d offset_mm = Eigen::Vector3d(tool_ball_offset_um.x(), tool_ball_offset_um.y(), 0.0) / 1000.0;
  for (const auto& p : setup.pairs) out.push_back(pairLengthMm(model, q, errors, p, offset_mm));
  return out;
}

BallbarIdentification identifyFromBallbar(const MultibodyModel& model, const BallbarSetup& setup,
                                          const std::vector<BallbarReadings>& readings) {
  const int axis = coordinateIndex(model, setup.coordinate);
  if (readings.size() < 2)
    throw InputError("ballbar identification: at least two axis positions (the first is the reference)");
  const auto k = static_cast<Eigen::Index>(setup.pairs.size());
  for (std::size_t j = 0; j < readings.size(); ++j) {
    if (static_cast<Eigen::Index>(readings[j].delta_length_um.size()) != k) {
      throw InputError(fmt::format("ballbar identification: position {} has {} length(s) for {} ball placements", j + 1,
                                   readings[j].delta_length_um.size(), k));
    }
  }
  // The axis' motion errors in the order of their components: the translations dx, dy, dz,
  // then the rotations rx, ry, rz (EXC, EYC, EZC, EAC, EBC, ECC), whatever order the machine
  // file names them in. A layout that sees fewer keeps the translations first.
  std::vector<int> axis_terms;
  for (std::size_t t = 0; t < model.terms().size(); ++t) {
    const auto& term = model.terms()[t];
    if (term.motion && model.coordinateOfJoint(term.joint) == axis) axis_terms.push_back(static_cast<int>(t));
  }
  std::stable_sort(axis_terms.begin(), axis_terms.end(), [&](int a, int b) {
    return static_cast<int>(model.terms()[static_cast<std::size_t>(a)].component) <
           static_cast<int>(model.terms()[static_cast<std::size_t>(b)].component);
  });
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
  // The readings are the bar's total length changes from the reference: the nominal change
  // the axis' move makes (the X test's slide moves the balls apart; the C test's turns keep
  // them) and the errors'. Readings of the errors alone would be read as errors the size of
  // the nominal change.
  double nominal_um = 0.0, read_um = 0.0;
  const Eigen::VectorXd reference = lengths(readings.front().coordinate, Eigen::VectorXd::Zero(n_terms), no_offset);
  for (std::size_t j = 1; j < readings.size(); ++j) {
    const Eigen::VectorXd nominal =
        (lengths(readings[j].coordinate, Eigen::VectorXd::Zero(n_terms), no_offset) - reference) * 1000.0;
    nominal_um = std::max(nominal_um, nominal.cwiseAbs().maxCoeff());
    for (const double v : readings[j].delta_length_um) read_um = std::max(read_um, std::abs(v));
  }
  if (nominal_um > 100.0 && read_um < 0.1 * nominal_um) {
    throw InputError(fmt::format(
        "ballbar identification: the readings change the bar's length by {:.1f} um at most, where the {} axis' "
        "moves change it by {:.1f} um nominally: give each reading as the bar reads it, the total change of its "
        "length from the reference (the nominal change included), not the errors alone",
        read_um, setup.coordinate, nominal_um));
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
    throw InputError(fmt::format("ballbar identification: {} ball placements cannot give {} errors per position{}", k,
                                 m, extra ? " and the tool ball's offset" : ""));
  }
  LengthProblem problem;
  problem.model = &model;
  LengthProblem::Pass pass;
  pass.pairs = setup.pairs;
  for (const auto& r : readings) {
    Eigen::VectorXd q = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(model.coordinates().size()));
    q(axis) = r.coordinate;
    pass.q.push_back(q);
  }
  problem.passes.push_back(pass);
  problem.measured.resize(k * positions);
  for (Eigen::Index j = 0; j < positions; ++j) {
    for (Eigen::Index p = 0; p < k; ++p)
      problem.measured(j * k + p) =
          readings[static_cast<std::size_t>(j + 1)].delta_length_um[static_cast<std::size_t>(p)];
  }
  for (int i : used) problem.per_position.push_back(axis_terms[static_cast<std::size_t>(i)]);
  problem.offset = setup.unknown_tool_ball_offset;
  // A fixed offset of the tool-side ball reads, position by position, as the axis'
  // translations (for C, EXC and EYC turning with the head), which are free at every position
  // but the reference: nothing in the lengths tells them apart.
  const auto solution = solveLengths(
      problem, extra > 0 ? setup.max_condition_number : std::numeric_limits<double>::infinity(),
      fmt::format(
          "ballbar identification: the tool-side ball's offset (the tailstock eccentricity m, n) cannot be "
          "separated from the {} axis' translation errors: at every position a fixed offset reads as those errors. "
          "Measure m, n by other means (e.g. an indicator on the tailstock centre) or identify without them: the "
          "translations then carry the eccentricity",
          setup.coordinate));
  const Eigen::VectorXd& u = solution.u;
  out.rms_residual_um = solution.rms_residual_um;
  out.coordinate.push_back(readings.front().coordinate);
  out.values = Eigen::MatrixXd::Zero(positions + 1, m);
  for (Eigen::Index j = 0; j < positions; ++j) {
    out.coordinate.push_back(readings[static_cast<std::size_t>(j + 1)].coordinate);
    out.values.row(j + 1) = u.segment(j * m, m).transpose();
  }
  if (extra) out.tool_ball_offset_um = Eigen::Vector2d(u(m * positions), u(m * positions + 1));
  return out;
}

double linkedPositionMm(const MultibodyModel& model, const LinkageSetup& setup, const BallPair& pair, double angle_deg,
                        double length_mm, double start_mm) {
  Eigen::VectorXd q = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(model.coordinates().size()));
  q(coordinateIndex(model, setup.rotary)) = angle_deg;
  const int linear = coordinateIndex(model, setup.linear);
  const Eigen::VectorXd zero = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(model.terms().size()));
  auto length = [&](double x) {
    q(linear) = x;
    return pairLengthMm(model, q, zero, pair);
  };
  double x = start_mm;
  for (int it = 0; it < 50; ++it) {
    const double f = length(x) - length_mm;
    if (std::abs(f) < 1e-12) return x;
    const double d = (length(x + 1e-4) - length(x - 1e-4)) / 2e-4;
    if (std::abs(d) < 1e-9) break;
    x -= f / d;
  }
  throw InputError(fmt::format("C-X linkage: no slide position keeps the bar at {} mm with the head at {} deg",
                               length_mm, angle_deg));
}

std::vector<std::vector<Eigen::VectorXd>> linkagePath(const MultibodyModel& model, const LinkageSetup& setup,
                                                      const std::vector<BallPair>& pairs, double start_mm) {
  if (setup.angles_deg.size() < 2) throw InputError("C-X linkage: at least two angles (the first is the reference)");
  const int rotary = coordinateIndex(model, setup.rotary), linear = coordinateIndex(model, setup.linear);
  const Eigen::VectorXd zero = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(model.terms().size()));
  std::vector<std::vector<Eigen::VectorXd>> out;
  for (const auto& pair : pairs) {
    Eigen::VectorXd q = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(model.coordinates().size()));
    q(rotary) = setup.angles_deg.front();
    q(linear) = start_mm;
    const double length = pairLengthMm(model, q, zero, pair);
    std::vector<Eigen::VectorXd> path;
    double x = start_mm;
    for (double a : setup.angles_deg) {
      x = linkedPositionMm(model, setup, pair, a, length, x);
      q(rotary) = a;
      q(linear) = x;
      path.push_back(q);
    }
    out.push_back(path);
  }
  return out;
}

LinkageIdentification identifyLinkage(const MultibodyModel& model, const LinkageSetup& setup,
                                      const std::vector<LinkagePass>& passes, double start_mm,
                                      const std::function<Eigen::VectorXd(const Eigen::VectorXd&)>& known_errors) {
  std::vector<BallPair> pairs;
  for (const auto& p : passes) {
    if (p.delta_length_um.size() != setup.angles_deg.size()) {
      throw InputError(fmt::format("C-X linkage: a pass has {} length change(s) for {} angles",
                                   p.delta_length_um.size(), setup.angles_deg.size()));
    }
    pairs.push_back(p.pair);
  }
  const auto path = linkagePath(model, setup, pairs, start_mm);
  LengthProblem problem;
  problem.model = &model;
  problem.known = known_errors;
  for (const auto& name : setup.per_angle) problem.per_position.push_back(model.termIndex(name));
  for (const auto& group : setup.tied) {
    std::vector<int> g;
    for (const auto& name : group) g.push_back(model.termIndex(name));
    problem.tied.push_back(g);
  }
  std::vector<double> measured;
  for (std::size_t i = 0; i < passes.size(); ++i) {
    problem.passes.push_back({{passes[i].pair}, path[i]});
    measured.insert(measured.end(), passes[i].delta_length_um.begin() + 1, passes[i].delta_length_um.end());
  }
  problem.measured = Eigen::Map<const Eigen::VectorXd>(measured.data(), static_cast<Eigen::Index>(measured.size()));
  const auto solution = solveLengths(problem, setup.max_condition_number,
                                     "C-X linkage: these ball placements cannot separate the unknowns; add placements "
                                     "at other heights or radii");
  LinkageIdentification out;
  const auto m = static_cast<Eigen::Index>(problem.per_position.size());
  const Eigen::Index positions = problem.positions();
  out.per_angle = Eigen::MatrixXd::Zero(positions + 1, m);
  for (Eigen::Index j = 0; j < positions; ++j) out.per_angle.row(j + 1) = solution.u.segment(j * m, m).transpose();
  for (std::size_t g = 0; g < problem.tied.size(); ++g)
    out.tied_values.push_back(solution.u(m * positions + static_cast<Eigen::Index>(g)));
  out.rms_residual_um = solution.rms_residual_um;
  out.condition_number = solution.condition_number;
  return out;
}

}  // namespace mtcal::processing
