#pragma once
// A programmed contouring path (lines and circular arcs at a feed), as a part program
// describes it: the one description the circular-test plan writes as G-code, the virtual
// CNC interpolates and the ballbar analysis uses to know where the tool was meant to be at
// each instant. Positions mm, feeds mm/min, times s from the path's start, angles rad.

#include <Eigen/Core>
#include <string>
#include <vector>

#include "mtcal/processing/plane.h"

namespace mtcal::processing {

struct PathSegment {
  bool arc = false;
  Eigen::Vector3d start_mm, end_mm;
  Eigen::Vector3d centre_mm = Eigen::Vector3d::Zero();  ///< arcs
  Plane plane = Plane::kXY;                             ///< arcs
  double sweep_rad = 0.0;  ///< arcs: signed, + counter-clockwise seen from the normal's + end (G3)
  double feed_mm_per_min = 0.0;
  double length_mm = 0.0;
  double start_s = 0.0, duration_s = 0.0;
};

class ContourPath {
 public:
  explicit ContourPath(const Eigen::Vector3d& start_mm);

  /// A straight line to `end_mm` at `feed_mm_per_min` (> 0). @throws InputError
  ContourPath& lineTo(const Eigen::Vector3d& end_mm, double feed_mm_per_min);
  /// An arc about `centre_mm` in `plane`, sweeping `sweep_rad` (may exceed 2 pi) from the
  /// current point, at `feed_mm_per_min`. The centre must lie in the current point's plane.
  /// @throws InputError (zero radius, centre off the plane, feed <= 0)
  ContourPath& arc(const Eigen::Vector3d& centre_mm, Plane plane, double sweep_rad, double feed_mm_per_min);

  const std::vector<PathSegment>& segments() const { return segments_; }
  Eigen::Vector3d start() const { return start_mm_; }
  Eigen::Vector3d end() const { return segments_.empty() ? start_mm_ : segments_.back().end_mm; }
  double durationS() const { return segments_.empty() ? 0.0 : segments_.back().start_s + segments_.back().duration_s; }
  /// Programmed position at time t (clamped to the path's ends).
  Eigen::Vector3d positionAt(double t_s) const;

 private:
  void append(PathSegment segment);
  Eigen::Vector3d start_mm_;
  std::vector<PathSegment> segments_;
};

/// The point of an arc after turning `angle_rad` about its centre from `from_mm`.
Eigen::Vector3d rotateInPlane(const Eigen::Vector3d& from_mm, const Eigen::Vector3d& centre_mm, Plane plane,
                              double angle_rad);

}  // namespace mtcal::processing
