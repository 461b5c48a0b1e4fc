#include "mtcal/processing/gantry_accuracy.h"

#include <fmt/format.h>

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <map>
#include <numbers>
#include <random>

#include "mtcal/error.h"

namespace mtcal::processing {
namespace {

constexpr double kUradPerRad = 1e6;

/// A face plane moved from the reflector centres back onto the surface: by the radius
/// against `outward` (the normal is oriented along it).
PlaneFit facePlane(const Points3d& points, const Eigen::Vector3d& outward, double radius_mm, const char* what) {
  PlaneFit plane = fitPlane(points, what);
  if (plane.normal.dot(outward) < 0.0) plane.normal = -plane.normal;
  plane.centroid -= radius_mm * plane.normal;
  return plane;
}

/// A line through tracked points, refitted once without the points farther than 5 times the
/// median distance (for normal noise across the line the median distance is 1.18 sigma: the
/// cut is ~6 sigma) and farther than 5 um. Counts what it left out.
LineFit robustLine(const Points3d& points, const char* what, int& outliers) {
  const LineFit first = fitLine(points, what);
  std::vector<double> d;
  d.reserve(points.size());
  for (const auto& p : points) {
    const Eigen::Vector3d r = p - first.point;
    d.push_back((r - r.dot(first.direction) * first.direction).norm());
  }
  std::vector<double> sorted = d;
  std::nth_element(sorted.begin(), sorted.begin() + static_cast<std::ptrdiff_t>(sorted.size() / 2), sorted.end());
  const double cut = std::max(5.0 * sorted[sorted.size() / 2], 0.005);  // never within 5 um of the line
  Points3d kept;
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (d[i] <= cut) kept.push_back(points[i]);
  }
  if (kept.size() == points.size() || kept.size() < 2) return first;
  outliers += static_cast<int>(points.size() - kept.size());
  return fitLine(kept, what);
}

const BedCorner& originCorner(const GantryMeasurements& m) {
  for (const auto& c : m.corners) {
    if (c.name == m.origin_corner) return c;
  }
  throw InputError(fmt::format("gantry evaluation: the origin corner '{}' was not measured", m.origin_corner));
}

double angleUrad(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b)) * kUradPerRad;
}

}  // namespace

AccuracySummary summarise(const std::vector<HoleResult>& holes, int gantry_position) {
  AccuracySummary s;
  s.gantry_position = gantry_position;
  double norm2 = 0.0, perp2 = 0.0;
  for (const auto& h : holes) {
    if (gantry_position != 0 && h.gantry_position != gantry_position) continue;
    ++s.holes;
    s.mean_dp_um += h.dp_um;
    s.mean_norm_um += h.dp_norm_um;
    s.mean_perp_um += h.dp_perp_um;
    norm2 += h.dp_norm_um * h.dp_norm_um;
    perp2 += h.dp_perp_um * h.dp_perp_um;
    if (h.dp_norm_um >= s.max_norm_um) {
      s.max_norm_um = h.dp_norm_um;
      s.worst_hole = h.id;
    }
    s.max_perp_um = std::max(s.max_perp_um, h.dp_perp_um);
  }
  if (s.holes > 0) {
    const double n = s.holes;
    s.mean_dp_um /= n;
    s.mean_norm_um /= n;
    s.mean_perp_um /= n;
    s.rms_norm_um = std::sqrt(norm2 / n);
    s.rms_perp_um = std::sqrt(perp2 / n);
  }
  return s;
}

namespace {

/// A machine's point error is micrometres, a wrong convention in the file metres: the holes'
/// measured moves against their nominal ones (X and Y mirrored by a pass's wrong direction),
/// or a dP beyond any machine's, are refused with what to check.
void checkPlausible(const GantryEvaluation& ev, const GantryMeasurements& m) {
  constexpr double kLargestDpMm = 5.0;
  double along = 0.0, nominal2 = 0.0;
  const HoleResult* worst = nullptr;
  for (const auto& h : ev.holes) {
    const Eigen::Vector3d moved = h.tcp_mm - ev.tcp0_mm, nominal = h.np_mm - ev.tcp0_mm;
    along += moved.dot(nominal);
    nominal2 += nominal.squaredNorm();
    if (!worst || h.dp_norm_um > worst->dp_norm_um) worst = &h;
  }
  if (nominal2 > 1.0 && along < 0.0) {
    throw InputError(
        "gantry evaluation: the holes moved against their nominal positions (X and Y mirrored): a gantry pass's "
        "\"direction\" is wrong (1 when the gantry moved towards increasing X), or the holes' np_mm are not in the "
        "machine's axes (docs/gantry.md, the measurement file)");
  }
  if (worst && worst->dp_norm_um > kLargestDpMm * 1000.0) {
    throw InputError(fmt::format(
        "gantry evaluation: dP of {:.1f} mm at hole {} is no machine's error: check the file's conventions "
        "(docs/gantry.md): points in the tracker's frame and in mm, the reflector radius ({} mm), each hole's np_mm "
        "the nominal position in the machine's axes, the initial state's targets the same reflectors as each hole's",
        worst->dp_norm_um / 1000.0, worst->id, m.reflector_radius_mm));
  }
}

}  // namespace

GantryEvaluation evaluateGantry(const GantryMeasurements& m, const GantryOptions& options) {
  GantryEvaluation ev;
  // 1. Global frame.
  Points3d tops;
  int top_faces = 0;
  for (const auto& c : m.corners) {
    if (c.top.empty()) continue;
    ++top_faces;
    tops.insert(tops.end(), c.top.begin(), c.top.end());
  }
  if (top_faces < 3) {
    throw InputError(
        fmt::format("gantry evaluation: top faces of {} bed corner(s) measured, at least 3 needed "
                    "(the patent uses all four)",
                    top_faces));
  }
  if (top_faces < 4) ev.notes.push_back(fmt::format("XY plane from {} corners (the patent uses four)", top_faces));
  if (m.gantry_passes.empty()) throw InputError("gantry evaluation: no pass of the gantry was tracked (X axis)");
  Points3d gantry_points;
  for (const auto& pass : m.gantry_passes)
    gantry_points.insert(gantry_points.end(), pass.points.begin(), pass.points.end());
  const Eigen::Vector3d bed_centre = centroid(tops);
  const Eigen::Vector3d up_hint = centroid(gantry_points) - bed_centre;
  ev.xy_plane = fitPlane(tops, "XY plane (tops of the bed corners)");
  if (ev.xy_plane.normal.dot(up_hint) < 0.0) ev.xy_plane.normal = -ev.xy_plane.normal;
  const PlaneFit top = facePlane(tops, up_hint, m.reflector_radius_mm, "XY plane (tops of the bed corners)");
  const Eigen::Vector3d z = top.normal;

  const BedCorner& corner = originCorner(m);
  // A side face is touched from outside its own block: its normal points from the block (the
  // centroid of the block's top, over the block) to the reflector centres on it, whichever way
  // the face looks at the bed's centre.
  if (corner.top.empty()) {
    throw InputError(
        fmt::format("gantry evaluation: the top face of the origin corner {} was not measured (it says "
                    "which side of its side faces the block is)",
                    corner.name));
  }
  const Eigen::Vector3d block = centroid(corner.top);
  const auto sideFace = [&](const Points3d& points, const char* what) {
    if (points.empty()) throw InputError(fmt::format("gantry evaluation: {} was not measured", what));
    const Eigen::Vector3d outward = centroid(points) - block;
    return facePlane(points, outward - outward.dot(z) * z, m.reflector_radius_mm, what);
  };
  const std::string side_1_name = "side face 1 of corner " + corner.name,
                    side_2_name = "side face 2 of corner " + corner.name;
  const PlaneFit side_1 = sideFace(corner.side_1, side_1_name.c_str());
  const PlaneFit side_2 = sideFace(corner.side_2, side_2_name.c_str());
  ev.side_1_rms_um = side_1.rms_mm * 1000.0;
  ev.side_2_rms_um = side_2.rms_mm * 1000.0;
  Eigen::Matrix3d planes;
  planes.row(0) = z.transpose();
  planes.row(1) = side_1.normal.transpose();
  planes.row(2) = side_2.normal.transpose();
  if (std::abs(planes.determinant()) < 0.05) {
    throw InputError(
        fmt::format("gantry evaluation: the side faces of corner {} and the XY plane do not meet in a "
                    "point (determinant {:.3g}; are the side faces perpendicular to each other?)",
                    corner.name, planes.determinant()));
  }
  const Eigen::Vector3d origin = planes.partialPivLu().solve(
      Eigen::Vector3d(z.dot(top.centroid), side_1.normal.dot(side_1.centroid), side_2.normal.dot(side_2.centroid)));

  Eigen::Vector3d direction = Eigen::Vector3d::Zero();
  std::vector<Eigen::Vector3d> pass_directions;
  for (std::size_t i = 0; i < m.gantry_passes.size(); ++i) {
    const auto& pass = m.gantry_passes[i];
    const std::string what = fmt::format("gantry pass {}", i + 1);
    const LineFit line = robustLine(pass.points, what.c_str(), ev.gantry_outliers);
    pass_directions.push_back(pass.direction >= 0 ? line.direction : Eigen::Vector3d(-line.direction));
    direction += pass_directions.back();
    ev.gantry_line_rms_um = std::max(ev.gantry_line_rms_um, line.rms_mm * 1000.0);
  }
  direction.normalize();
  if (ev.gantry_outliers > 0) {
    ev.notes.push_back(
        fmt::format("{} tracked point(s) of the gantry passes left out of the X line as outliers", ev.gantry_outliers));
  }
  for (const auto& d : pass_directions)
    ev.gantry_passes_spread_urad = std::max(ev.gantry_passes_spread_urad, angleUrad(d, direction));
  ev.gantry_tilt_urad = std::asin(std::clamp(direction.dot(z), -1.0, 1.0)) * kUradPerRad;
  const Eigen::Vector3d x = (direction - direction.dot(z) * z).normalized();
  Eigen::Matrix3d axes;
  axes.col(0) = x;
  axes.col(1) = z.cross(x);
  axes.col(2) = z;
  ev.global_from_tracker.linear() = axes.transpose();
  ev.global_from_tracker.translation() = -axes.transpose() * origin;
  const auto toGlobal = [&](const Points3d& points) {
    Points3d g;
    g.reserve(points.size());
    for (const auto& p : points) g.push_back(ev.global_from_tracker * p);
    return g;
  };

  // 2. Rotary axes, wrist centre, TCP0.
  ev.c_axis = fitCircle3d(toGlobal(m.c_sweep), "C axis (target tracked while C turns)");
  if (ev.c_axis.normal.z() < 0.0) ev.c_axis.normal = -ev.c_axis.normal;
  ev.a_axis = fitCircle3d(toGlobal(m.a_sweep), "A axis (target tracked while A turns)");
  if (ev.a_axis.normal.x() < 0.0) ev.a_axis.normal = -ev.a_axis.normal;
  ev.axes = commonPerpendicular(ev.c_axis.centre, ev.c_axis.normal, ev.a_axis.centre, ev.a_axis.normal);
  ev.axes_squareness_urad = (ev.axes.angle_deg - 90.0) * std::numbers::pi / 180.0 * kUradPerRad;
  ev.wrist_centre_mm = ev.axes.on_first;
  if (!(m.tool_length_mm > 0.0)) throw InputError("gantry evaluation: tool_length_mm (L_sp) must be > 0");
  const Eigen::Vector3d tcp0_axes = ev.wrist_centre_mm - m.tool_length_mm * ev.c_axis.normal;
  ev.tcp0_mm = tcp0_axes;
  if (m.tool_point) {
    const Eigen::Vector3d measured = ev.global_from_tracker * *m.tool_point;
    ev.tcp0_axes_minus_tool_point_um = (tcp0_axes - measured) * 1000.0;
    if (ev.tcp0_axes_minus_tool_point_um->norm() > 5.0) {
      ev.notes.push_back(
          fmt::format("TCP0 from the A and C axes is {:.1f} um from the tool-point nest (the axes {:.1f} um apart, "
                      "{:+.1f} urad out of "
                      "square): the construction assumes the tool on the C axis through their intersection; every hole "
                      "with the head "
                      "turned inherits the difference turned with it{}",
                      ev.tcp0_axes_minus_tool_point_um->norm(), ev.axes.distance_mm * 1000.0, ev.axes_squareness_urad,
                      options.tcp0 == Tcp0Source::kAxes ? " (TCP0 from the nest: --tcp0 tool-point)" : ""));
    }
    if (options.tcp0 == Tcp0Source::kToolPoint) ev.tcp0_mm = measured;
  } else if (options.tcp0 == Tcp0Source::kToolPoint) {
    throw InputError("gantry evaluation: TCP0 from the tool point was asked for but no tool point was measured");
  }

  // 3. Targets and holes.
  const Points3d initial = toGlobal(m.initial_targets);
  if (initial.size() < 3) {
    throw InputError(
        fmt::format("gantry evaluation: {} target(s) in the initial state, at least 3 needed", initial.size()));
  }
  TargetFit fit = options.target_fit;
  if (fit == TargetFit::kAuto) fit = initial.size() == 3 ? TargetFit::kPatentFrame : TargetFit::kLeastSquares;
  if (fit == TargetFit::kPatentFrame && initial.size() != 3) {
    throw InputError(
        fmt::format("gantry evaluation: the patent's frame takes exactly 3 targets, {} were measured "
                    "(use the least-squares fit)",
                    initial.size()));
  }
  ev.target_fit = fit == TargetFit::kPatentFrame ? "patent-frame" : "least-squares";
  const double spread = planarSpread(initial);
  if (spread < options.collinear_spread) {
    ev.notes.push_back(
        fmt::format("the targets are nearly collinear (spread {:.3f} < {}): the rotation about their "
                    "line is poorly determined",
                    spread, options.collinear_spread));
  }
  Eigen::Isometry3d m0 = Eigen::Isometry3d::Identity();
  if (fit == TargetFit::kPatentFrame) m0 = frameFromThreePoints(initial[0], initial[1], initial[2]);
  for (const auto& hole : m.holes) {
    if (hole.targets.size() != initial.size()) {
      throw InputError(fmt::format("gantry evaluation: hole {}: {} targets measured, the initial state has {}", hole.id,
                                   hole.targets.size(), initial.size()));
    }
    const Points3d targets = toGlobal(hole.targets);
    HoleResult r;
    r.id = hole.id;
    r.gantry_position = hole.gantry_position;
    Eigen::Isometry3d t;
    if (fit == TargetFit::kPatentFrame) {
      t = frameFromThreePoints(targets[0], targets[1], targets[2]) * m0.inverse();
    } else {
      const RigidFit rigid = rigidFit(initial, targets);
      t = rigid.transform;
      r.fit_rms_um = rigid.rms_mm * 1000.0;
    }
    r.tcp_mm = t * ev.tcp0_mm;
    r.np_mm = ev.tcp0_mm + (hole.np_mm - m.initial_np_mm);
    r.dp_um = (r.tcp_mm - r.np_mm) * 1000.0;
    r.dp_norm_um = r.dp_um.norm();
    const Eigen::Vector3d v = hole.tool_vector.normalized();
    r.dp_perp_um = (r.dp_um - v.dot(r.dp_um) * v).norm();
    ev.holes.push_back(r);
  }
  checkPlausible(ev, m);
  if (!ev.holes.empty()) {
    ev.summaries.push_back(summarise(ev.holes, 0));
    std::map<int, bool> positions;
    for (const auto& h : ev.holes) positions[h.gantry_position] = true;
    for (const auto& [position, unused] : positions) ev.summaries.push_back(summarise(ev.holes, position));
  }
  return ev;
}

namespace {

/// Half-width of the central 95 % interval of the values.
double halfWidth95(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const auto at = [&](double q) {
    const double f = q * static_cast<double>(v.size() - 1);
    const auto k = static_cast<std::size_t>(f);
    const double w = f - static_cast<double>(k);
    return k + 1 < v.size() ? (1.0 - w) * v[k] + w * v[k + 1] : v[k];
  };
  return (at(0.975) - at(0.025)) / 2.0;
}

}  // namespace

GantryUncertainty monteCarloGantry(const GantryMeasurements& m, const GantryOptions& options, const TrackerMpe& mpe,
                                   int trials, std::uint64_t seed) {
  if (trials < 2) throw InputError("gantry uncertainty: at least 2 Monte Carlo trials needed");
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal;
  const std::size_t holes = m.holes.size();
  std::vector<std::vector<Eigen::Vector3d>> dp(holes);
  std::vector<std::vector<double>> norms(holes), perps(holes);
  std::vector<Eigen::Vector3d> tcp0;
  for (int k = 0; k < trials; ++k) {
    GantryMeasurements trial = m;
    forEachPoint(trial, [&](Eigen::Vector3d& p) {
      const double range_m = p.norm() / 1000.0;
      const Eigen::Vector3d radial = p.normalized(), t1 = radial.unitOrthogonal(), t2 = radial.cross(t1);
      const double u_distance_mm = (mpe.distance_um + mpe.distance_um_per_m * range_m) / 2.0 / 1000.0;
      const double u_transverse_mm = (mpe.transverse_um + mpe.transverse_um_per_m * range_m) / 2.0 / 1000.0;
      p += u_distance_mm * normal(rng) * radial + u_transverse_mm * (normal(rng) * t1 + normal(rng) * t2);
    });
    const GantryEvaluation ev = evaluateGantry(trial, options);
    tcp0.push_back(ev.tcp0_mm * 1000.0);
    for (std::size_t h = 0; h < holes; ++h) {
      dp[h].push_back(ev.holes[h].dp_um);
      norms[h].push_back(ev.holes[h].dp_norm_um);
      perps[h].push_back(ev.holes[h].dp_perp_um);
    }
  }
  const auto sigma = [&](const std::vector<Eigen::Vector3d>& v) {
    Eigen::Vector3d mean = Eigen::Vector3d::Zero(), sq = Eigen::Vector3d::Zero();
    for (const auto& x : v) mean += x;
    mean /= static_cast<double>(v.size());
    for (const auto& x : v) sq += (x - mean).cwiseAbs2();
    return Eigen::Vector3d((sq / static_cast<double>(v.size() - 1)).cwiseSqrt());
  };
  GantryUncertainty u;
  u.trials = trials;
  u.tcp0_sigma_um = sigma(tcp0);
  for (std::size_t h = 0; h < holes; ++h) {
    HoleUncertainty hu;
    hu.id = m.holes[h].id;
    hu.dp_sigma_um = sigma(dp[h]);
    hu.norm_u95_um = halfWidth95(norms[h]);
    hu.perp_u95_um = halfWidth95(perps[h]);
    u.max_norm_u95_um = std::max(u.max_norm_u95_um, hu.norm_u95_um);
    u.max_perp_u95_um = std::max(u.max_perp_u95_um, hu.perp_u95_um);
    u.holes.push_back(hu);
  }
  return u;
}

}  // namespace mtcal::processing
