#include "mtcal/processing/grinding.h"

#include <fmt/format.h>

#include <Eigen/Dense>
#include <Eigen/Sparse>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <sstream>

#include "mtcal/error.h"

namespace mtcal::processing {
namespace {
constexpr double kPi = std::numbers::pi;

double signedArea(const std::vector<Eigen::Vector2d>& p) {
  double a = 0.0;
  for (std::size_t i = 0; i < p.size(); ++i) {
    const auto& u = p[i];
    const auto& v = p[(i + 1) % p.size()];
    a += u.x() * v.y() - v.x() * u.y();
  }
  return a / 2.0;
}

double cross(const Eigen::Vector2d& a, const Eigen::Vector2d& b) { return a.x() * b.y() - a.y() * b.x(); }

}  // namespace

PeriodicSpline2d::PeriodicSpline2d(const std::vector<Eigen::Vector2d>& points) : p_(points) {
  const std::size_t n = p_.size();
  if (n < 4) throw InputError(fmt::format("cam profile: {} point(s), at least 4 needed", n));
  s_.assign(n + 1, 0.0);
  std::vector<double> h(n);
  for (std::size_t i = 0; i < n; ++i) {
    h[i] = (p_[(i + 1) % n] - p_[i]).norm();
    if (!(h[i] > 1e-9)) throw InputError(fmt::format("cam profile: points {} and {} coincide", i + 1, (i + 1) % n + 1));
    s_[i + 1] = s_[i] + h[i];
  }
  period_ = s_[n];
  // Periodic cubic spline: h_{i-1} M_{i-1} + 2 (h_{i-1} + h_i) M_i + h_i M_{i+1} = 6 (d_i - d_{i-1}).
  Eigen::SparseMatrix<double> a(static_cast<Eigen::Index>(n), static_cast<Eigen::Index>(n));
  std::vector<Eigen::Triplet<double>> t;
  Eigen::MatrixXd rhs(static_cast<Eigen::Index>(n), 2);
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t prev = (i + n - 1) % n, next = (i + 1) % n;
    t.emplace_back(static_cast<int>(i), static_cast<int>(prev), h[prev]);
    t.emplace_back(static_cast<int>(i), static_cast<int>(i), 2.0 * (h[prev] + h[i]));
    t.emplace_back(static_cast<int>(i), static_cast<int>(next), h[i]);
    const Eigen::Vector2d d = (p_[next] - p_[i]) / h[i] - (p_[i] - p_[prev]) / h[prev];
    rhs.row(static_cast<Eigen::Index>(i)) = 6.0 * d.transpose();
  }
  a.setFromTriplets(t.begin(), t.end());
  Eigen::SparseLU<Eigen::SparseMatrix<double>> lu(a);
  const Eigen::MatrixXd m = lu.solve(rhs);
  for (std::size_t i = 0; i < n; ++i)
    m_.emplace_back(m(static_cast<Eigen::Index>(i), 0), m(static_cast<Eigen::Index>(i), 1));
}

std::pair<std::size_t, double> PeriodicSpline2d::locate(double s) const {
  s = std::fmod(s, period_);
  if (s < 0.0) s += period_;
  const auto it = std::upper_bound(s_.begin(), s_.end(), s);
  const std::size_t i = std::min<std::size_t>(static_cast<std::size_t>(it - s_.begin()) - 1, p_.size() - 1);
  return {i, s - s_[i]};
}

Eigen::Vector2d PeriodicSpline2d::at(double s) const {
  const auto [i, x] = locate(s);
  const std::size_t j = (i + 1) % p_.size();
  const double h = s_[i + 1] - s_[i], u = h - x;
  return m_[i] * u * u * u / (6 * h) + m_[j] * x * x * x / (6 * h) + (p_[i] / h - m_[i] * h / 6) * u +
         (p_[j] / h - m_[j] * h / 6) * x;
}

Eigen::Vector2d PeriodicSpline2d::derivative(double s) const {
  const auto [i, x] = locate(s);
  const std::size_t j = (i + 1) % p_.size();
  const double h = s_[i + 1] - s_[i], u = h - x;
  return -m_[i] * u * u / (2 * h) + m_[j] * x * x / (2 * h) - (p_[i] / h - m_[i] * h / 6) + (p_[j] / h - m_[j] * h / 6);
}

Eigen::Vector2d PeriodicSpline2d::second(double s) const {
  const auto [i, x] = locate(s);
  const std::size_t j = (i + 1) % p_.size();
  const double h = s_[i + 1] - s_[i];
  return m_[i] * (h - x) / h + m_[j] * x / h;
}

double PeriodicSpline2d::curvature(double s) const {
  const Eigen::Vector2d d1 = derivative(s), d2 = second(s);
  return cross(d1, d2) / std::pow(d1.norm(), 3);
}

std::vector<Eigen::Vector2d> polarProfile(const std::vector<double>& angle_deg, const std::vector<double>& radius_mm) {
  if (angle_deg.size() != radius_mm.size() || angle_deg.size() < 4) {
    throw InputError(fmt::format("cam lift table: {} angle(s) and {} radius(es), at least 4 of each needed",
                                 angle_deg.size(), radius_mm.size()));
  }
  std::vector<Eigen::Vector2d> out;
  for (std::size_t i = 0; i < angle_deg.size(); ++i) {
    if (i > 0 && !(angle_deg[i] > angle_deg[i - 1])) {
      throw InputError(fmt::format("cam lift table: row {}: angle {} deg does not increase", i + 1, angle_deg[i]));
    }
    if (!(radius_mm[i] > 0.0))
      throw InputError(fmt::format("cam lift table: row {}: radius {} mm must be > 0", i + 1, radius_mm[i]));
    const double a = angle_deg[i] * kPi / 180.0;
    out.emplace_back(radius_mm[i] * std::cos(a), radius_mm[i] * std::sin(a));
  }
  if (!(angle_deg.back() - angle_deg.front() < 360.0))
    throw InputError("cam lift table: the angles span 360 deg or more");
  // The profile closes from the last row to the first: a table cut short would close with a
  // straight-ish chord across the turn's rest and grind another cam.
  double largest_step_deg = 0.0;
  for (std::size_t i = 1; i < angle_deg.size(); ++i)
    largest_step_deg = std::max(largest_step_deg, angle_deg[i] - angle_deg[i - 1]);
  if (const double closing_deg = angle_deg.front() + 360.0 - angle_deg.back(); closing_deg > 2.0 * largest_step_deg) {
    throw InputError(fmt::format(
        "cam lift table: the angles run from {} to {} deg, leaving {:.4g} deg of the turn without a row (its rows "
        "step by up to {:.4g} deg): a lift table covers one whole turn",
        angle_deg.front(), angle_deg.back(), closing_deg, largest_step_deg));
  }
  return out;
}

std::vector<WheelPathPoint> wheelCentrePath(const std::vector<Eigen::Vector2d>& profile_mm, double wheel_radius_mm,
                                            int samples) {
  if (!(wheel_radius_mm > 0.0)) throw InputError(fmt::format("wheel radius {} mm must be > 0", wheel_radius_mm));
  if (samples < 4) throw InputError("wheel path: at least 4 points");
  std::vector<Eigen::Vector2d> ccw = profile_mm;
  if (signedArea(ccw) < 0.0) std::reverse(ccw.begin(), ccw.end());
  const PeriodicSpline2d spline(ccw);
  std::vector<WheelPathPoint> out;
  for (int k = 0; k < samples; ++k) {
    WheelPathPoint w;
    w.s_mm = spline.period() * k / samples;
    w.profile_mm = spline.at(w.s_mm);
    const Eigen::Vector2d tangent = spline.derivative(w.s_mm).normalized();
    w.normal = Eigen::Vector2d(tangent.y(), -tangent.x());  // outward of a counter-clockwise curve
    const double kappa = spline.curvature(w.s_mm);
    if (kappa < 0.0 && wheel_radius_mm >= 1.0 / -kappa) {
      throw InputError(
          fmt::format("the wheel (radius {} mm) cannot grind the concave flank at {:.2f} deg of the cam: its "
                      "radius of curvature there is {:.2f} mm",
                      wheel_radius_mm, std::atan2(w.profile_mm.y(), w.profile_mm.x()) * 180.0 / kPi, 1.0 / -kappa));
    }
    w.centre_mm = w.profile_mm + wheel_radius_mm * w.normal;
    out.push_back(w);
  }
  return out;
}

namespace {

struct Axes {
  int x = -1, c = -1;
  std::size_t size = 0;
};

Eigen::VectorXd coordinates(const Axes& a, double x_mm, double c_deg) {
  Eigen::VectorXd q = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(a.size));
  q(a.x) = x_mm;
  q(a.c) = c_deg;
  return q;
}

// Solves the ideal constraint P_ideal(x, c) = target in the cam's plane by Newton from (x, c).
// @throws InputError when it does not converge
void idealInverse(const MultibodyModel& m, const Axes& a, const Eigen::Vector2d& target, double& x, double& c) {
  for (int it = 0; it < 60; ++it) {
    const Eigen::Vector2d f = m.idealPoint(coordinates(a, x, c)).head<2>() - target;
    if (f.norm() < 1e-11) return;
    constexpr double kDx = 1e-4, kDc = 1e-4;
    Eigen::Matrix2d j;
    j.col(0) =
        (m.idealPoint(coordinates(a, x + kDx, c)).head<2>() - m.idealPoint(coordinates(a, x - kDx, c)).head<2>()) /
        (2 * kDx);
    j.col(1) =
        (m.idealPoint(coordinates(a, x, c + kDc)).head<2>() - m.idealPoint(coordinates(a, x, c - kDc)).head<2>()) /
        (2 * kDc);
    const Eigen::Vector2d step = j.fullPivLu().solve(-f);
    x += step(0);
    c += step(1);
  }
  throw InputError(
      fmt::format("the wheel centre ({:.4f}, {:.4f}) mm cannot be reached by X and C", target.x(), target.y()));
}

}  // namespace

std::vector<GrindCommand> compensateGrinding(const MultibodyModel& kinematics, const ErrorsAt& errors,
                                             const std::vector<Eigen::Vector2d>& wheel_centre_mm,
                                             const CompensationOptions& options) {
  Axes a;
  const auto& names = kinematics.coordinates();
  a.size = names.size();
  for (std::size_t i = 0; i < names.size(); ++i) {
    if (names[i] == "x") a.x = static_cast<int>(i);
    if (names[i] == "c") a.c = static_cast<int>(i);
  }
  if (a.x < 0 || a.c < 0)
    throw InputError("machine '" + kinematics.name() + "' has no x and c coordinates (a grinder's X slide and C head)");
  if (!(options.resolution_x_um >= kFinestStepXUm && options.resolution_x_um <= kCoarsestStepXUm))
    throw InputError(fmt::format("the X slide's resolution must be {:g}..{:g} um, got {:g}", kFinestStepXUm,
                                 kCoarsestStepXUm, options.resolution_x_um));
  if (!(options.resolution_c_deg >= kFinestStepCDeg && options.resolution_c_deg <= kCoarsestStepCDeg))
    throw InputError(fmt::format("the C axis' resolution must be {:g}..{:g} deg, got {:g}", kFinestStepCDeg,
                                 kCoarsestStepCDeg, options.resolution_c_deg));
  // Which way C turns the cam as seen from the wheel: the angle of the ideal point at c = 90
  // deg against c = 0.
  const double r0 = std::max(1.0, wheel_centre_mm.empty() ? 1.0 : wheel_centre_mm.front().norm());
  const Eigen::Vector2d at0 = kinematics.idealPoint(coordinates(a, r0, 0.0)).head<2>();
  const Eigen::Vector2d at90 = kinematics.idealPoint(coordinates(a, r0, 90.0)).head<2>();
  const double phi0 = std::atan2(at0.y(), at0.x());
  const double sense = cross(at0, at90) > 0.0 ? 1.0 : -1.0;
  std::vector<GrindCommand> out;
  double previous_c = 0.0;
  for (std::size_t i = 0; i < wheel_centre_mm.size(); ++i) {
    const Eigen::Vector2d& w = wheel_centre_mm[i];
    GrindCommand g;
    double x = w.norm();
    double c = sense * (std::atan2(w.y(), w.x()) - phi0) * 180.0 / kPi;
    if (i > 0) c += 360.0 * std::round((previous_c - c) / 360.0);  // continue where the head is
    idealInverse(kinematics, a, w, x, c);
    g.x_ideal_mm = x;
    g.c_ideal_deg = c;
    auto actual = [&](double xx, double cc) {
      const Eigen::VectorXd q = coordinates(a, xx, cc);
      return kinematics.actualPoint(q, errors(q));
    };
    g.error_ideal_um = (actual(x, c).head<2>() - w).norm() * 1000.0;
    // The paper's iteration: errors at the last commands, the ideal constraint solved for the
    // point they displace, until what is left is below the axes' resolution.
    for (g.iterations = 0; g.iterations < options.max_iterations;) {
      const Eigen::VectorXd q = coordinates(a, x, c);
      const Eigen::Vector3d p_actual = actual(x, c);
      const Eigen::Vector2d r = w - p_actual.head<2>();
      const Eigen::Vector2d radial = p_actual.head<2>().normalized();
      const double radial_um = std::abs(r.dot(radial)) * 1000.0;
      const double tangential_um = std::abs(cross(radial, r)) * 1000.0;
      if (radial_um < options.resolution_x_um && tangential_um < x * options.resolution_c_deg * kPi / 180.0 * 1000.0)
        break;
      const Eigen::Vector2d displaced = (p_actual - kinematics.idealPoint(q)).head<2>();
      idealInverse(kinematics, a, w - displaced, x, c);
      ++g.iterations;
    }
    const Eigen::Vector3d final_actual = actual(x, c);
    g.x_mm = x;
    g.c_deg = c;
    g.error_um = (final_actual.head<2>() - w).norm() * 1000.0;
    g.error_z_um = (final_actual.z() - kinematics.idealPoint(coordinates(a, x, c)).z()) * 1000.0;
    if (g.iterations >= options.max_iterations) {
      throw InputError(
          fmt::format("wheel path point {}: the correction did not settle below the resolution in {} iterations "
                      "({:.4f} um left)",
                      i + 1, options.max_iterations, g.error_um));
    }
    previous_c = c;
    out.push_back(g);
  }
  return out;
}

std::string grindingGcode(const std::vector<GrindCommand>& commands, double c_rpm, const std::string& title) {
  if (!(c_rpm >= kSlowestWorkHeadRpm && c_rpm <= kFastestWorkHeadRpm))
    throw InputError(fmt::format("the work head's speed must be {:g}..{:g} rpm, got {:g}", kSlowestWorkHeadRpm,
                                 kFastestWorkHeadRpm, c_rpm));
  std::ostringstream g;
  g << "%\n(" << title << ")\n";
  g << "(corrected X and C commands of mtcal grind compensate; inverse-time feed: the work head at "
    << fmt::format("{}", c_rpm) << " rpm)\n";
  g << "G21 G90\n";
  if (!commands.empty()) g << fmt::format("G0 X{:.5f} C{:.5f}\n", commands.front().x_mm, commands.front().c_deg);
  g << "G93\n";
  for (std::size_t i = 1; i < commands.size(); ++i) {
    const double minutes = std::abs(commands[i].c_deg - commands[i - 1].c_deg) / (360.0 * c_rpm);
    g << fmt::format("G1 X{:.5f} C{:.5f} F{:.3f}\n", commands[i].x_mm, commands[i].c_deg,
                     minutes > 0.0 ? 1.0 / minutes : 1e6);
  }
  if (commands.size() > 1) {
    // The turn closed: back to the first point, one turn on, in the direction C turns.
    const double sense = commands.back().c_deg >= commands.front().c_deg ? 1.0 : -1.0;
    const double c_end = commands.front().c_deg + sense * 360.0;
    const double minutes = std::abs(c_end - commands.back().c_deg) / (360.0 * c_rpm);
    g << fmt::format("G1 X{:.5f} C{:.5f} F{:.3f} (the turn closed)\n", commands.front().x_mm, c_end,
                     minutes > 0.0 ? 1.0 / minutes : 1e6);
  }
  g << "G94\nM30\n%\n";
  return g.str();
}

}  // namespace mtcal::processing
