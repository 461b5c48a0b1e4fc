#include "mtcal/processing/line_identification.h"

#include <fmt/format.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <map>
#include <set>

#include "mtcal/error.h"

namespace mtcal::processing {
namespace {

constexpr double kUmPerMmPerUrad = 1e-3;  // a rotation of 1 urad moves a point 1 mm away by 1e-3 um
constexpr double kRankTolerance = 1e-9;   // relative singular value below which a column adds nothing

bool isRotation(ErrorComponent c) { return static_cast<int>(c) >= 3; }

double conditionNumber(const Eigen::MatrixXd& a) {
  if (a.cols() == 0) return 1.0;
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(a);
  const auto& sv = svd.singularValues();
  if (a.rows() < a.cols() || sv(sv.size() - 1) <= kRankTolerance * sv(0))
    return std::numeric_limits<double>::infinity();
  return sv(0) / sv(sv.size() - 1);
}

/// Least-squares slope of y over x.
double slope(const std::vector<double>& x, const Eigen::VectorXd& y) {
  const double n = static_cast<double>(x.size());
  double sx = 0, sy = 0, sxx = 0, sxy = 0;
  for (std::size_t i = 0; i < x.size(); ++i) {
    sx += x[i];
    sy += y(static_cast<Eigen::Index>(i));
    sxx += x[i] * x[i];
    sxy += x[i] * y(static_cast<Eigen::Index>(i));
  }
  return (n * sxy - sx * sy) / (n * sxx - sx * sx);
}

/// The term's values on its node grid, linearly interpolated (clamped at the ends).
double interpolate(const ErrorCurveData& c, double x) {
  if (c.position_mm.empty()) return c.mean.front();
  if (x <= c.position_mm.front()) return c.mean.front();
  if (x >= c.position_mm.back()) return c.mean.back();
  const auto it = std::upper_bound(c.position_mm.begin(), c.position_mm.end(), x);
  const auto i = static_cast<std::size_t>(it - c.position_mm.begin());
  const double f = (x - c.position_mm[i - 1]) / (c.position_mm[i] - c.position_mm[i - 1]);
  return c.mean[i - 1] + f * (c.mean[i] - c.mean[i - 1]);
}

struct Context {
  const MultibodyModel& model;
  const std::vector<MeasuredLine>& lines;
  const LineIdentificationOptions& options;
  LineIdentification out;
  std::map<std::string, ErrorCurveData> curves;  ///< identified motion errors by name
};

Eigen::VectorXd atNode(const MeasuredLine& line, double position_mm) {
  Eigen::VectorXd q = line.q;
  q(line.coordinate) = position_mm;
  return q;
}

/// The translation component a term moves along (0..2) when it is a straightness or
/// positioning error, -1 for a rotation.
int translationComponent(const ErrorTerm& term) {
  return isRotation(term.component) ? -1 : static_cast<int>(term.component);
}

bool isPositioning(const MultibodyModel& model, const ErrorTerm& term) {
  const Joint& joint = model.joints()[static_cast<std::size_t>(term.joint)];
  if (!term.motion || joint.type != JointType::kPrismatic || isRotation(term.component)) return false;
  Eigen::Index along = 0;
  joint.axis.cwiseAbs().maxCoeff(&along);
  return static_cast<int>(term.component) == along;
}

bool isStraightness(const MultibodyModel& model, const ErrorTerm& term) {
  const Joint& joint = model.joints()[static_cast<std::size_t>(term.joint)];
  return term.motion && joint.type == JointType::kPrismatic && !isRotation(term.component) &&
         !isPositioning(model, term);
}

void checkLine(const MultibodyModel& model, const MeasuredLine& line) {
  const auto n = line.position_mm.size();
  if (n < 2 || line.mean.size() != n || line.s.size() != n || line.repeats.size() != n) {
    throw InputError(line.id + ": needs at least 2 nodes with a mean, s and repeats each");
  }
  for (std::size_t i = 1; i < n; ++i) {
    if (!(line.position_mm[i] > line.position_mm[i - 1])) throw InputError(line.id + ": nodes must ascend");
  }
  if (line.q.size() != static_cast<Eigen::Index>(model.coordinates().size()) || line.coordinate < 0 ||
      line.coordinate >= line.q.size()) {
    throw InputError(line.id + ": the machine position does not match the machine's coordinates");
  }
  if (line.component < 0 || line.component > 5) throw InputError(line.id + ": component must be 0..5");
  const auto& term = model.terms()[static_cast<std::size_t>(model.termIndex(line.measures))];
  if (!term.motion || model.coordinateOfJoint(term.joint) != line.coordinate) {
    throw InputError(fmt::format("{}: {} is not a motion error of the axis it moves ({})", line.id, line.measures,
                                 model.coordinates()[static_cast<std::size_t>(line.coordinate)]));
  }
  const auto row = readingRow(model, atNode(line, line.position_mm.front()), line.point_mm, line.component);
  if (std::abs(row(model.termIndex(line.measures))) < 0.5) {
    throw InputError(
        fmt::format("{}: its optics (component {}) do not see {}", line.id, line.component, line.measures));
  }
}

/// Solves the lines of one axis node by node; fills ctx.curves and an AxisSolution.
void solveAxis(Context& ctx, int coordinate, const std::vector<std::size_t>& members) {
  const MultibodyModel& model = ctx.model;
  const auto& first = ctx.lines[members.front()];
  AxisSolution solution;
  solution.coordinate = model.coordinates()[static_cast<std::size_t>(coordinate)];
  for (std::size_t m : members) {
    const auto& line = ctx.lines[m];
    solution.lines.push_back(line.id);
    bool same = line.position_mm.size() == first.position_mm.size();
    for (std::size_t i = 0; same && i < line.position_mm.size(); ++i) {
      same = std::abs(line.position_mm[i] - first.position_mm[i]) < 1e-6;
    }
    if (!same) {
      throw InputError(
          fmt::format("{} and {} measure axis {} on different node grids: give the lines of one axis "
                      "the same targets",
                      first.id, line.id, solution.coordinate));
    }
  }
  // The axis' own motion errors, and each line's row over them at the first node.
  std::vector<int> own;
  for (std::size_t t = 0; t < model.terms().size(); ++t) {
    const auto& term = model.terms()[t];
    if (term.motion && model.coordinateOfJoint(term.joint) == coordinate) own.push_back(static_cast<int>(t));
  }
  auto rowsAt = [&](double position_mm, const std::vector<int>& columns) {
    Eigen::MatrixXd a(static_cast<Eigen::Index>(members.size()), static_cast<Eigen::Index>(columns.size()));
    for (std::size_t r = 0; r < members.size(); ++r) {
      const auto& line = ctx.lines[members[r]];
      const auto row = readingRow(model, atNode(line, position_mm), line.point_mm, line.component);
      for (std::size_t c = 0; c < columns.size(); ++c)
        a(static_cast<Eigen::Index>(r), static_cast<Eigen::Index>(c)) = row(columns[c]);
    }
    return a;
  };
  // Unknowns: the terms the lines name, then any other term of the axis the layout
  // separates (rotations first: lever arms), within the condition limit.
  std::vector<int> unknowns;
  for (std::size_t m : members) {
    const int t = model.termIndex(ctx.lines[m].measures);
    if (std::find(unknowns.begin(), unknowns.end(), t) == unknowns.end()) unknowns.push_back(t);
  }
  const double x0 = first.position_mm.front();
  const double named_condition = conditionNumber(rowsAt(x0, unknowns));
  if (!(named_condition <= ctx.options.max_condition_number)) {
    throw InputError(fmt::format(
        "the lines of axis {} ({}) cannot separate the errors they name (condition number "
        "{:.3g} > {:.3g})",
        solution.coordinate, fmt::join(solution.lines, ", "), named_condition, ctx.options.max_condition_number));
  }
  std::vector<int> candidates;
  for (bool rotations : {true, false}) {
    for (int t : own) {
      if (isRotation(model.terms()[static_cast<std::size_t>(t)].component) == rotations &&
          std::find(unknowns.begin(), unknowns.end(), t) == unknowns.end()) {
        candidates.push_back(t);
      }
    }
  }
  for (int t : candidates) {
    const Eigen::MatrixXd a = rowsAt(x0, unknowns);
    Eigen::MatrixXd with(a.rows(), a.cols() + 1);
    with << a, rowsAt(x0, {t});
    if (with.col(with.cols() - 1).norm() < 1e-12) continue;  // the lines do not see it
    if (conditionNumber(with) <= ctx.options.max_condition_number) unknowns.push_back(t);
  }
  if (ctx.options.method == IdentificationMethod::kNineLine) {
    // Three displacement lines: the positioning error and every rotation with a lever arm
    // along the measuring direction must come out.
    std::vector<int> expected;
    for (int t : own) {
      const auto& term = model.terms()[static_cast<std::size_t>(t)];
      if (isPositioning(model, term) || (isRotation(term.component) && rowsAt(x0, {t}).norm() > 1e-12)) {
        expected.push_back(t);
      }
    }
    const double condition = conditionNumber(rowsAt(x0, expected));
    std::vector<std::string> missing;
    for (int t : expected) {
      if (std::find(unknowns.begin(), unknowns.end(), t) == unknowns.end()) {
        missing.push_back(model.terms()[static_cast<std::size_t>(t)].name);
      }
    }
    if (!missing.empty()) {
      // Where each line stands: the other axes' positions and the measured point in the tool's frame.
      std::vector<std::string> offsets;
      for (std::size_t m : members) {
        const auto& line = ctx.lines[m];
        std::string at;
        for (std::size_t c = 0; c < model.coordinates().size(); ++c)
          if (static_cast<int>(c) != line.coordinate)
            at += fmt::format("{} {:g}, ", model.coordinates()[c], line.q(static_cast<Eigen::Index>(c)));
        offsets.push_back(fmt::format("{} at {}optics at ({:.1f}, {:.1f}, {:.1f}) mm of the tool", line.id, at,
                                      line.point_mm.x(), line.point_mm.y(), line.point_mm.z()));
      }
      throw InputError(fmt::format(
          "9-line method: the displacement lines of axis {} leave {} undetermined (condition number {:.3g}, limit "
          "{:.3g}); the lines ({}) need three lever arms that are not collinear, set by line_position_mm or "
          "reflector_offset_mm",
          solution.coordinate, fmt::join(missing, ", "), condition, ctx.options.max_condition_number,
          fmt::join(offsets, "; ")));
    }
  }
  // Per node: weighted least squares of the readings relative to the first node.
  const auto nodes = first.position_mm.size();
  std::vector<ErrorCurveData> solved(unknowns.size());
  for (std::size_t k = 0; k < unknowns.size(); ++k) {
    solved[k].name = model.terms()[static_cast<std::size_t>(unknowns[k])].name;
    solved[k].position_mm = first.position_mm;
  }
  const auto rows = static_cast<Eigen::Index>(members.size());
  for (std::size_t n = 0; n < nodes; ++n) {
    const Eigen::MatrixXd a = rowsAt(first.position_mm[n], unknowns);
    Eigen::VectorXd y(rows), w(rows);
    bool all_s = true;
    int repeats = std::numeric_limits<int>::max();
    for (Eigen::Index r = 0; r < rows; ++r) {
      const auto& line = ctx.lines[members[static_cast<std::size_t>(r)]];
      y(r) = line.mean[n];
      const auto& s = line.s[n];
      all_s = all_s && s.has_value() && *s > 0.0;
      w(r) = s && *s > 0.0 ? 1.0 / (*s * *s) : 1.0;
      repeats = std::min(repeats, line.repeats[n]);
    }
    // The first node is the zero: reading(x) - reading(x0) = A(x) e(x) - A(x0) e(x0), e(x0) = 0.
    const Eigen::MatrixXd normal = a.transpose() * w.asDiagonal() * a;
    const Eigen::MatrixXd cov = normal.inverse();
    Eigen::VectorXd relative(rows);
    for (Eigen::Index r = 0; r < rows; ++r)
      relative(r) = y(r) - ctx.lines[members[static_cast<std::size_t>(r)]].mean.front();
    const Eigen::VectorXd e = cov * a.transpose() * w.asDiagonal() * relative;
    for (std::size_t k = 0; k < unknowns.size(); ++k) {
      const auto kk = static_cast<Eigen::Index>(k);
      solved[k].mean.push_back(e(kk));
      solved[k].s.push_back(all_s ? std::optional<double>(std::sqrt(cov(kk, kk))) : std::nullopt);
      solved[k].repeats.push_back(repeats);
    }
  }
  const Eigen::MatrixXd a = rowsAt(x0, unknowns);
  solution.condition_number = conditionNumber(a);
  const Eigen::MatrixXd gain = (a.transpose() * a).inverse();
  for (std::size_t k = 0; k < unknowns.size(); ++k) {
    solution.terms.push_back(solved[k].name);
    solution.noise_gain.push_back(std::sqrt(gain(static_cast<Eigen::Index>(k), static_cast<Eigen::Index>(k))));
    ctx.curves[solved[k].name] = std::move(solved[k]);
  }
  ctx.out.axes.push_back(std::move(solution));
}

/// 9-line method: straightness of each axis from its rotations, dT/dx = eps x u (the carriage
/// follows the tangent of its guideway: the rigid-body assumption).
void integrateStraightness(Context& ctx) {
  const MultibodyModel& model = ctx.model;
  for (const auto& term : model.terms()) {
    if (!isStraightness(model, term) || ctx.curves.count(term.name)) continue;
    const Joint& joint = model.joints()[static_cast<std::size_t>(term.joint)];
    const int d = translationComponent(term);
    // d(straightness)/dx in um per mm, per urad of each rotation of the same joint.
    std::vector<std::pair<const ErrorCurveData*, double>> sources;
    bool complete = true;
    for (const auto& r : model.terms()) {
      if (r.joint != term.joint || !r.motion || !isRotation(r.component)) continue;
      Eigen::Vector3d eps = Eigen::Vector3d::Zero();
      eps(static_cast<int>(r.component) - 3) = 1.0;
      const double coefficient = eps.cross(joint.axis)(d) * kUmPerMmPerUrad;
      if (std::abs(coefficient) < 1e-15) continue;
      const auto it = ctx.curves.find(r.name);
      if (it == ctx.curves.end()) {
        complete = false;
        break;
      }
      sources.emplace_back(&it->second, coefficient);
    }
    if (!complete || sources.empty()) continue;
    ErrorCurveData c;
    c.name = term.name;
    c.position_mm = sources.front().first->position_mm;
    double value = 0.0, variance = 0.0;
    bool have_s = true;
    for (std::size_t n = 0; n < c.position_mm.size(); ++n) {
      if (n > 0) {
        const double dx = c.position_mm[n] - c.position_mm[n - 1];
        for (const auto& [src, coefficient] : sources) {
          value += coefficient * 0.5 * (src->mean[n] + src->mean[n - 1]) * dx;
          const auto& s0 = src->s[n - 1];
          const auto& s1 = src->s[n];
          have_s = have_s && s0 && s1;
          if (s0 && s1) variance += std::pow(coefficient * 0.5 * dx, 2) * (*s0 * *s0 + *s1 * *s1);
        }
      }
      c.mean.push_back(value);
      c.s.push_back(have_s ? std::optional<double>(std::sqrt(variance)) : std::nullopt);
      c.repeats.push_back(sources.front().first->repeats[n]);
    }
    ctx.out.notes.push_back(
        fmt::format("{} integrated from the rotations of its axis (rigid-body assumption)", term.name));
    ctx.curves[term.name] = std::move(c);
  }
}

/// Squareness from the slopes of the straightness lines, with the orientation of the
/// workpiece frame (three small rotations) as a gauge; then every straightness error loses
/// its least-squares line.
void squarenessAndReferenceLines(Context& ctx) {
  const MultibodyModel& model = ctx.model;
  std::vector<std::size_t> straightness_lines;
  for (std::size_t i = 0; i < ctx.lines.size(); ++i) {
    const auto& term = model.terms()[static_cast<std::size_t>(model.termIndex(ctx.lines[i].measures))];
    if (isStraightness(model, term) && ctx.lines[i].component < 3) straightness_lines.push_back(i);
  }
  std::vector<int> statics;
  for (std::size_t t = 0; t < model.terms().size(); ++t) {
    if (!model.terms()[t].motion) statics.push_back(static_cast<int>(t));
  }
  if (straightness_lines.empty()) {
    for (int t : statics) {
      ctx.out.notes.push_back(fmt::format(
          "{} not identified: no straightness line was measured (displacement lines do not see squareness; measure "
          "straightness of both axes against one reference, or give it from a squareness measurement)",
          model.terms()[static_cast<std::size_t>(t)].name));
    }
  } else if (!statics.empty()) {
    // Per line: observed slope (after the other own terms), and the slope each static term,
    // gauge rotation and other axis' identified error puts into it.
    const auto n_lines = static_cast<Eigen::Index>(straightness_lines.size());
    Eigen::MatrixXd g_static(n_lines, static_cast<Eigen::Index>(statics.size()));
    Eigen::MatrixXd g_gauge(n_lines, 3);
    Eigen::VectorXd observed(n_lines);
    for (Eigen::Index r = 0; r < n_lines; ++r) {
      const auto& line = ctx.lines[straightness_lines[static_cast<std::size_t>(r)]];
      const double xa = line.position_mm.front(), xb = line.position_mm.back();
      const auto row_a = readingRow(model, atNode(line, xa), line.point_mm, line.component);
      const auto row_b = readingRow(model, atNode(line, xb), line.point_mm, line.component);
      const Eigen::RowVectorXd d_row = (row_b - row_a) / (xb - xa);
      // The line's reading less what the identified own terms other than its own put in it.
      const int own_term = model.termIndex(line.measures);
      Eigen::VectorXd z(static_cast<Eigen::Index>(line.position_mm.size()));
      for (std::size_t n = 0; n < line.position_mm.size(); ++n) {
        const auto row = readingRow(model, atNode(line, line.position_mm[n]), line.point_mm, line.component);
        double v = line.mean[n];
        for (const auto& [name, curve] : ctx.curves) {
          const int t = model.termIndex(name);
          const auto& term = model.terms()[static_cast<std::size_t>(t)];
          if (t == own_term) continue;
          const int c = model.coordinateOfJoint(term.joint);
          const double at = c == line.coordinate ? line.position_mm[n] : line.q(c);
          v -= row(t) * interpolate(curve, at);
        }
        z(static_cast<Eigen::Index>(n)) = v;
      }
      observed(r) = slope(line.position_mm, z);
      for (std::size_t s = 0; s < statics.size(); ++s) g_static(r, static_cast<Eigen::Index>(s)) = d_row(statics[s]);
      // A rotation w (urad) of the workpiece frame changes the reading by -(w x P)_d.
      const Eigen::Vector3d u =
          (model.actualPoint(atNode(line, xb), Eigen::VectorXd::Zero(row_a.size()), line.point_mm) -
           model.actualPoint(atNode(line, xa), Eigen::VectorXd::Zero(row_a.size()), line.point_mm)) /
          (xb - xa);
      for (int m = 0; m < 3; ++m) {
        g_gauge(r, m) = -Eigen::Vector3d::Unit(m).cross(u)(line.component) * kUmPerMmPerUrad;
      }
    }
    // Unknowns: the gauge rotations the lines see, then the static terms they separate.
    std::vector<Eigen::VectorXd> columns;
    std::vector<int> chosen_statics;
    auto rankWith = [&](const Eigen::VectorXd& col) {
      Eigen::MatrixXd m(n_lines, static_cast<Eigen::Index>(columns.size()) + 1);
      for (std::size_t c = 0; c < columns.size(); ++c) m.col(static_cast<Eigen::Index>(c)) = columns[c];
      m.col(m.cols() - 1) = col;
      return std::isfinite(conditionNumber(m));
    };
    for (int m = 0; m < 3; ++m) {
      if (g_gauge.col(m).norm() > 1e-12 && rankWith(g_gauge.col(m))) columns.push_back(g_gauge.col(m));
    }
    const std::size_t gauge_columns = columns.size();
    for (std::size_t s = 0; s < statics.size(); ++s) {
      const Eigen::VectorXd col = g_static.col(static_cast<Eigen::Index>(s));
      if (col.norm() > 1e-12 && rankWith(col)) {
        columns.push_back(col);
        chosen_statics.push_back(statics[s]);
      } else {
        ctx.out.notes.push_back(
            fmt::format("{} not identified: it needs straightness lines of both axes it relates, sharing one reference",
                        model.terms()[static_cast<std::size_t>(statics[s])].name));
      }
    }
    if (!chosen_statics.empty()) {
      Eigen::MatrixXd m(n_lines, static_cast<Eigen::Index>(columns.size()));
      for (std::size_t c = 0; c < columns.size(); ++c) m.col(static_cast<Eigen::Index>(c)) = columns[c];
      const Eigen::VectorXd solution = m.colPivHouseholderQr().solve(observed);
      int repeats = std::numeric_limits<int>::max();
      for (std::size_t i : straightness_lines) {
        for (int r : ctx.lines[i].repeats) repeats = std::min(repeats, r);
      }
      for (std::size_t s = 0; s < chosen_statics.size(); ++s) {
        ErrorCurveData c;
        c.name = model.terms()[static_cast<std::size_t>(chosen_statics[s])].name;
        c.mean.push_back(solution(static_cast<Eigen::Index>(gauge_columns + s)));
        c.s.push_back(std::nullopt);
        c.repeats.push_back(repeats);
        ctx.curves[c.name] = std::move(c);
      }
    }
  }
  // ISO 230-1 reference straight line: remove each straightness error's least-squares line.
  for (auto& [name, curve] : ctx.curves) {
    if (curve.position_mm.size() < 2 ||
        !isStraightness(model, model.terms()[static_cast<std::size_t>(model.termIndex(name))])) {
      continue;
    }
    const Eigen::VectorXd y =
        Eigen::Map<const Eigen::VectorXd>(curve.mean.data(), static_cast<Eigen::Index>(curve.mean.size()));
    const double b = slope(curve.position_mm, y);
    double mean_x = 0.0;
    for (double x : curve.position_mm) mean_x += x;
    mean_x /= static_cast<double>(curve.position_mm.size());
    const double a = y.mean() - b * mean_x;
    for (std::size_t n = 0; n < curve.mean.size(); ++n) curve.mean[n] -= a + b * curve.position_mm[n];
  }
}

}  // namespace

Eigen::RowVectorXd readingRow(const MultibodyModel& model, const Eigen::VectorXd& q, const Eigen::Vector3d& point_mm,
                              int component) {
  if (component < 3) return -model.jacobian(q, point_mm).row(component);  // P - P_ideal = -E
  return model.orientationJacobian(q).row(component - 3);
}

LineComparison compareLine(const ErrorModel& model, const MeasuredLine& line) {
  const MultibodyModel& kinematics = model.kinematics();
  checkLine(kinematics, line);
  LineComparison out;
  const Eigen::VectorXd zero = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(kinematics.terms().size()));
  const auto [lower, upper] = model.coordinateRange(line.coordinate);
  const bool ranged = upper > lower;  // no function of this axis: nothing extrapolates
  std::vector<Eigen::VectorXd> at;
  std::vector<Eigen::RowVectorXd> rows;
  for (std::size_t n = 0; n < line.position_mm.size(); ++n) {
    if (ranged && (line.position_mm[n] < lower - 1e-9 || line.position_mm[n] > upper + 1e-9)) {
      ++out.outside;
      continue;
    }
    const Eigen::VectorXd q = atNode(line, line.position_mm[n]);
    const Eigen::VectorXd e = model.errorsAt(q);
    const double predicted = line.component < 3 ? (kinematics.actualPoint(q, e, line.point_mm) -
                                                   kinematics.actualPoint(q, zero, line.point_mm))(line.component) *
                                                      1000.0
                                                : kinematics.orientationErrorUrad(q, e)(line.component - 3);
    const Eigen::RowVectorXd row = readingRow(kinematics, q, line.point_mm, line.component);
    at.push_back(q);
    rows.push_back(row);
    out.position_mm.push_back(line.position_mm[n]);
    out.measured.push_back(line.mean[n]);
    out.predicted.push_back(predicted);
    out.sigma.push_back(std::sqrt(row.cwiseProduct(model.sigmasAt(q).transpose()).squaredNorm()));
    out.offset += line.mean[n] - predicted;
  }
  if (out.position_mm.empty()) {
    throw InputError(
        fmt::format("{}: no node inside the range the model was measured over ({} to {} mm)", line.id, lower, upper));
  }
  out.offset /= static_cast<double>(out.position_mm.size());
  Eigen::MatrixXd sensitivity(static_cast<Eigen::Index>(rows.size()), rows.front().size());
  for (std::size_t k = 0; k < rows.size(); ++k) sensitivity.row(static_cast<Eigen::Index>(k)) = rows[k];
  out.predicted_error_factor = model.readingFitErrorFactor(at, sensitivity);
  double ss = 0.0;
  for (std::size_t n = 0; n < out.measured.size(); ++n) {
    const double r = out.measured[n] - out.predicted[n] - out.offset;
    out.residual.push_back(r);
    ss += r * r;
    out.peak = std::max(out.peak, std::abs(r));
  }
  out.rms = std::sqrt(ss / static_cast<double>(out.residual.size()));
  return out;
}

LineIdentification identifyFromLines(const MultibodyModel& model, const std::vector<MeasuredLine>& lines,
                                     const LineIdentificationOptions& options) {
  if (lines.empty()) throw InputError("no measured lines given");
  Context ctx{model, lines, options, {}, {}};
  std::map<int, std::vector<std::size_t>> by_axis;
  for (std::size_t i = 0; i < lines.size(); ++i) {
    checkLine(model, lines[i]);
    by_axis[lines[i].coordinate].push_back(i);
  }
  for (const auto& [coordinate, members] : by_axis) solveAxis(ctx, coordinate, members);
  if (options.method == IdentificationMethod::kNineLine) integrateStraightness(ctx);
  squarenessAndReferenceLines(ctx);
  for (auto& [name, curve] : ctx.curves) ctx.out.curves.push_back(std::move(curve));
  // Terms of the measured axes that nothing determined.
  for (const auto& term : model.terms()) {
    if (!term.motion) continue;
    const int c = model.coordinateOfJoint(term.joint);
    const bool measured_axis = by_axis.count(c) > 0;
    const bool found = std::any_of(ctx.out.curves.begin(), ctx.out.curves.end(),
                                   [&](const ErrorCurveData& d) { return d.name == term.name; });
    if (measured_axis && !found) ctx.out.notes.push_back(term.name + " not determined by these lines: taken as zero");
  }
  return std::move(ctx.out);
}

}  // namespace mtcal::processing
