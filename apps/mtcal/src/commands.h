#pragma once
// One function per command of the mtcal command line. Each returns the exit code and
// writes only to the streams it is given.

#include <atomic>
#include <cstdint>
#include <optional>
#include <istream>
#include <ostream>
#include <string>

#include <nlohmann/json.hpp>

#include "mtcal/services/circle.h"
#include "mtcal/services/diagnose.h"
#include "mtcal/services/gantry.h"
#include "mtcal/services/grind.h"
#include "mtcal/services/linear.h"
#include "mtcal/services/model.h"
#include "mtcal/services/thermal.h"
#include "mtcal/services/version.h"
#include "mtcal/services/workshop.h"

namespace mtcal::app {

struct Globals {
  std::string db = "mtcal.sqlite";
  bool json = false;
  std::ostream* out = nullptr;
  std::ostream* err = nullptr;
  std::istream* in = nullptr;  ///< the operator's answers (real-machine prompts); none: no prompts possible
  const std::atomic<bool>* stop = nullptr;
  bool terminal = false;  ///< stderr is a terminal: draw the progress bar in place
};

using services::kVersion;
using services::readTextFile;
using services::SimulationOptions;

struct RunOptions {
  bool triggered = false;           ///< mock devices: the virtual CNC runs the part program
  std::string machine = "unnamed machine";  ///< real devices: the machine measured
};

int demo(const Globals& g, const SimulationOptions& sim);
int listRuns(const Globals& g);
int showRun(const Globals& g, storage::Id run_id);
int importLinear(const Globals& g, const std::string& path, acquisition::LinearImportOptions options);
int analyzeIso230(const Globals& g, storage::Id run_id);
int airIndex(const Globals& g, const std::string& model, double temp_c, double pressure_pa, double humidity_pct,
             double co2_ppm, double wavelength_nm);
/// Runs plans in one new campaign. Several plans only on mock:// devices in controlled mode
/// (the simulated operator sets up the optics for each); --json then prints one line each.
int runLinear(const Globals& g, const std::vector<std::string>& plan_paths, const std::string& device_uri,
              const SimulationOptions& sim, const RunOptions& run_options);
int resumeRun(const Globals& g, storage::Id run_id, double time_scale);
int planGcode(const Globals& g, const std::string& plan_path, const std::string& output_path, const std::string& machine_file = "");
int listDevices(const Globals& g, const SimulationOptions& sim);
}  // namespace mtcal::app

namespace mtcal::app {

using ModelImportOptions = services::ModelFitRequest;
using services::MachineDescription;
using services::readMachine;

int modelImport(const Globals& g, const ModelImportOptions& options);
/// Identification from stored linear runs (ids, or "cN" for the completed linear runs of
/// campaign N) through the machine's model, by the direct or the 9-line method.
int modelIdentify(const Globals& g, const std::vector<std::string>& sources, const ModelImportOptions& options);
int modelList(const Globals& g);
/// `grid` "X0:X1:N,Y0:Y1:N,Z0:Z1:N" in the model's coordinate order, or `points_csv` with
/// x_mm,y_mm,z_mm; text output is CSV (to `out_csv` when given).
int modelPredict(const Globals& g, storage::Id model, const std::string& grid, const std::string& points_csv,
                 const std::string& out_csv);
/// At `at` ("x,y,z"; the workspace centre when empty); with `sobol_samples` > 0 also the
/// Monte Carlo first-order Sobol indices.
int modelKeyErrors(const Globals& g, storage::Id model, const std::string& at, int sobol_samples);
int modelBands(const Globals& g, storage::Id model, const std::string& plane, const std::string& at, int grid_n);
/// Predicts each run's readings with the model and reports the residuals (RMS, peak); the
/// comparison is stored as a result of the run (processor "model-validation").
int modelValidate(const Globals& g, storage::Id model, const std::vector<storage::Id>& runs);
struct CompensationOptions {
  std::string axis = "X";
  std::optional<double> from_mm, to_mm;  ///< default: the range the model was measured over
  double step_mm = 10.0;
  std::string at;           ///< the other coordinates ("x,y,z"); the workspace centre when empty
  std::string output_path;  ///< CSV here instead of stdout
};
/// The pitch compensation table of one axis for the CNC: the model's positioning reading
/// along the axis per approach direction, with the model's extensions that depend on the
/// position and direction (backlash, cyclic error, scale, Abbe ...), and its negative.
int modelCompensation(const Globals& g, storage::Id model, const CompensationOptions& options);

struct EstOptions {
  std::string csv_path;
  double spacing_mm = 0.0;
  std::string method = "two-probe";        ///< two-probe | three-probe | frequency
  std::string start = "carriage-at-rest";  ///< two-probe: carriage-at-rest | second-point
};
/// Straightness by error separation from x_mm,v1_um,v2_um[,v3_um] (docs/est.md).
int estimateStraightness(const Globals& g, const EstOptions& options);


/// Runs a probe stepping plan (acquisition::EstPlan) on the simulated machine with
/// mock://probes, then prints the two-probe (three-probe with 3 probes) separation.
int runEst(const Globals& g, const std::string& plan_path, const std::string& device_uri, const SimulationOptions& sim);
/// The separation of a stored probe run (docs/est.md), stored as a result of the run.
int analyzeEst(const Globals& g, storage::Id run_id, const EstOptions& options);

/// Circular tests (docs/ballbar.md): a plan on the simulated machine with mock://ballbar,
/// evaluated and diagnosed; circle data from other software; a stored test's ISO 230-4
/// figures and its diagnosis, each stored as a result of the run.
int runBallbar(const Globals& g, const std::string& plan_path, const std::string& device_uri, const SimulationOptions& sim);
int importCircle(const Globals& g, const std::string& path, acquisition::CircleImportOptions options);
int analyzeIso230_4(const Globals& g, storage::Id run_id);
int analyzeBallbar(const Globals& g, storage::Id run_id);

using GrindOptions = services::GrindRequest;
using services::GantryEvaluateOptions;
/// Runs a gantry plan, then evaluates it: on the simulated gantry through mock://tracker, or
/// with a real tracker (tcp://) on a real machine running the plan's NC program, the operator
/// answering prompts (reflector placed, machine in position) on g.in.
int runGantry(const Globals& g, const std::string& plan_path, const std::string& device_uri, const SimulationOptions& sim,
              const GantryEvaluateOptions& evaluate);
int analyzeGantry(const Globals& g, storage::Id run_id, const GantryEvaluateOptions& options);
/// Evaluates an exported measurement file (docs/gantry.md).
int gantryEvaluate(const Globals& g, const std::string& path, const GantryEvaluateOptions& options);
int gantryExport(const Globals& g, storage::Id run_id, const std::string& path);

/// Corrected NC commands for grinding a cam on an X + C grinder (docs/grinding.md).
int grindCompensate(const Globals& g, const GrindOptions& options);
/// One axis' motion errors from ballbar length changes: the layout (JSON: coordinate, pairs of
/// tool-side and workpiece-side balls) and the readings (CSV position,pair,delta_length_um).
int grindIdentify(const Globals& g, const std::string& readings_path, const std::string& machine_path,
                  const std::string& layout_path);

/// Thermal error (docs/thermal.md).
int importThermal(const Globals& g, const std::string& path, acquisition::ThermalImportOptions options);
/// A thermal run as the import's CSV (to stdout for "-").
int exportThermal(const Globals& g, storage::Id run_id, const std::string& path);
using ThermalFitCommandOptions = services::ThermalFitRequest;
struct ThermalRunCommandOptions {
  std::string plan_path;
  storage::Id resume_run = 0;  ///< continue this run (its plan) instead of a new one
  std::string logger_uri = "mock://logger", probes_uri = "mock://probes", interferometer_uri = "mock://interferometer";
  std::string machine = "unnamed machine";  ///< real instruments: the machine measured
};
/// Runs a thermal monitoring plan (docs/thermal.md) on the simulated machine, or with real
/// instruments while the operator runs the spindle program (prompted on g.in).
int runThermal(const Globals& g, const ThermalRunCommandOptions& options, const SimulationOptions& sim);
/// Fits, selects and validates the time-series thermal model of a thermal run; stored as a
/// result of the run (processor "thermal-fit").
int thermalFit(const Globals& g, storage::Id run_id, const ThermalFitCommandOptions& options);

using DiagnoseOptions = services::DiagnoseRequest;
/// Diagnoses a run: residual, evidence, named causes, held-out gain; stored as a result
/// (processor "diagnosis") and, against a model, as a new model version with the extensions.
int diagnoseCommand(const Globals& g, const DiagnoseOptions& options);

}  // namespace mtcal::app
