#pragma once
// ISO 230-4 circular tests with a ballbar: the plan (JSON), the tool path it makes and the
// part program written from that path. The run is in circle_run.h, the import of circle data
// from other software and the stored test's points in circle_measurements.h.
//
// Path of one direction (plane axes first/second, angles from first toward second):
//   a feed-in semicircle of diameter feed_in_mm from inside the circle, tangent to it an
//   overshoot before the start angle; the overshoot arc (the servo's transient from the tight
//   feed-in dies out there); the measuring arc (arc_deg, 360 for a full circle); an overshoot
//   arc; a feed-out semicircle back inside. Data of the measuring arc only are kept. CCW starts at
//   start_angle_deg, CW at start_angle_deg + arc_deg, so both cover the same arc.

#include <Eigen/Core>
#include <cstdint>
#include <nlohmann/json_fwd.hpp>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "mtcal/processing/contour_path.h"
#include "mtcal/processing/iso230_4.h"
#include "mtcal/processing/plane.h"

namespace mtcal::acquisition {

/// The least arc a circular test covers: a quarter of the circle (ISO 230-4's partial arcs).
inline constexpr double kLeastArcDeg = 90.0;
/// The feeds a circle is taken at (mm/min): a machine's feed is under 1000 m/min; a value beyond
/// is in other units (um/min), one below 1 mm/min in m/min or no measurement.
inline constexpr double kLeastFeedMmPerMin = 1.0;
inline constexpr double kGreatestFeedMmPerMin = 1e6;

struct CirclePlan {
  std::string name = "circle";
  std::string device = "mock://ballbar";
  processing::Plane plane = processing::Plane::kXY;
  double radius_mm = 100.0;                        ///< the bar's length: 50, 100, 150 (or any > 0)
  Eigen::Vector3d centre_mm{350.0, 350.0, 350.0};  ///< machine coordinates of the table ball
  double feed_mm_per_min = 1000.0;
  std::vector<processing::CircleDirection> directions{processing::CircleDirection::kCcw,
                                                      processing::CircleDirection::kCw};
  double start_angle_deg = 0.0;
  double arc_deg = 360.0;       ///< < 360: a partial arc (short travel)
  double overshoot_deg = 45.0;  ///< before and after the measuring arc
  double feed_in_mm = 1.5;      ///< diameter of the feed-in/out semicircles
  std::uint32_t sample_rate_hz = 1000;
  double settle_s = 2.0;  ///< wait after the moves to the centre before the table ball is set
  /// Zero the bar in its calibrator before the test, at this reference length (its
  /// certificate; the radius when the plan does not say); nullopt (null in the plan): use the
  /// bar as it is (scale figures are then relative).
  std::optional<double> calibrator_length_mm = 100.0;
  std::string gcode_dialect = "iso";  ///< the part program's dialect (only ISO G-code)

  /// Reads and validates a plan. @throws InputError "SOURCE: key: why"
  static CirclePlan fromJson(const nlohmann::json& j, const std::string& source);
  nlohmann::json toJson() const;
};

/// The programmed path of one direction, from the feed-in start to the feed-out end.
processing::ContourPath circlePath(const CirclePlan& plan, processing::CircleDirection direction);
/// Time (s from the path's start) at which the measuring arc starts and its duration.
std::pair<double, double> measuringWindow(const CirclePlan& plan);
/// The programmed angle (rad) at time t of the measuring arc (t from the path's start).
double programmedAngle(const CirclePlan& plan, processing::CircleDirection direction, double t_s);

/// The part program of the whole test (both directions, G17/G18/G19, G2/G3 with centre
/// offsets, the feed), written from the same paths the simulation follows.
std::string circleGcode(const CirclePlan& plan);

}  // namespace mtcal::acquisition
