#include "mtcal/processing/geometry3d.h"

#include <fmt/format.h>

#include <Eigen/SVD>
#include <cmath>
#include <numbers>

#include "mtcal/error.h"
#include "mtcal/processing/iso230_4.h"

namespace mtcal::processing {
namespace {

/// SVD of the centred points: singular values (descending) and right singular vectors.
Eigen::JacobiSVD<Eigen::MatrixXd> centredSvd(const Points3d& points, const Eigen::Vector3d& centroid) {
  Eigen::MatrixXd a(static_cast<Eigen::Index>(points.size()), 3);
  for (std::size_t i = 0; i < points.size(); ++i)
    a.row(static_cast<Eigen::Index>(i)) = (points[i] - centroid).transpose();
  return Eigen::JacobiSVD<Eigen::MatrixXd>(a, Eigen::ComputeThinV);
}

}  // namespace

Eigen::Vector3d centroid(const Points3d& points) {
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (const auto& p : points) c += p;
  return c / static_cast<double>(points.size());
}

PlaneFit fitPlane(const Points3d& points, const char* what) {
  if (points.size() < 3) throw InputError(fmt::format("{}: {} point(s), at least 3 needed", what, points.size()));
  PlaneFit fit;
  fit.centroid = centroid(points);
  const auto svd = centredSvd(points, fit.centroid);
  const Eigen::VectorXd sv = svd.singularValues();
  if (sv.size() < 3 || sv(1) <= 1e-9 * std::max(1.0, sv(0))) {
    throw InputError(fmt::format("{}: the {} points lie on a line, they do not define a plane", what, points.size()));
  }
  fit.normal = svd.matrixV().col(2).normalized();
  double sum = 0.0;
  for (const auto& p : points) {
    const double d = fit.distance(p);
    sum += d * d;
    fit.max_abs_mm = std::max(fit.max_abs_mm, std::abs(d));
  }
  fit.rms_mm = std::sqrt(sum / static_cast<double>(points.size()));
  return fit;
}

LineFit fitLine(const Points3d& points, const char* what) {
  if (points.size() < 2) throw InputError(fmt::format("{}: {} point(s), at least 2 needed", what, points.size()));
  LineFit fit;
  fit.point = centroid(points);
  const auto svd = centredSvd(points, fit.point);
  if (svd.singularValues()(0) <= 1e-9) throw InputError(fmt::format("{}: the points coincide", what));
  fit.direction = svd.matrixV().col(0).normalized();
  if (fit.direction.dot(points.back() - points.front()) < 0.0) fit.direction = -fit.direction;
  double sum = 0.0;
  for (const auto& p : points) {
    const Eigen::Vector3d r = p - fit.point;
    const double d = (r - r.dot(fit.direction) * fit.direction).norm();
    sum += d * d;
    fit.max_mm = std::max(fit.max_mm, d);
  }
  fit.rms_mm = std::sqrt(sum / static_cast<double>(points.size()));
  return fit;
}

Circle3dFit fitCircle3d(const Points3d& points, const char* what) {
  const PlaneFit plane = fitPlane(points, what);
  // In-plane basis: u towards the first point, v = n x u.
  Eigen::Vector3d u = points.front() - plane.centroid;
  u -= u.dot(plane.normal) * plane.normal;
  if (u.norm() < 1e-12) u = plane.normal.unitOrthogonal();
  u.normalize();
  const Eigen::Vector3d v = plane.normal.cross(u);
  std::vector<Eigen::Vector2d> in_plane;
  in_plane.reserve(points.size());
  for (const auto& p : points) in_plane.emplace_back(u.dot(p - plane.centroid), v.dot(p - plane.centroid));
  CircleFit circle;
  try {
    circle = fitCircle(in_plane);
  } catch (const InputError& e) {
    throw InputError(fmt::format("{}: {}", what, e.what()));
  }
  Circle3dFit fit;
  fit.centre = plane.centroid + circle.centre.x() * u + circle.centre.y() * v;
  fit.radius_mm = circle.radius;
  fit.radial_rms_mm = circle.rms_residual;
  fit.plane_rms_mm = plane.rms_mm;
  // Unwrapped angle swept from the first point to the last, about +normal.
  double swept = 0.0, previous = 0.0;
  for (std::size_t i = 0; i < in_plane.size(); ++i) {
    const Eigen::Vector2d r = in_plane[i] - circle.centre;
    const double angle = std::atan2(r.y(), r.x());
    if (i > 0) swept += std::remainder(angle - previous, 2.0 * std::numbers::pi);
    previous = angle;
  }
  fit.normal = swept >= 0.0 ? plane.normal : Eigen::Vector3d(-plane.normal);
  fit.arc_deg = std::abs(swept) * 180.0 / std::numbers::pi;
  if (fit.arc_deg < 1e-6) throw InputError(fmt::format("{}: the points do not move along an arc", what));
  return fit;
}

CommonPerpendicular commonPerpendicular(const Eigen::Vector3d& p1, const Eigen::Vector3d& d1, const Eigen::Vector3d& p2,
                                        const Eigen::Vector3d& d2) {
  const Eigen::Vector3d u = d1.normalized(), v = d2.normalized();
  const double b = u.dot(v), denominator = 1.0 - b * b;
  if (denominator < 1e-12) throw InputError("common perpendicular: the two lines are parallel");
  const Eigen::Vector3d w = p1 - p2;
  const double d = u.dot(w), e = v.dot(w);
  const double s = (b * e - d) / denominator, t = (e - b * d) / denominator;
  CommonPerpendicular c;
  c.on_first = p1 + s * u;
  c.on_second = p2 + t * v;
  c.distance_mm = (c.on_second - c.on_first).norm();
  c.angle_deg = std::acos(std::clamp(b, -1.0, 1.0)) * 180.0 / std::numbers::pi;
  return c;
}

Eigen::Isometry3d frameFromThreePoints(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  const Eigen::Vector3d x = b - a, normal = x.cross(c - a);
  if (x.norm() < 1e-9 || normal.norm() < 1e-9 * x.norm() * std::max(1.0, (c - a).norm())) {
    throw InputError("frame from three points: the points are collinear or coincide");
  }
  Eigen::Matrix3d r;
  r.col(0) = x.normalized();
  r.col(2) = normal.normalized();
  r.col(1) = r.col(2).cross(r.col(0));
  Eigen::Isometry3d m = Eigen::Isometry3d::Identity();
  m.linear() = r;
  m.translation() = a;
  return m;
}

RigidFit rigidFit(const Points3d& from, const Points3d& to) {
  if (from.size() != to.size()) {
    throw InputError(fmt::format("rigid fit: {} reference points but {} measured", from.size(), to.size()));
  }
  if (from.size() < 3) throw InputError(fmt::format("rigid fit: {} point pair(s), at least 3 needed", from.size()));
  if (planarSpread(from) < 1e-9) throw InputError("rigid fit: the reference points are collinear");
  Eigen::Matrix3Xd src(3, static_cast<Eigen::Index>(from.size())), dst(3, static_cast<Eigen::Index>(to.size()));
  for (std::size_t i = 0; i < from.size(); ++i) {
    src.col(static_cast<Eigen::Index>(i)) = from[i];
    dst.col(static_cast<Eigen::Index>(i)) = to[i];
  }
  RigidFit fit;
  fit.transform = Eigen::Isometry3d(Eigen::umeyama(src, dst, false));
  double sum = 0.0;
  for (std::size_t i = 0; i < from.size(); ++i) {
    fit.residuals_mm.push_back((fit.transform * from[i] - to[i]).norm());
    sum += fit.residuals_mm.back() * fit.residuals_mm.back();
  }
  fit.rms_mm = std::sqrt(sum / static_cast<double>(from.size()));
  return fit;
}

double planarSpread(const Points3d& points) {
  if (points.size() < 2) return 0.0;
  const auto svd = centredSvd(points, centroid(points));
  const Eigen::VectorXd sv = svd.singularValues();
  if (sv(0) <= 0.0 || sv.size() < 2) return 0.0;
  return sv(1) / sv(0);
}

}  // namespace mtcal::processing
