#pragma once
// The sampling scheduler for a linear positioning plan: drives the machine through the ISO
// 230-2 test cycle, captures each target from the interferometer stream when stable,
// compensates it (air index, NTC to 20 degC) and commits it with its raw samples.
// A run interrupted by the user or by a device error keeps every completed target, is
// marked interrupted and can be resumed.

#include <atomic>
#include <functional>
#include <optional>
#include <set>
#include <string>

#include "mtcal/acquisition/linear_plan.h"
#include "mtcal/drivers/interferometer/driver.h"
#include "mtcal/storage/store.h"

namespace mtcal::acquisition {

/// Moves the machine. For the virtual machine this commands it directly; for a real
/// machine an implementation talks to the CNC.
class MachineController {
 public:
  virtual ~MachineController() = default;
  /// Moves `axis` to `position_mm`; returns when the move command is complete.
  /// @return the instrument-clock time (s) at which the axis is in position, when the
  ///         controller knows it; otherwise the scheduler takes the first sample after the call.
  virtual std::optional<double> moveTo(const std::string& axis, double position_mm) = 0;
};

struct LinearProgress {
  std::size_t done = 0, total = 0;
  double target_mm = 0.0;
  int direction = 1, cycle = 1;
  double deviation_um = 0.0;
};

struct LinearRunOptions {
  std::function<void(const LinearProgress&)> on_progress;
  const std::atomic<bool>* stop_requested = nullptr;  ///< checked between targets
  std::size_t queue_capacity = 1 << 20;               ///< samples
  std::string software_version = "unknown";
};

enum class RunOutcome { kCompleted, kInterrupted };

class LinearRun {
 public:
  LinearRun(storage::Store& store, drivers::interferometer::InterferometerDevice& device,
            MachineController& controller, LinearRunOptions options);

  /// Creates a run in `campaign_id` and executes the plan.
  /// @return the run id; outcome() tells whether it completed or was interrupted.
  /// @throws what the device or storage threw, after marking the run interrupted.
  storage::Id start(const LinearPlan& plan, storage::Id campaign_id, std::optional<storage::Id> instrument_id);

  /// Continues an interrupted run from its stored plan, skipping completed targets.
  /// @throws InputError when the run is not a linear run or is already completed.
  void resume(storage::Id run_id);

  RunOutcome outcome() const { return outcome_; }

 private:
  void execute(storage::Id run_id, const LinearPlan& plan, const std::set<std::int64_t>& done);
  struct Capture;
  Capture capture(const LinearPlan& plan, std::optional<double> in_position_s, const std::string& what);

  storage::Store& store_;
  drivers::interferometer::InterferometerDevice& device_;
  MachineController& controller_;
  LinearRunOptions options_;
  RunOutcome outcome_ = RunOutcome::kCompleted;
  struct Stream;
  Stream* stream_ = nullptr;
};

}  // namespace mtcal::acquisition
