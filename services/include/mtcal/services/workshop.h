#pragma once
// The workshop a session measures in: the simulated one behind mock:// devices (the virtual
// machine, its controller, its clock in lock step with the runs and a registry that serves
// both the built-in drivers and the mock instruments), or the real one (the built-in drivers
// only, real time).

#include <cstdint>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "mtcal/acquisition/circle_plan.h"
#include "mtcal/acquisition/csv.h"
#include "mtcal/acquisition/linear_run.h"
#include "mtcal/drivers/registry.h"
#include "mtcal/mocks/simulation.h"
#include "mtcal/processing/number_text.h"
#include "mtcal/storage/store.h"

namespace mtcal::services {

/// Drives the virtual machine; in-position times are on the world clock, which is also the
/// mock instrument's device clock.
class VirtualMachineController final : public acquisition::MachineController {
 public:
  explicit VirtualMachineController(mocks::VirtualMachine& machine) : machine_(machine) {}
  /// X, Y, Z (mm) or a rotary axis A, B, C (deg) of the machine's kinematics.
  std::optional<double> moveTo(const std::string& axis, double position) override {
    if (axis == "A" || axis == "B" || axis == "C") {
      return machine_.rotateTo(std::string(1, static_cast<char>(axis[0] - 'A' + 'a')), position);
    }
    return machine_.moveTo(mocks::parseAxis(axis), position);
  }
  std::optional<std::pair<double, double>> followPath(const processing::ContourPath& path) override {
    return machine_.followPath(path);
  }

 private:
  mocks::VirtualMachine& machine_;
};

/// The simulated world's time as a run sees it: in lock step, the world runs where the run
/// asks and holds there; free-running, like real instruments, it runs by itself.
class WorldRunClock final : public acquisition::RunClock {
 public:
  explicit WorldRunClock(mocks::WorldClock& clock) : clock_(clock) {}
  void advanceTo(double device_time_s) override;
  std::optional<double> nowS() const override;

 private:
  mocks::WorldClock& clock_;
};

struct Simulation {
  /// In lock step (the default) the world runs as far as the runs ask (run_clock); free-
  /// running, it streams in real time by itself (a recording of a stream for a wall-clock
  /// duration).
  Simulation(mocks::VirtualMachineConfig machine, mocks::InterferometerEmulatorConfig interferometer, double time_scale,
             mocks::WorldClock::Mode mode = mocks::WorldClock::Mode::kLockStep);
  /// What the operator does before a plan: aligns the beam with the plan's axis, mounts the
  /// optics for the error it measures, places the moving optic at its reflector offset.
  void setUpFor(const acquisition::LinearPlan& plan);
  /// Before a circular test: the ballbar, fitted to the plan's radius, lies in its
  /// calibrator (the run zeroes it there, then the operator mounts it at the circle's centre).
  void setUpFor(const acquisition::CirclePlan& plan);
  mocks::SimulatedWorld world;
  VirtualMachineController controller;
  WorldRunClock run_clock{world.clock};
  drivers::Registry registry;
};

/// The emulated laser interferometer of the simulations (noise 0.02 um).
mocks::InterferometerEmulatorConfig demoInterferometer();

/// Which simulated machine, how fast its world runs.
/// A compensation table file a simulated machine's controller runs.
struct ControllerTable {
  std::string axis;  ///< X, Y or Z
  std::string path;
  std::string controller;  ///< its format (processing::controllerNames())
};

struct SimulationOptions {
  /// Of the demo machine (1 when none); with a machine file it replaces the file's seed.
  std::optional<std::uint64_t> seed;
  double time_scale = 50.0;  ///< world seconds per wall second, at most (lock step)
  std::string machine_file;  ///< virtual machine description (JSON); demo machine when empty
  /// Tables the virtual CNC applies (run linear --compensation [AXIS=]FILE --controller NAME);
  /// they replace the machine file's (its key "compensation") for their axis.
  std::vector<ControllerTable> compensation;
  /// The run kind stores the tables its controller runs (linear runs); others refuse a machine
  /// file that names tables rather than run them unrecorded.
  bool records_tables = false;
};

/// Before anything moves: `what` (a plan's move, a hole) needs `axis` at `position_mm`.
/// @throws InputError "WHAT needs X at P mm, outside the machine's travel [MIN, MAX] mm"
void requireInTravel(const mocks::VirtualMachineConfig& machine, mocks::Axis axis, double position_mm,
                     const std::string& what);

/// The virtual machine a simulation runs, as its runs' machine is stored.
struct SimulatedMachine {
  mocks::VirtualMachineConfig config;
  std::string file_json;       ///< the machine file's description (with the seed given); empty: the demo machine
  bool seed_replaced = false;  ///< --seed replaced the file's seed: another machine in the archive
  /// The controller's tables (storage::NewRun::compensation_json): stored with each run, not
  /// with the machine (the same machine runs with and without them).
  std::string compensation_json = "{}";
  /// In the machines table: the file's name, or the demo machine with its seed.
  std::string name() const;
  /// {"simulation": {"demo_seed": N}} or {"simulation": <the machine file>}: what a resumed run
  /// rebuilds its virtual machine from (simulationFromDescription).
  std::string description() const;
};
/// The demo machine of the seed, or the machine file. @throws InputError naming the file
SimulatedMachine simulatedMachine(const SimulationOptions& options);
/// A new campaign on the simulated machine (stored once by its name).
storage::Id simulatedCampaign(storage::Store& store, const SimulatedMachine& machine, const std::string& campaign_name);
/// A machine's kinematics from a kinematic description (*.model.json) or from a machine file.
/// @throws InputError naming the file
processing::MultibodyModel machineKinematics(const std::string& path);
/// A new campaign on a real machine, known by the name the operator gives it.
storage::Id realCampaign(storage::Store& store, const std::string& machine_name, const std::string& campaign_name);
/// A number rounded to its decimals, never "-0.00" (processing/number_text.h): a document's value
/// without the binary conversion's noise (0.236, not 0.23600000000000002), a table's for people.
using processing::roundedTo;
/// The whole text of a file. @throws InputError naming the file when it cannot be read
std::string readTextFile(const std::string& path);
/// Writes a whole file: into PATH.part, renamed to PATH once complete (a failed write leaves
/// no half-written PATH). @throws InputError naming the file and why
void writeTextFile(const std::string& path, const std::string& text);
/// Writes whole files together: each into PATH.part, all renamed once all are complete (one
/// that cannot be written leaves none of them; a folder or a file named twice is refused
/// first). @throws InputError naming the file and why
void writeTextFiles(const std::vector<std::pair<std::string, std::string>>& path_and_text);
/// A JSON file. @throws InputError naming the file when it cannot be read or is not JSON (where)
using acquisition::readJsonFile;

/// The virtual machine of a stored machine description; none for a real machine.
/// @throws InputError when the description is damaged
std::optional<mocks::VirtualMachineConfig> simulationFromDescription(const std::string& config_json);

/// Where a stored run was measured, to continue it: the run, its instruments (with their
/// roles and URIs) and its machine.
struct StoredRig {
  storage::RunInfo run;
  std::vector<storage::RunInstrument> instruments;
  std::optional<mocks::VirtualMachineConfig> simulation;  ///< none: a real machine
  /// The URI of the run's instrument in `role`. @throws InputError when it has none
  std::string uriOf(const std::string& role) const;
};
/// @throws InputError when the run was imported or is completed (nothing to resume)
StoredRig storedRig(storage::Store& store, storage::Id run_id);

}  // namespace mtcal::services
