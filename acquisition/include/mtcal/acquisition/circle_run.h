#pragma once
// The run of an ISO 230-4 circular test (circle_plan.h): streams the ballbar while the
// machine interpolates the circle in each direction and stores the measuring arc's points.

#include <atomic>
#include <cstddef>
#include <functional>
#include <optional>
#include <string>

#include "mtcal/acquisition/circle_plan.h"
#include "mtcal/acquisition/linear_run.h"
#include "mtcal/acquisition/run_clock.h"
#include "mtcal/drivers/ballbar/driver.h"
#include "mtcal/storage/store.h"

namespace mtcal::acquisition {

struct CircleRunOptions {
  std::string software_version = "unknown";
  /// Called after the bar is zeroed in its calibrator, with the machine at rest at the
  /// circle's centre: the operator sets the table ball there and mounts the bar.
  std::function<void()> mount_bar;
  const std::atomic<bool>* stop_requested = nullptr;  ///< checked between directions
  /// Before the first direction is measured (done: the directions stored before, points 0) and
  /// after each direction is stored: directions done, of all, and the direction's points.
  std::function<void(std::size_t done, std::size_t total, std::size_t points)> on_progress;
  /// The instruments' time (a simulated world runs in lock step with the run); nullptr: real instruments.
  RunClock* run_clock = nullptr;
  /// Continue this interrupted test: the directions it stored are kept, the others measured
  /// (the bar is zeroed and mounted again).
  std::optional<storage::Id> resume_run;
  /// A real machine: called once the bar streams, when the operator is to start the part
  /// program (`mtcal plan gcode`): cycle start.
  std::function<void()> on_waiting_for_program;
  /// A real machine: how long after cycle start the first feed-in may come (s of device time).
  double program_start_timeout_s = 600.0;
};

struct CircleRunResult {
  storage::Id run_id = 0;
  RunOutcome outcome = RunOutcome::kCompleted;
  std::string reason;
  drivers::StreamStats stats;
  std::size_t points = 0;  ///< all the run's points (a resumed run's earlier ones included)
};

/// Runs (or resumes, options.resume_run) the test on a machine whose controller can follow a contour (the virtual
/// machine): one run, each direction committed with its points and raw samples as it completes; an error (device, over
/// range in the measuring arc) marks the run interrupted with the reason and keeps what was committed. @throws
/// InputError when the controller cannot contour (a real CNC: run the part program there; triggered capture of circles
/// is not built yet).
CircleRunResult runCircleTest(storage::Store& store, storage::Id campaign_id, drivers::ballbar::BallbarDevice& bar,
                              MachineController& controller, const CirclePlan& plan, const CircleRunOptions& options);

/// Runs the test on a machine that runs the plan's part program by itself (a real CNC, or the
/// virtual one rehearsing it): the bar streams from cycle start; each direction is found in the
/// stream by its feed-in and feed-out, as the ballbar vendors' software does it: the bar reads
/// the feed-in semicircle (radius half the plan's feed-in) pass the length it has at its middle,
/// sqrt((R - f/2)^2 + (f/2)^2), on the way out to the circle and again on the way back in. The
/// two crossings (interpolated between samples) time the path; their interval must be the
/// plan's at its feed (within 1 %: a feed override or another plan is refused); the measuring
/// arc's samples get their angle from that timing, the overshoot left out. Directions are
/// stored as they complete, as runCircleTest does. The plan is stored with `"capture":
/// "part program"` and the crossings in the run's events.
CircleRunResult runTriggeredCircleTest(storage::Store& store, storage::Id campaign_id,
                                       drivers::ballbar::BallbarDevice& bar, const CirclePlan& plan,
                                       const CircleRunOptions& options);

}  // namespace mtcal::acquisition
