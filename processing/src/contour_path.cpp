#include "mtcal/processing/contour_path.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "mtcal/error.h"

namespace mtcal::processing {

Eigen::Vector3d rotateInPlane(const Eigen::Vector3d& from_mm, const Eigen::Vector3d& centre_mm, Plane plane,
                              double angle_rad) {
  const PlaneAxes a = planeAxes(plane);
  const double u = from_mm(a.first) - centre_mm(a.first), v = from_mm(a.second) - centre_mm(a.second);
  const double c = std::cos(angle_rad), s = std::sin(angle_rad);
  Eigen::Vector3d p = from_mm;
  p(a.first) = centre_mm(a.first) + c * u - s * v;
  p(a.second) = centre_mm(a.second) + s * u + c * v;
  return p;
}

ContourPath::ContourPath(const Eigen::Vector3d& start_mm) : start_mm_(start_mm) {}

void ContourPath::append(PathSegment segment) {
  if (!(segment.feed_mm_per_min > 0.0))
    throw InputError(fmt::format("path segment: feed {} mm/min must be > 0", segment.feed_mm_per_min));
  segment.start_s = durationS();
  segment.duration_s = segment.length_mm / (segment.feed_mm_per_min / 60.0);
  segments_.push_back(segment);
}

ContourPath& ContourPath::lineTo(const Eigen::Vector3d& end_mm, double feed_mm_per_min) {
  PathSegment s;
  s.start_mm = end();
  s.end_mm = end_mm;
  s.feed_mm_per_min = feed_mm_per_min;
  s.length_mm = (end_mm - s.start_mm).norm();
  append(s);
  return *this;
}

ContourPath& ContourPath::arc(const Eigen::Vector3d& centre_mm, Plane plane, double sweep_rad, double feed_mm_per_min) {
  PathSegment s;
  s.arc = true;
  s.start_mm = end();
  s.centre_mm = centre_mm;
  s.plane = plane;
  s.sweep_rad = sweep_rad;
  s.feed_mm_per_min = feed_mm_per_min;
  const PlaneAxes a = planeAxes(plane);
  if (std::abs(s.start_mm(a.normal) - centre_mm(a.normal)) > 1e-9) {
    throw InputError(fmt::format("arc in the {} plane: its centre is {} mm off the start point's plane",
                                 planeName(plane), centre_mm(a.normal) - s.start_mm(a.normal)));
  }
  const double radius =
      std::hypot(s.start_mm(a.first) - centre_mm(a.first), s.start_mm(a.second) - centre_mm(a.second));
  if (!(radius > 1e-9)) throw InputError("arc: the start point is on the centre (radius 0)");
  s.end_mm = rotateInPlane(s.start_mm, centre_mm, plane, sweep_rad);
  s.length_mm = radius * std::abs(sweep_rad);
  append(s);
  return *this;
}

Eigen::Vector3d ContourPath::positionAt(double t_s) const {
  if (segments_.empty() || t_s <= 0.0) return start_mm_;
  auto it = std::upper_bound(segments_.begin(), segments_.end(), t_s,
                             [](double t, const PathSegment& s) { return t < s.start_s; });
  const PathSegment& s = *std::prev(it);
  const double f = s.duration_s > 0.0 ? std::clamp((t_s - s.start_s) / s.duration_s, 0.0, 1.0) : 1.0;
  if (s.arc) return rotateInPlane(s.start_mm, s.centre_mm, s.plane, f * s.sweep_rad);
  return s.start_mm + f * (s.end_mm - s.start_mm);
}

}  // namespace mtcal::processing
