#pragma once
// A gantry point accuracy session on the virtual gantry for tests and studies: the plan run
// through the laser tracker emulator (127.0.0.1) and the real driver into a temporary
// database, the stored measurements loaded back, and the truth: the machine's actual tool
// point (bed frame) captured while it stands at each hole and in the initial state (every
// error of the model, drive errors and the scales' expansion included).

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <functional>
#include <limits>
#include <map>
#include <string>
#include <thread>

#include "mtcal/acquisition/gantry_measurements.h"
#include "mtcal/acquisition/gantry_plan.h"
#include "mtcal/acquisition/gantry_run.h"
#include "mtcal/error.h"
#include "mtcal/mocks/tracker_emulator.h"
#include "mtcal/services/workshop.h"
#include "temp_dir.h"
#include "time_scale.h"

namespace mtcal::testing {

struct GantrySession {
  acquisition::GantryRunResult result;
  processing::GantryMeasurements measured;
  std::map<std::string, Eigen::Vector3d> truth_mm;  // actual tool point (bed frame) at each hole, and "initial"
  Eigen::Isometry3d bed_from_tracker;
  std::vector<acquisition::PlannedHole> holes;
};

/// Runs a plan on the virtual gantry through the tracker emulator and the real driver over
/// TCP, into a temporary database; captures the truth while the machine stands at each place.
/// A CNC that moves the virtual machine but, like a real one running its NC program, does
/// not tell when it is in position.
class SilentController final : public acquisition::MachineController {
 public:
  explicit SilentController(mocks::VirtualMachine& machine) : inner_(machine) {}
  std::optional<double> moveTo(const std::string& axis, double position) override {
    inner_.moveTo(axis, position);
    return std::nullopt;
  }
  std::optional<std::pair<double, double>> followPath(const processing::ContourPath& path) override {
    inner_.followPath(path);
    return std::nullopt;
  }

 private:
  services::VirtualMachineController inner_;
};

/// `operator_confirms`: the controller hides its times (SilentController) and the simulated
/// operator confirms each position once the machine has rested for the plan's settle_s.
inline GantrySession runSession(const acquisition::GantryPlan& plan, const mocks::VirtualMachineConfig& config,
                                mocks::TrackerNoise noise,
                                std::function<void(mocks::TrackerEmulator&, const std::string&)> fault = {},
                                std::uint64_t tracker_seed = 5, double time_scale = 400.0,
                                bool operator_confirms = false) {
  mtcal::testing::TempDir dir;
  storage::Store store((dir.path() / "g.sqlite").string());
  mocks::WorldClock clock(timeScale(time_scale), mocks::WorldClock::Mode::kLockStep);
  services::WorldRunClock run_clock(clock);
  mocks::VirtualMachine machine(config, clock);
  services::VirtualMachineController timed(machine);
  SilentController silent(machine);
  acquisition::MachineController& controller =
      operator_confirms ? static_cast<acquisition::MachineController&>(silent) : timed;
  auto tracker_config = mocks::TrackerEmulatorConfig::forGantry(config, tracker_seed);
  tracker_config.noise = noise;
  mocks::TrackerEmulator emulator(machine, tracker_config);
  auto tracker_device = emulator.connect("mock://tracker");
  drivers::tracker::TrackerDevice& tracker = *tracker_device;
  GantrySession run;
  run.bed_from_tracker = tracker_config.bedFromTracker();
  acquisition::GantryRunOptions options;
  options.environment =
      drivers::tracker::Environment{config.air_temp_c, config.air_pressure_pa / 100.0, config.humidity_pct};
  options.run_clock = &run_clock;
  std::string feature;
  options.on_progress = [&](std::size_t, std::size_t, const std::string& what) { feature = what; };
  options.place_reflector = [&](const std::string& place) {
    emulator.placeReflector(place);
    if (fault) fault(emulator, feature);
    const std::string key = feature.rfind("hole ", 0) == 0 ? feature.substr(5, feature.find(' ', 5) - 5) : feature;
    if (!run.truth_mm.count(key)) run.truth_mm[key] = machine.actualPointMm({0, 0, 0}, clock.nowS());
  };
  if (operator_confirms) {
    // The operator watches the machine until it has done everything commanded (a contour
    // may start up to 0.1 s later than commanded) and rested for settle_s.
    options.confirm_in_position = [&](const std::string&) {
      clock.advanceTo(machine.moveEpoch(std::numeric_limits<double>::max()).second + plan.settle_s);
    };
  }
  const auto kinematics = config.kinematics();
  run.holes = acquisition::planHoles(plan, kinematics);
  const storage::Id campaign = store.addCampaign(store.ensureMachine("gantry", "sim", "{}"), "c");
  run.result = acquisition::runGantryTest(store, campaign, tracker, controller, plan, kinematics, options);
  if (run.result.outcome == acquisition::RunOutcome::kCompleted || run.result.points > 0) {
    try {
      run.measured = acquisition::loadGantryMeasurements(store, run.result.run_id);
    } catch (const InputError&) {  // NOLINT(bugprone-empty-catch): nothing evaluable was stored; the caller checks
    }
  }
  return run;
}

/// The deviation the evaluation should find at a hole: the actual tool point's motion from
/// the initial state, in the evaluation's global frame, minus the programmed motion.
inline Eigen::Vector3d truthUm(const GantrySession& run, const processing::GantryEvaluation& ev,
                               const acquisition::PlannedHole& h, const Eigen::Vector3d& initial_np) {
  const Eigen::Matrix3d global_from_bed = ev.global_from_tracker.linear() * run.bed_from_tracker.inverse().linear();
  return (global_from_bed * (run.truth_mm.at(h.id) - run.truth_mm.at("initial state")) - (h.np_mm - initial_np)) *
         1000.0;
}

}  // namespace mtcal::testing
