#pragma once
// ISO 230-4 circular tests with a ballbar: the plan (JSON), the tool path and part program it
// makes, the run that streams the bar while the machine interpolates the circle in each
// direction, the import of circle data from other software, and the stored test's points.
//
// Path of one direction (plane axes first/second, angles from first toward second):
//   a feed-in semicircle of diameter feed_in_mm from inside the circle, tangent to it an
//   overshoot before the start angle; the overshoot arc (the servo's transient from the tight
//   feed-in dies out there); the measuring arc (arc_deg, 360 for a full circle); an overshoot
//   arc; a feed-out semicircle back inside. Data of the measuring arc only are kept. CCW starts at
//   start_angle_deg, CW at start_angle_deg + arc_deg, so both cover the same arc.

#include <atomic>
#include <functional>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json_fwd.hpp>

#include "mtcal/acquisition/linear_run.h"
#include "mtcal/acquisition/run_clock.h"
#include "mtcal/drivers/ballbar/driver.h"
#include "mtcal/processing/contour_path.h"
#include "mtcal/processing/iso230_4.h"
#include "mtcal/storage/store.h"

namespace mtcal::acquisition {

struct CirclePlan {
  std::string name = "circle";
  std::string device = "mock://ballbar";
  processing::Plane plane = processing::Plane::kXY;
  double radius_mm = 100.0;                  ///< the bar's length: 50, 100, 150 (or any > 0)
  Eigen::Vector3d centre_mm{350.0, 350.0, 350.0};  ///< machine coordinates of the table ball
  double feed_mm_per_min = 1000.0;
  std::vector<processing::CircleDirection> directions{processing::CircleDirection::kCcw, processing::CircleDirection::kCw};
  double start_angle_deg = 0.0;
  double arc_deg = 360.0;                    ///< < 360: a partial arc (short travel)
  double overshoot_deg = 45.0;                ///< before and after the measuring arc
  double feed_in_mm = 1.5;                   ///< diameter of the feed-in/out semicircles
  std::uint32_t sample_rate_hz = 1000;
  double settle_s = 2.0;                     ///< wait after the moves to the centre before the table ball is set
  /// Zero the bar in its calibrator before the test, at this reference length (its
  /// certificate; the radius when the plan does not say); nullopt (null in the plan): use the
  /// bar as it is (scale figures are then relative).
  std::optional<double> calibrator_length_mm = 100.0;
  std::string gcode_dialect = "iso";          ///< the part program's dialect (only ISO G-code)

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

/// Converts the stored points of a circular test for processing.
std::vector<processing::CirclePoint> toCirclePoints(const std::vector<storage::CirclePointRecord>& records);

struct CircleRunOptions {
  std::string software_version = "unknown";
  /// Called after the bar is zeroed in its calibrator, with the machine at rest at the
  /// circle's centre: the operator sets the table ball there and mounts the bar.
  std::function<void()> mount_bar;
  const std::atomic<bool>* stop_requested = nullptr;  ///< checked between directions
  /// After each direction is stored: directions done, of all, and its points.
  std::function<void(std::size_t done, std::size_t total, std::size_t points)> on_progress;  /// The instruments' time (a simulated world runs in lock step with the run); nullptr: real instruments.
  RunClock* run_clock = nullptr;
};

struct CircleRunResult {
  storage::Id run_id = 0;
  RunOutcome outcome = RunOutcome::kCompleted;
  std::string reason;
  drivers::StreamStats stats;
  std::size_t points = 0;
};

/// Runs the test on a machine whose controller can follow a contour (the virtual machine):
/// one run, each direction committed with its points and raw samples as it completes; an
/// error (device, over range in the measuring arc) marks the run interrupted with the reason
/// and keeps what was committed. @throws InputError when the controller cannot contour
/// (a real CNC: run the part program there; triggered capture of circles is not built yet).
CircleRunResult runCircleTest(storage::Store& store, storage::Id campaign_id, drivers::ballbar::BallbarDevice& bar,
                              MachineController& controller, const CirclePlan& plan, const CircleRunOptions& options);

struct CircleImportOptions {
  double radius_mm = 0.0;
  processing::Plane plane = processing::Plane::kXY;
  double feed_mm_per_min = 1000.0;
  std::string name;
  std::string machine = "imported";
  std::string software_version = "unknown";
};

/// Imports `angle_deg,direction,deviation_um` (optional time_s) into one run, in one
/// transaction. @throws InputError naming the line and column; nothing is stored then.
storage::Id importCircleCsv(storage::Store& store, const std::string& path, const CircleImportOptions& options);

}  // namespace mtcal::acquisition
