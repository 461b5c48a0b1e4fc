#include "mtcal/processing/iso230_4.h"

#include <fmt/format.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include "mtcal/error.h"

namespace mtcal::processing {
namespace {

constexpr double kPi = std::numbers::pi;

double wrap2Pi(double a) {
  a = std::fmod(a, 2.0 * kPi);
  return a < 0.0 ? a + 2.0 * kPi : a;
}

// The angle span covered by a set of angles: 2 pi minus the largest gap between neighbours.
double angleSpan(std::vector<double> angles) {
  for (auto& a : angles) a = wrap2Pi(a);
  std::sort(angles.begin(), angles.end());
  double gap = angles.front() + 2.0 * kPi - angles.back();
  for (std::size_t i = 1; i < angles.size(); ++i) gap = std::max(gap, angles[i] - angles[i - 1]);
  return 2.0 * kPi - gap;
}

Eigen::Vector2d pointOf(double radius_mm, const CirclePoint& p) {
  const double r = radius_mm + p.deviation_um / 1000.0;
  return {r * std::cos(p.angle_rad), r * std::sin(p.angle_rad)};
}

// Radial deviations (um) from the nominal radius about `centre`.
std::vector<double> radialAbout(double radius_mm, const std::vector<CirclePoint>& points,
                                const Eigen::Vector2d& centre) {
  std::vector<double> r;
  for (const auto& p : points) r.push_back(((pointOf(radius_mm, p) - centre).norm() - radius_mm) * 1000.0);
  return r;
}

std::vector<CirclePoint> ofDirection(const std::vector<CirclePoint>& points, CircleDirection d) {
  std::vector<CirclePoint> out;
  for (const auto& p : points) {
    if (p.direction == d) out.push_back(p);
  }
  return out;
}

CircleFit fitOf(double radius_mm, const std::vector<CirclePoint>& points) {
  std::vector<Eigen::Vector2d> xy;
  for (const auto& p : points) xy.push_back(pointOf(radius_mm, p));
  return fitCircle(xy);
}

CircularPathResult evaluatePath(double radius_mm, const std::vector<CirclePoint>& points) {
  CircularPathResult out;
  const CircleFit fit = fitOf(radius_mm, points);
  const auto r = radialAbout(radius_mm, points, fit.centre);
  const auto [lo, hi] = std::minmax_element(r.begin(), r.end());
  out.points = static_cast<int>(points.size());
  std::vector<double> angles;
  for (const auto& p : points) angles.push_back(p.angle_rad);
  out.angle_span_deg = angleSpan(angles) * 180.0 / kPi;
  out.g_um = *hi - *lo;
  out.radius_deviation_um = (fit.radius - radius_mm) * 1000.0;
  out.centre_first_um = fit.centre.x() * 1000.0;
  out.centre_second_um = fit.centre.y() * 1000.0;
  out.rms_um = fit.rms_residual * 1000.0;
  return out;
}

// Linear interpolation of a periodic sampled function at `angle`, within `max_gap` of data.
std::optional<double> interpolateAt(const std::vector<std::pair<double, double>>& sorted, double angle,
                                    double max_gap) {
  const double a = wrap2Pi(angle);
  auto hi = std::lower_bound(sorted.begin(), sorted.end(), std::pair{a, -1e300});
  const auto& after = hi == sorted.end() ? sorted.front() : *hi;
  const auto& before = hi == sorted.begin() ? sorted.back() : *std::prev(hi);
  const double span = wrap2Pi(after.first - before.first);
  const double into = wrap2Pi(a - before.first);
  if (span > max_gap) return std::nullopt;
  return span > 0.0 ? before.second + (after.second - before.second) * into / span : before.second;
}

}  // namespace

CircleFit fitCircle(const std::vector<Eigen::Vector2d>& points) {
  const auto n = static_cast<Eigen::Index>(points.size());
  if (n < 3) throw InputError(fmt::format("circle fit: {} point(s), at least 3 needed", n));
  // Algebraic start (Kasa): x^2 + y^2 = a x + b y + c, about the mean for conditioning.
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (const auto& p : points) mean += p;
  mean /= static_cast<double>(n);
  Eigen::MatrixXd a(n, 3);
  Eigen::VectorXd rhs(n);
  for (Eigen::Index i = 0; i < n; ++i) {
    const Eigen::Vector2d q = points[static_cast<std::size_t>(i)] - mean;
    a.row(i) << q.x(), q.y(), 1.0;
    rhs(i) = q.squaredNorm();
  }
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(a, Eigen::ComputeThinU | Eigen::ComputeThinV);
  const Eigen::VectorXd sv = svd.singularValues();
  if (sv(2) <= 1e-12 * sv(0)) throw InputError("circle fit: the points are collinear (or coincide)");
  const Eigen::Vector3d k = svd.solve(rhs);
  Eigen::Vector3d x(k(0) / 2.0, k(1) / 2.0, 0.0);
  x(2) = std::sqrt(k(2) + x(0) * x(0) + x(1) * x(1));
  // Gauss-Newton on the orthogonal distances d_i = |p_i - c| - r.
  CircleFit fit;
  Eigen::MatrixXd j(n, 3);
  Eigen::VectorXd d(n);
  for (fit.iterations = 1; fit.iterations <= 100; ++fit.iterations) {
    for (Eigen::Index i = 0; i < n; ++i) {
      const Eigen::Vector2d q = points[static_cast<std::size_t>(i)] - mean - x.head<2>();
      const double dist = q.norm();
      d(i) = dist - x(2);
      j.row(i) << -q.x() / dist, -q.y() / dist, -1.0;
    }
    const Eigen::Vector3d step = j.colPivHouseholderQr().solve(-d);
    x += step;
    if (step.norm() <= 1e-13 * std::max(1.0, x(2))) break;
  }
  for (Eigen::Index i = 0; i < n; ++i) d(i) = (points[static_cast<std::size_t>(i)] - mean - x.head<2>()).norm() - x(2);
  fit.centre = mean + x.head<2>();
  fit.radius = x(2);
  fit.rms_residual = std::sqrt(d.squaredNorm() / static_cast<double>(n));
  return fit;
}

const char* directionName(CircleDirection d) { return d == CircleDirection::kCcw ? "ccw" : "cw"; }

CircleDirection parseDirection(const std::string& text) {
  std::string t;
  for (char c : text) t.push_back(static_cast<char>(std::tolower(static_cast<unsigned char>(c))));
  if (t == "ccw") return CircleDirection::kCcw;
  if (t == "cw") return CircleDirection::kCw;
  throw InputError("direction '" + text + "' is not cw or ccw");
}

CircularTestResult evaluateCircularTest(double radius_mm, const std::vector<CirclePoint>& points) {
  if (!(radius_mm > 0.0)) throw InputError(fmt::format("circular test: radius {} mm must be > 0", radius_mm));
  CircularTestResult out;
  out.radius_mm = radius_mm;
  const auto ccw = ofDirection(points, CircleDirection::kCcw);
  const auto cw = ofDirection(points, CircleDirection::kCw);
  if (ccw.empty() && cw.empty()) throw InputError("circular test: no points");
  for (const auto& [path, result, name] : {std::tuple{&ccw, &out.ccw, "ccw"}, std::tuple{&cw, &out.cw, "cw"}}) {
    if (path->empty()) continue;
    if (path->size() < 3)
      throw InputError(fmt::format("circular test: {} path has {} point(s), at least 3 needed", name, path->size()));
    *result = evaluatePath(radius_mm, *path);
  }
  const CircleFit common = fitOf(radius_mm, points);
  out.centre_first_um = common.centre.x() * 1000.0;
  out.centre_second_um = common.centre.y() * 1000.0;
  if (ccw.empty() || cw.empty()) return out;
  const auto r_ccw = radialAbout(radius_mm, ccw, common.centre);
  const auto r_cw = radialAbout(radius_mm, cw, common.centre);
  const auto [lo_a, hi_a] = std::minmax_element(r_ccw.begin(), r_ccw.end());
  const auto [lo_b, hi_b] = std::minmax_element(r_cw.begin(), r_cw.end());
  out.g_b_um = std::max(*hi_a, *hi_b) - std::min(*lo_a, *lo_b);
  // H: each CCW point against the CW path interpolated at its angle (where the CW path has
  // data: not across gaps wider than 5 degrees, e.g. outside a partial arc).
  std::vector<std::pair<double, double>> cw_sorted;
  for (std::size_t i = 0; i < cw.size(); ++i) cw_sorted.emplace_back(wrap2Pi(cw[i].angle_rad), r_cw[i]);
  std::sort(cw_sorted.begin(), cw_sorted.end());
  double h = 0.0;
  bool any = false;
  for (std::size_t i = 0; i < ccw.size(); ++i) {
    if (auto other = interpolateAt(cw_sorted, ccw[i].angle_rad, 5.0 * kPi / 180.0)) {
      h = std::max(h, std::abs(r_ccw[i] - *other));
      any = true;
    }
  }
  if (any) out.h_um = h;
  return out;
}

namespace {

// Columns of the signature basis, in the order of the fit.
enum Column {
  kCentreFirstCcw,
  kCentreSecondCcw,
  kCentreFirstCw,
  kCentreSecondCw,
  kRadius,
  kScaleDifference,
  kSquareness,
  kServo,
  kBacklashFirst,
  kBacklashSecond,
  kStraightFirst,
  kStraightSecond,
  kSpikeFirst,
  kSpikeSecond,
  kColumns
};

// Elapsed travel angle after passing `reversal` in direction d (0 at the reversal).
double sinceReversal(double angle, double reversal, double d) { return wrap2Pi(d * (angle - reversal)); }

// What shapes the reversal signatures, found by search (nonlinear in the basis).
struct ReversalShape {
  double radius_mm = 100.0;
  double lag_rad = 0.0;            ///< the axes reverse this much after the programmed angle (servo lag x omega)
  double mismatch_rad = 0.0;       ///< the first axis' lag minus the second's (servo mismatch x omega)
  double decay_rad = 0.0;          ///< stick decay x omega; 0: no stick columns
  double play_um[2] = {0.0, 0.0};  ///< lost motion of each axis: its error ramps across the play after a reversal
};

// One axis' error after its latest reversal, in units of its parameter: the lost motion
// (-s (min(delta / b, 1) - 1/2), delta the motor's travel since the reversal; a step for b -> 0)
// and the stick (-s exp(-phi / decay)), s the new direction of travel.
struct ReversalTerms {
  double play = 0.0, stick = 0.0;
};
ReversalTerms reversalTerms(double t, double d, int axis, const ReversalShape& shape) {
  // The first axis reverses at 0 and pi (new direction -cos r), the second at pi/2 and 3pi/2 (-sin r).
  const double r0 = axis == 0 ? 0.0 : kPi / 2;
  double phi = 1e300, r_latest = r0;
  for (double r : {r0, r0 + kPi}) {
    const double lag = shape.lag_rad + (axis == 0 ? 0.5 : -0.5) * shape.mismatch_rad;
    const double since = sinceReversal(t, r + d * lag, d);
    if (since < phi) {
      phi = since;
      r_latest = r;
    }
  }
  const double s_new = axis == 0 ? -std::cos(r_latest) : -std::sin(r_latest);
  const double travel_um = shape.radius_mm * (1.0 - std::cos(phi)) * 1000.0;
  const double b = shape.play_um[axis];
  ReversalTerms out;
  out.play = -s_new * ((b > 0.0 ? std::min(travel_um / b, 1.0) : 1.0) - 0.5);
  if (shape.decay_rad > 0.0) out.stick = -s_new * std::exp(-phi / shape.decay_rad);
  return out;
}

Eigen::RowVectorXd basisRow(const CirclePoint& p, const ReversalShape& shape) {
  const double t = p.angle_rad, c = std::cos(t), s = std::sin(t);
  const double d = static_cast<double>(static_cast<int>(p.direction));
  const bool ccw = p.direction == CircleDirection::kCcw;
  Eigen::RowVectorXd row = Eigen::RowVectorXd::Zero(kColumns);
  row(ccw ? kCentreFirstCcw : kCentreFirstCw) = c;
  row(ccw ? kCentreSecondCcw : kCentreSecondCw) = s;
  row(kRadius) = 1.0;
  row(kScaleDifference) = std::cos(2.0 * t);
  row(kSquareness) = std::sin(2.0 * t);
  row(kServo) = d * std::sin(2.0 * t);
  // Each axis' reversal errors act along it: radial projection by cos t / sin t.
  const ReversalTerms first = reversalTerms(t, d, 0, shape), second = reversalTerms(t, d, 1, shape);
  row(kBacklashFirst) = first.play * c;
  row(kBacklashSecond) = second.play * s;
  row(kSpikeFirst) = first.stick * c;
  row(kSpikeSecond) = second.stick * s;
  row(kStraightFirst) = c * c * s;   // error along the second axis = S (u/R)^2
  row(kStraightSecond) = s * s * c;  // error along the first axis = S (v/R)^2
  return row;
}

struct LinearFit {
  Eigen::VectorXd coef, se;
  double rss = 0.0;
  Eigen::VectorXd residual;
  std::vector<bool> used;
};

// Least squares on the columns in `use` only; standard errors from the residual variance.
LinearFit solve(const Eigen::MatrixXd& a, const Eigen::VectorXd& y, const std::vector<bool>& use) {
  std::vector<Eigen::Index> cols;
  for (Eigen::Index c = 0; c < a.cols(); ++c) {
    if (use[static_cast<std::size_t>(c)]) cols.push_back(c);
  }
  Eigen::MatrixXd sub(a.rows(), static_cast<Eigen::Index>(cols.size()));
  for (std::size_t k = 0; k < cols.size(); ++k) sub.col(static_cast<Eigen::Index>(k)) = a.col(cols[k]);
  const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(sub);
  const Eigen::VectorXd x = qr.solve(y);
  LinearFit f;
  f.used = use;
  f.residual = y - sub * x;
  f.rss = f.residual.squaredNorm();
  const double dof = std::max<double>(1.0, static_cast<double>(a.rows() - sub.cols()));
  const Eigen::MatrixXd cov = (sub.transpose() * sub).inverse() * (f.rss / dof);
  f.coef = Eigen::VectorXd::Zero(a.cols());
  f.se = Eigen::VectorXd::Constant(a.cols(), std::numeric_limits<double>::infinity());
  for (std::size_t k = 0; k < cols.size(); ++k) {
    f.coef(cols[k]) = x(static_cast<Eigen::Index>(k));
    f.se(cols[k]) = std::sqrt(cov(static_cast<Eigen::Index>(k), static_cast<Eigen::Index>(k)));
  }
  return f;
}

struct CyclicPeak {
  double reduction = 0.0, period_mm = 0.0, amplitude_um = 0.0;
  int axis = -1;
};

// The two columns of a cyclic error of one axis' drive with this period: its error
// a sin(2 pi u / p) + b cos(2 pi u / p) at the axis position u (R cos t or R sin t),
// projected on the radius.
Eigen::MatrixXd cyclicColumns(const std::vector<CirclePoint>& points, double radius_mm, int axis, double period_mm) {
  const auto n = static_cast<Eigen::Index>(points.size());
  Eigen::MatrixXd b(n, 2);
  for (Eigen::Index i = 0; i < n; ++i) {
    const double t = points[static_cast<std::size_t>(i)].angle_rad;
    const double proj = axis == 0 ? std::cos(t) : std::sin(t);
    const double pos = radius_mm * proj;
    b(i, 0) = std::sin(2.0 * kPi * pos / period_mm) * proj;
    b(i, 1) = std::cos(2.0 * kPi * pos / period_mm) * proj;
  }
  return b;
}

// A least-squares periodogram, per axis, over periods from 1 mm to 2R (600 log-spaced trials
// per axis, then refined): for each period the reduction of the residual sum of squares when
// its two columns join the fitted basis (the extra sum of squares: the columns are taken
// orthogonal to the basis, so a long wave that the basis' signatures partly explain is not
// credited to the other axis). On at most ~15000 of the points.
CyclicPeak strongestCycle(const std::vector<CirclePoint>& points, double radius_mm, const Eigen::VectorXd& residual,
                          const Eigen::MatrixXd& basis) {
  const std::size_t stride = std::max<std::size_t>(1, points.size() / 15000);
  std::vector<CirclePoint> sub;
  std::vector<Eigen::Index> rows;
  for (std::size_t i = 0; i < points.size(); i += stride) {
    sub.push_back(points[i]);
    rows.push_back(static_cast<Eigen::Index>(i));
  }
  const auto m = static_cast<Eigen::Index>(rows.size());
  Eigen::MatrixXd a(m, basis.cols());
  Eigen::VectorXd r(m);
  for (Eigen::Index i = 0; i < m; ++i) {
    a.row(i) = basis.row(rows[static_cast<std::size_t>(i)]);
    r(i) = residual(rows[static_cast<std::size_t>(i)]);
  }
  const Eigen::HouseholderQR<Eigen::MatrixXd> qr(a);
  const Eigen::MatrixXd q = qr.householderQ() * Eigen::MatrixXd::Identity(m, basis.cols());
  r -= q * (q.transpose() * r);
  CyclicPeak best;
  const int trials = 600;
  const double p_min = 1.0, p_max = 2.0 * radius_mm;  // down to one period across the diameter
  auto tryPeriod = [&](int axis, double period) {
    Eigen::MatrixXd b = cyclicColumns(sub, radius_mm, axis, period);
    b -= q * (q.transpose() * b);
    const Eigen::Matrix2d gram = b.transpose() * b;
    if (gram.determinant() <= 1e-12 * gram.trace() * gram.trace()) return;  // explained by the basis
    const Eigen::Vector2d x = gram.ldlt().solve(b.transpose() * r);
    const double reduction = (b * x).squaredNorm() * static_cast<double>(stride);
    if (reduction > best.reduction) best = {reduction, period, x.norm(), axis};
  };
  const double step = std::pow(p_max / p_min, 1.0 / (trials - 1.0));
  for (int axis = 0; axis < 2; ++axis) {
    for (int k = 0; k < trials; ++k) tryPeriod(axis, p_min * std::pow(step, k));
  }
  // Refined between the neighbours of the best trial (the peak is narrower than the grid
  // for periods much shorter than the circle).
  if (best.axis >= 0) {
    const CyclicPeak coarse = best;
    for (int k = -50; k <= 50; ++k) tryPeriod(coarse.axis, coarse.period_mm * std::pow(step, k / 50.0));
  }
  return best;
}

// Smallest signature amplitude (um on the radius) worth naming, whatever its t statistic:
// below it a "finding" would be the fit's own model error on a good machine.
constexpr double kFloorUm = 0.1;

}  // namespace

BallbarDiagnosis diagnoseBallbar(double radius_mm, const std::vector<CirclePoint>& points,
                                 const BallbarDiagnosisOptions& options) {
  if (!(radius_mm > 0.0)) throw InputError(fmt::format("ballbar diagnosis: radius {} mm must be > 0", radius_mm));
  if (points.size() < 20)
    throw InputError(fmt::format("ballbar diagnosis: {} points, at least 20 needed", points.size()));
  const bool has_ccw =
      std::any_of(points.begin(), points.end(), [](const auto& p) { return p.direction == CircleDirection::kCcw; });
  const bool has_cw =
      std::any_of(points.begin(), points.end(), [](const auto& p) { return p.direction == CircleDirection::kCw; });
  const bool both = has_ccw && has_cw;
  BallbarDiagnosis out;
  const auto n = static_cast<Eigen::Index>(points.size());
  Eigen::VectorXd y(n);
  for (Eigen::Index i = 0; i < n; ++i) y(i) = points[static_cast<std::size_t>(i)].deviation_um;

  std::vector<bool> use(kColumns, true);
  use[kCentreFirstCcw] = use[kCentreSecondCcw] = has_ccw;
  use[kCentreFirstCw] = use[kCentreSecondCw] = has_cw;
  if (!both) {
    // One direction cannot tell squareness from servo mismatch, nor backlash from a centre offset.
    use[kServo] = use[kBacklashFirst] = use[kBacklashSecond] = false;
    out.notes.push_back(
        "one direction only: squareness and servo mismatch are not separated (reported as squareness), backlash not "
        "estimated");
  }
  // The reversal signatures' shape: the servo lag that delays each reversal after its
  // programmed angle, the stick's decay (both at the test's feed) and the lost motion that
  // shapes the ramp across the play are found by search: lag and decay on a grid (on at most
  // ~8000 of the points), the play by refitting with the last estimate.
  const double omega = options.feed_mm_per_min / 60.0 / radius_mm;  // rad/s
  // A cyclic error of a drive, found first (it would bias the searches below): the columns of
  // its period, appended to the basis.
  Eigen::MatrixXd cyclic(n, 0);
  auto build = [&](const ReversalShape& shape) {
    Eigen::MatrixXd m(n, kColumns + cyclic.cols());
    for (Eigen::Index i = 0; i < n; ++i) m.row(i).head(kColumns) = basisRow(points[static_cast<std::size_t>(i)], shape);
    m.rightCols(cyclic.cols()) = cyclic;
    return m;
  };
  auto withCyclic = [&](std::vector<bool> columns) {
    columns.resize(kColumns + static_cast<std::size_t>(cyclic.cols()), true);
    return columns;
  };
  ReversalShape shape;
  shape.radius_mm = radius_mm;
  std::vector<bool> no_spikes = use;
  no_spikes[kSpikeFirst] = no_spikes[kSpikeSecond] = false;
  Eigen::MatrixXd a = build(shape);
  LinearFit fit = solve(a, y, no_spikes);
  {
    // rms before: about each path's own LSQ circle (centre and radius per direction)
    std::vector<bool> circle(kColumns, false);
    circle[kCentreFirstCcw] = circle[kCentreSecondCcw] = has_ccw;
    circle[kCentreFirstCw] = circle[kCentreSecondCw] = has_cw;
    circle[kRadius] = true;
    out.rms_before_um = std::sqrt(solve(a, y, circle).rss / static_cast<double>(n));
  }
  {
    // What the first fit leaves, searched for a cyclic error of either drive; one that stands
    // out (chi-square with 2 degrees of freedom over 1200 trials: exp(-q/2) * 1200 < 1e-4
    // gives q > 32.6) joins the basis.
    const double dof = static_cast<double>(n) - static_cast<double>(std::count(fit.used.begin(), fit.used.end(), true));
    const double sigma2 = fit.rss / std::max(1.0, dof);
    Eigen::MatrixXd used(n, 0);
    for (Eigen::Index c = 0; c < a.cols(); ++c) {
      if (fit.used[static_cast<std::size_t>(c)]) {
        used.conservativeResize(n, used.cols() + 1);
        used.col(used.cols() - 1) = a.col(c);
      }
    }
    const CyclicPeak peak = strongestCycle(points, radius_mm, fit.residual, used);
    if (peak.axis >= 0 && peak.reduction / sigma2 > 33.0 && peak.amplitude_um > kFloorUm) {
      cyclic = cyclicColumns(points, radius_mm, peak.axis, peak.period_mm);
      out.cyclic_period_mm = peak.period_mm;
      out.cyclic_axis = peak.axis;
      use = withCyclic(use);
      no_spikes = withCyclic(no_spikes);
      a = build(shape);
      fit = solve(a, y, no_spikes);
    }
  }
  // The reversal signatures' shape: the servo lag that delays each reversal after its
  // programmed angle, the stick's decay (both at the test's feed) and the lost motion that
  // shapes the ramp across the play are found by search: lag and decay on a grid (on the
  // points near the reversals and a stride of the others), the play by refitting with the
  // last estimate.
  if (both) {
    // Every point within 5 degrees of a reversal (where the shapes differ), a stride elsewhere.
    const std::size_t stride = std::max<std::size_t>(1, points.size() / 8000);
    std::vector<std::size_t> subset;
    for (std::size_t i = 0; i < points.size(); ++i) {
      const double quarter = std::fmod(wrap2Pi(points[i].angle_rad), kPi / 2);
      if (i % stride == 0 || quarter < 5.0 * kPi / 180.0 || quarter > 85.0 * kPi / 180.0) subset.push_back(i);
    }
    const auto m = static_cast<Eigen::Index>(subset.size());
    // The data's angular spacing (median of each direction's neighbours): a stick shorter than
    // a few samples cannot be told from noise on one point.
    std::vector<double> gaps;
    for (std::size_t i = 1; i < points.size(); ++i) {
      if (points[i].direction == points[i - 1].direction)
        gaps.push_back(std::abs(points[i].angle_rad - points[i - 1].angle_rad));
    }
    std::nth_element(gaps.begin(), gaps.begin() + static_cast<std::ptrdiff_t>(gaps.size() / 2), gaps.end());
    const double spacing_rad = gaps.empty() ? 0.0 : gaps[gaps.size() / 2];
    Eigen::VectorXd ys(m);
    Eigen::MatrixXd cyclic_subset(m, cyclic.cols());
    for (Eigen::Index i = 0; i < m; ++i) {
      const auto row = static_cast<Eigen::Index>(subset[static_cast<std::size_t>(i)]);
      ys(i) = y(row);
      cyclic_subset.row(i) = cyclic.row(row);
    }
    auto subsetFit = [&](const ReversalShape& trial, const std::vector<bool>& columns) {
      Eigen::MatrixXd sa(m, kColumns + cyclic.cols());
      for (Eigen::Index i = 0; i < m; ++i)
        sa.row(i).head(kColumns) = basisRow(points[subset[static_cast<std::size_t>(i)]], trial);
      sa.rightCols(cyclic.cols()) = cyclic_subset;
      return solve(sa, ys, columns);
    };
    for (int round = 0; round < 3; ++round) {
      // the play from the current fit, then lag and decay with it
      shape.play_um[0] = std::max(0.0, fit.coef(kBacklashFirst));
      shape.play_um[1] = std::max(0.0, fit.coef(kBacklashSecond));
      // each axis' lag: the common one searched, their difference from the servo mismatch
      shape.mismatch_rad = omega * fit.coef(kServo) * 2.0 / (options.feed_mm_per_min / 60.0) / 1000.0;
      // The lag, with the sticks as the last round found them (none in the first). A lag that
      // does not beat none clearly (chi-square, 1 degree of freedom, 1e-3) stays 0: without
      // lost motion's steps to pin it, a shifted exponential is the same exponential scaled.
      const std::vector<bool>& columns = shape.decay_rad > 0.0 ? use : no_spikes;
      const LinearFit at_zero = subsetFit(
          [&] {
            ReversalShape z = shape;
            z.lag_rad = z.mismatch_rad = 0.0;
            return z;
          }(),
          columns);
      const double sigma2 = at_zero.rss / std::max(1.0, static_cast<double>(m - kColumns));
      double best_rss = at_zero.rss - 11.0 * sigma2;
      ReversalShape best = shape;
      best.lag_rad = best.mismatch_rad = 0.0;
      for (int lag_ms = 2; lag_ms <= 60; lag_ms += 2) {
        ReversalShape trial = shape;
        trial.lag_rad = omega * lag_ms / 1000.0;
        if (trial.lag_rad < 2.0 * spacing_rad) continue;  // a lag within the data's spacing cannot be told
        const double rss = subsetFit(trial, columns).rss;
        if (rss < best_rss) {
          best_rss = rss;
          best.lag_rad = trial.lag_rad;
          best.mismatch_rad = trial.mismatch_rad;
        }
      }
      // Lag and decay refined together (1 ms about the lag found).
      best_rss = std::numeric_limits<double>::infinity();
      const double lag_found_ms = best.lag_rad / omega * 1000.0;
      for (double lag_ms = std::max(0.0, lag_found_ms - 6.0); lag_ms <= (lag_found_ms > 0.0 ? lag_found_ms + 6.0 : 0.0);
           lag_ms += 1.0) {
        for (double decay_s : {0.0, 0.005, 0.01, 0.015, 0.02, 0.03, 0.05, 0.1}) {
          if (decay_s > 0.0 && omega * decay_s < 1.5 * spacing_rad) continue;  // a stick on too few points
          ReversalShape trial = best;
          trial.lag_rad = omega * lag_ms / 1000.0;
          trial.decay_rad = omega * decay_s;
          const double rss = subsetFit(trial, decay_s > 0.0 ? use : no_spikes).rss;
          if (rss < best_rss) {
            best_rss = rss;
            best.decay_rad = trial.decay_rad;
            best.lag_rad = trial.lag_rad;
          }
        }
      }
      shape = best;
      a = build(shape);
      fit = solve(a, y, shape.decay_rad > 0.0 ? use : no_spikes);
    }
  } else {
    fit = solve(a, y, no_spikes);
  }
  const double best_decay_s = shape.decay_rad / omega;
  if (cyclic.cols() > 0) out.cyclic_amplitude_um = std::hypot(fit.coef(kColumns), fit.coef(kColumns + 1));
  out.rms_after_um = std::sqrt(fit.rss / static_cast<double>(n));
  auto detected = [&](Column c, double amplitude_um) {
    return fit.used[c] && std::abs(fit.coef(c)) > options.min_t_statistic * fit.se(c) &&
           std::abs(amplitude_um) > kFloorUm;
  };
  const double feed_mm_s = options.feed_mm_per_min / 60.0;
  if (detected(kSquareness, fit.coef(kSquareness))) {
    // x error = a y reads as +(a R / 2) sin 2t; the reported squareness is the angle between
    // the axes' + directions minus 90 deg, which such an error makes smaller: -a.
    out.squareness_urad = -fit.coef(kSquareness) * 2.0 / radius_mm * 1000.0;  // um over mm: 1e-3 rad -> urad
  }
  if (detected(kServo, fit.coef(kServo)))
    out.servo_mismatch_ms = fit.coef(kServo) * 2.0 / feed_mm_s;  // um / (mm/s) = ms
  if (options.bar_zeroed) {
    // mean radius R (sx + sy)/2 and cos 2t coefficient R (sx - sy)/2; um = mm * ppm * 1e-3
    const double c0 = fit.coef(kRadius), c2 = fit.coef(kScaleDifference);
    double sx_ppm = (c0 + c2) / radius_mm * 1000.0, sy_ppm = (c0 - c2) / radius_mm * 1000.0;
    // A position loop with lag tau follows a circle at 1 / sqrt(1 + (omega tau)^2) of its
    // radius: each axis reads (omega tau)^2 / 2 short, which is not a scale error. With the
    // lags the reversals gave, that part is put back (not where the angles are timed from the
    // feed-in, which the axes reach late by about their lag: the reversals then read it short).
    const auto reduction_ppm = [](double lag_rad) { return (1.0 - 1.0 / std::sqrt(1.0 + lag_rad * lag_rad)) * 1e6; };
    if (options.timed_from_feed_in) {
      out.notes.push_back(fmt::format(
          "scale not corrected for the servo loops' radius reduction: the angles are timed from the bar's feed-in, "
          "which the axes reach late by about their lag, so the reversals do not give it (a lag of 30 ms would "
          "leave each axis {:.1f} ppm short at this feed and radius)",
          reduction_ppm(omega * 0.030)));
    } else if (shape.lag_rad > 0.0) {
      const double first_ppm = reduction_ppm(shape.lag_rad + 0.5 * shape.mismatch_rad),
                   second_ppm = reduction_ppm(shape.lag_rad - 0.5 * shape.mismatch_rad);
      sx_ppm += first_ppm;
      sy_ppm += second_ppm;
      out.notes.push_back(fmt::format("scale corrected for the servo loops' radius reduction ({:.1f} and {:.1f} ppm)",
                                      first_ppm, second_ppm));
    }
    const bool any = detected(kRadius, c0) || detected(kScaleDifference, c2);
    if (any) {
      out.scale_mismatch_first_ppm = sx_ppm;
      out.scale_mismatch_second_ppm = sy_ppm;
    }
    out.notes.push_back(
        "scale per axis assumes the bar was zeroed in its calibrator: the mean radius is read as a scale error "
        "(it also holds the calibrator's uncertainty and the thermal growth of machine and bar)");
  } else if (detected(kScaleDifference, fit.coef(kScaleDifference))) {
    const double diff_ppm = fit.coef(kScaleDifference) * 2.0 / radius_mm * 1000.0;
    out.scale_mismatch_first_ppm = diff_ppm / 2.0;
    out.scale_mismatch_second_ppm = -diff_ppm / 2.0;
    out.notes.push_back("bar not zeroed: only the scale difference between the axes is known (reported split evenly)");
  }
  if (detected(kBacklashFirst, fit.coef(kBacklashFirst) / 2.0)) out.backlash_first_um = fit.coef(kBacklashFirst);
  if (detected(kBacklashSecond, fit.coef(kBacklashSecond) / 2.0)) out.backlash_second_um = fit.coef(kBacklashSecond);
  if (best_decay_s > 0.0) {
    if (detected(kSpikeFirst, fit.coef(kSpikeFirst))) out.reversal_spike_first_um = fit.coef(kSpikeFirst);
    if (detected(kSpikeSecond, fit.coef(kSpikeSecond))) out.reversal_spike_second_um = fit.coef(kSpikeSecond);
    if (out.reversal_spike_first_um || out.reversal_spike_second_um) {
      out.notes.push_back(fmt::format("reversal spikes decay in about {:.0f} ms", best_decay_s * 1000.0));
    }
    if (shape.lag_rad > 0.0) {
      out.notes.push_back(fmt::format("the axes reverse about {:.0f} ms after {}", shape.lag_rad / omega * 1000.0,
                                      options.timed_from_feed_in
                                          ? "the angle timed from the feed-in (their lag less the feed-in's)"
                                          : "the programmed angle (servo lag)"));
    }
  }
  if (detected(kStraightFirst, fit.coef(kStraightFirst))) out.straightness_first_um = fit.coef(kStraightFirst);
  if (detected(kStraightSecond, fit.coef(kStraightSecond))) out.straightness_second_um = fit.coef(kStraightSecond);

  return out;
}

}  // namespace mtcal::processing
