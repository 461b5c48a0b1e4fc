#pragma once
// The run of a gantry point accuracy plan (gantry_plan.h): measures the global frame, the
// rotary axes, the targets in the initial state and at every hole with the laser tracker.
//
// A run's measured points are stored as they are taken (each feature in one transaction:
// a face, a pass, a sweep, the targets at one hole); the run's plan is the expanded plan,
// holes with their machine coordinates, programmed tool points and tool vectors, so the
// stored run is evaluated without the machine file (gantry_measurements.h).

#include <atomic>
#include <cstddef>
#include <functional>
#include <optional>
#include <string>

#include "mtcal/acquisition/gantry_plan.h"
#include "mtcal/acquisition/linear_run.h"
#include "mtcal/acquisition/run_clock.h"
#include "mtcal/drivers/tracker/driver.h"
#include "mtcal/processing/multibody.h"
#include "mtcal/storage/store.h"

namespace mtcal::acquisition {

/// What the operator does at the machine: puts the reflector where the run asks for it.
using PlaceReflector = std::function<void(const std::string& place)>;

struct GantryRunOptions {
  std::string software_version = "unknown";
  std::optional<storage::Id> instrument_id;  ///< the tracker in the archive
  PlaceReflector place_reflector;
  /// For a machine whose controller does not report when it is in position (a real CNC
  /// running the plan's NC program): called with what the machine should be doing or where it
  /// should stand; returns when the operator confirms it stands there (throw to stop). The
  /// passes then keep every tracked point (the line's fit does not mind the still ends).
  std::function<void(const std::string& what)> confirm_in_position;
  std::optional<drivers::tracker::Environment> environment;  ///< sent to the tracker (ENV)
  const std::atomic<bool>* stop_requested = nullptr;         ///< checked between features
  /// Called as each feature (a corner face, a pass, a sweep, the initial state, a hole) starts,
  /// with how many of the total are done.
  std::function<void(std::size_t done, std::size_t total, const std::string& what)> on_progress;
  /// The instruments' time (a simulated world runs in lock step with the run); nullptr: real instruments.
  RunClock* run_clock = nullptr;
  /// Continue this interrupted run: the features it stored are kept, the others measured.
  std::optional<storage::Id> resume_run;
};

struct GantryRunResult {
  storage::Id run_id = 0;
  RunOutcome outcome = RunOutcome::kCompleted;
  std::string reason;
  std::size_t points = 0;
};

/// Runs the plan: every feature committed as it completes; an error marks the run
/// interrupted with the reason and keeps what was committed. A controller that reports its
/// in-position times (the virtual machine) is waited for on the tracker's clock; otherwise
/// the operator confirms (options.confirm_in_position; without it the run is interrupted
/// saying so).
GantryRunResult runGantryTest(storage::Store& store, storage::Id campaign_id, drivers::tracker::TrackerDevice& tracker,
                              MachineController& controller, const GantryPlan& plan,
                              const processing::MultibodyModel& kinematics, const GantryRunOptions& options);

}  // namespace mtcal::acquisition
