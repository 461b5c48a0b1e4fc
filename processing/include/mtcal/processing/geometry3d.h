#pragma once
// Fits of 3D features to measured points (a laser tracker's coordinates, mm): plane and line
// by SVD (orthogonal least squares), a circle in space (its plane by SVD, then the
// geometric circle fit in that plane), the common perpendicular of two lines, a frame from
// three points, and the least-squares rigid motion between two point sets (Umeyama 1991).

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <vector>

namespace mtcal::processing {

using Points3d = std::vector<Eigen::Vector3d>;

/// Mean of the points. @throws nothing; the points must not be empty.
Eigen::Vector3d centroid(const Points3d& points);

struct PlaneFit {
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();  ///< unit; sign as the SVD gives it unless oriented
  double rms_mm = 0.0, max_abs_mm = 0.0;              ///< of the signed distances to the plane
  /// Signed distance of a point (mm, + on the normal's side).
  double distance(const Eigen::Vector3d& p) const { return normal.dot(p - centroid); }
};
/// @throws InputError with fewer than 3 points or points on a line (`what` names them).
PlaneFit fitPlane(const Points3d& points, const char* what = "plane fit");

struct LineFit {
  Eigen::Vector3d point = Eigen::Vector3d::Zero();       ///< the centroid
  Eigen::Vector3d direction = Eigen::Vector3d::UnitX();  ///< unit, from the first point towards the last
  double rms_mm = 0.0, max_mm = 0.0;                     ///< of the distances to the line
};
/// @throws InputError with fewer than 2 distinct points.
LineFit fitLine(const Points3d& points, const char* what = "line fit");

struct Circle3dFit {
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();  ///< unit; the rotation of the points about it is positive
  double radius_mm = 0.0;
  double radial_rms_mm = 0.0;  ///< in-plane distances to the circle
  double plane_rms_mm = 0.0;   ///< distances to the circle's plane
  double arc_deg = 0.0;        ///< angle the points span (first to last, unwrapped)
};
/// Points in the order they were taken along the arc (at least 3, spanning > 0).
/// @throws InputError
Circle3dFit fitCircle3d(const Points3d& points, const char* what = "circle fit");

struct CommonPerpendicular {
  Eigen::Vector3d on_first = Eigen::Vector3d::Zero(), on_second = Eigen::Vector3d::Zero();  ///< feet
  double distance_mm = 0.0;                                                                 ///< |on_second - on_first|
  double angle_deg = 0.0;  ///< between the lines' directions, 0..180
};
/// Lines p1 + s d1 and p2 + t d2. @throws InputError when they are parallel.
CommonPerpendicular commonPerpendicular(const Eigen::Vector3d& p1, const Eigen::Vector3d& d1, const Eigen::Vector3d& p2,
                                        const Eigen::Vector3d& d2);

/// The patent's frame on three points: origin a, X towards b, Z normal to the plane of a, b,
/// c (on the side of (b-a) x (c-a)), Y = Z x X. As the transform from that frame to the
/// points' frame. @throws InputError when the points are (nearly) collinear.
Eigen::Isometry3d frameFromThreePoints(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c);

struct RigidFit {
  Eigen::Isometry3d transform = Eigen::Isometry3d::Identity();  ///< to = transform * from
  std::vector<double> residuals_mm;                             ///< |transform * from_i - to_i|
  double rms_mm = 0.0;
};
/// Least-squares rigid motion (rotation + translation, no scale) from `from` to `to`,
/// Eigen::umeyama. @throws InputError for fewer than 3 pairs, unequal sizes, collinear points.
RigidFit rigidFit(const Points3d& from, const Points3d& to);

/// How far a point set is from a line: the second singular value of the centred points over
/// the first (0 on a line, 1 for an isotropic spread in a plane).
double planarSpread(const Points3d& points);

}  // namespace mtcal::processing
