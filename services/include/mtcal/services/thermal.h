#pragma once
// Thermal error (docs/thermal.md): a monitoring plan run on the simulated machine or with
// real instruments, logger data from other software in and out, and the time-series model
// with sensor selection fitted, validated and stored.

#include <nlohmann/json.hpp>
#include <optional>
#include <ostream>
#include <string>
#include <vector>

#include "mtcal/acquisition/thermal_data.h"
#include "mtcal/acquisition/thermal_run.h"
#include "mtcal/processing/thermal_model.h"
#include "mtcal/services/session.h"
#include "mtcal/services/workshop.h"

namespace mtcal::services {

struct ThermalImport {
  storage::Id run_id = 0;
  std::vector<storage::ThermalChannel> channels;
  std::size_t samples = 0, missing_values = 0;
  std::vector<std::string> warnings;  ///< the same file imported before
  nlohmann::json document() const;
};
/// @throws InputError naming the line and column; nothing is stored then
ThermalImport importThermal(Session& session, const std::string& path, acquisition::ThermalImportOptions options);
/// A thermal run as the import's CSV.
void exportThermal(Session& session, storage::Id run_id, std::ostream& out);

struct ThermalFitRequest {
  std::string target;  ///< the displacement channel
  double train_fraction = 0.6;
  double validation_fraction = 0.25;  ///< of the training rows: the last part, which compares the models
  int max_sensors = 4;
  std::string normalisation = "range";
  double rho = 0.5;
  double accuracy_um = 0.0;      ///< > 0: the fewest sensors reaching it on the test part
  bool with_speed = false;       ///< the spindle speed channels are inputs too
  std::string predictions_path;  ///< CSV of the chosen model's predictions, when given
};

/// The fewest sensors of either selection path whose test RMS reaches an accuracy.
struct SensorsNeeded {
  double accuracy_um = 0.0;
  std::string method;
  std::vector<std::string> sensors;
  double rms_test_um = 0.0;
};

/// A fitted thermal model (processor "thermal-fit").
struct ThermalFitAnalysis {
  storage::Id run_id = 0, result_id = 0;
  ThermalFitRequest request;
  processing::ThermalFitResult fit;
  std::optional<SensorsNeeded> needed;  ///< when an accuracy was asked and a candidate reaches it
  nlohmann::json document() const;
};
/// Fits, selects and validates the model of a thermal run and stores it.
/// @throws InputError for a run without the target or too few samples
ThermalFitAnalysis fitThermal(Session& session, storage::Id run_id, const ThermalFitRequest& request);

struct ThermalRunRequest {
  acquisition::ThermalPlan plan;  ///< a new run's (ignored when resuming)
  storage::Id resume_run = 0;     ///< continue this interrupted run (its plan) instead
  std::string logger_uri = "mock://logger", probes_uri = "mock://probes", interferometer_uri = "mock://interferometer";
  std::string machine = "unnamed machine";  ///< real instruments: the machine measured
  SimulationOptions simulation;             ///< mock:// instruments
};

struct ThermalRunResult {
  storage::Id run_id = 0;
  std::string displacement_name;  ///< the plan's target channel
  std::int64_t samples = 0, planned = 0, missing_values = 0;
  bool complete = false;
  std::string stopped_because;
  nlohmann::json document() const;
};

/// Runs (or resumes) a thermal monitoring plan: on the simulated machine, or with real
/// instruments while the operator runs the spindle program (asked through the session's
/// operator). Progress: one step per sample.
/// @throws InputError for a request that cannot run (mixed real and simulated instruments ...)
ThermalRunResult runThermal(Session& session, const ThermalRunRequest& request);

}  // namespace mtcal::services
