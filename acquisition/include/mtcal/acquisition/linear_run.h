#pragma once
// The sampling scheduler for a linear positioning plan: drives the machine through the ISO
// 230-2 test cycle, captures each target from the interferometer stream when stable,
// compensates it (air index, NTC to 20 degC) and commits it with its raw samples.
// A run interrupted by the user or by a device error keeps every completed target, is
// marked interrupted and can be resumed.

#include <atomic>
#include <functional>
#include <map>
#include <optional>
#include <set>
#include <string>

#include "mtcal/acquisition/capture.h"
#include "mtcal/acquisition/linear_plan.h"
#include "mtcal/acquisition/run_clock.h"
#include "mtcal/drivers/interferometer/driver.h"
#include "mtcal/processing/contour_path.h"
#include "mtcal/storage/store.h"

namespace mtcal::acquisition {

/// Moves the machine. For the virtual machine this commands it directly; for a real
/// machine an implementation talks to the CNC.
class MachineController {
 public:
  virtual ~MachineController() = default;
  /// Moves `axis` to `position`: mm for X, Y, Z; degrees for A, B, C. Returns when the move
  /// command is complete.
  /// @return the instrument-clock time (s) at which the axis is in position, when the
  ///         controller knows it; otherwise the scheduler takes the first sample after the call.
  virtual std::optional<double> moveTo(const std::string& axis, double position) = 0;
  /// Follows a contouring path from where the axes are. @return the instrument-clock times
  /// at which the path starts and at which the machine is settled at its end; nullopt when
  /// this controller cannot command contours (a real CNC runs the part program itself).
  virtual std::optional<std::pair<double, double>> followPath(const processing::ContourPath& /*path*/) {
    return std::nullopt;
  }
};

/// The moves to a plan's measured line (the other axes' positions), issued together.
struct LineArrival {
  bool time_known = true;          ///< every move reported its in-position time
  std::optional<double> latest_s;  ///< the latest of them
  /// When the machine is in position after a further move that ends at `in_position_s`:
  /// the later of the two, or unknown when either is.
  std::optional<double> laterOf(std::optional<double> in_position_s) const;
};
LineArrival moveToLine(MachineController& controller, const std::map<std::string, double>& line_position_mm);

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
  /// The compensation tables the controller applies while the run measures (storage::NewRun's).
  std::string compensation_json = "{}";
  /// Triggered runs: called once the stream runs and mtcal waits for the part program to
  /// bring the machine to the datum (the moment to press cycle start).
  std::function<void()> on_waiting_for_program;
  /// The instruments' time (a simulated world runs in lock step with the run); nullptr: real instruments.
  RunClock* run_clock = nullptr;
};

enum class RunOutcome { kCompleted, kInterrupted };

class LinearRun {
 public:
  /// @param controller moves the machine; nullptr when the machine runs the plan's part
  ///        program by itself (a real CNC): each target is then captured when the reading
  ///        holds still within triggerToleranceMm() of it, in the order of the plan.
  LinearRun(storage::Store& store, drivers::interferometer::InterferometerDevice& device, MachineController* controller,
            LinearRunOptions options);

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
  enum class Verdict { kAccept, kSlide };
  using Judge = std::function<Verdict(const WindowStats&, std::span<const drivers::Sample>)>;
  /// Slides an averaging window (by half a window) over the stream from `from_ns` on (or from
  /// the first sample that arrives plus `delay_ns`) until `judge` accepts one; once the
  /// windows pass `timeout_s`, on_timeout(last stats) throws.
  Capture slide(const LinearPlan& plan, std::optional<std::int64_t> from_ns, std::int64_t delay_ns, double timeout_s,
                const Judge& judge, const std::function<void(const WindowStats&)>& on_timeout);
  /// The stable window after the dwell that follows `in_position_s` (unknown: from now).
  Capture capture(const LinearPlan& plan, std::optional<double> in_position_s, const std::string& what);
  /// Triggered mode: waits until the machine has moved (left `previous_raw_mm`, or at least
  /// shown an unsteady reading) and then holds still at `target_mm` (anywhere when empty)
  /// for a whole dwell. @return when the hold began (device time, s) and the raw reading held.
  struct Arrival {
    double time_s = 0.0;
    double raw_mm = 0.0;
  };
  Arrival waitForArrival(const LinearPlan& plan, std::optional<double> target_mm, double datum_raw_mm,
                         std::optional<double> previous_raw_mm, const std::string& what);
  /// Triggered mode: the capture after an arrival, refused when the machine has left the
  /// position whose hold was seen (mtcal fell behind the program).
  Capture captureHeld(const LinearPlan& plan, const Arrival& arrival, const std::string& what);

  storage::Store& store_;
  drivers::interferometer::InterferometerDevice& device_;
  MachineController* controller_;
  LinearRunOptions options_;
  RunClock& clock_;
  RunOutcome outcome_ = RunOutcome::kCompleted;
  struct Stream;
  Stream* stream_ = nullptr;
  double reading_to_um_ = 1000.0;  ///< 1000 for readings in mm, 1 for angles in urad
};

}  // namespace mtcal::acquisition
