#pragma once
// Point accuracy of a gantry drilling machine with a laser tracker (patent CN106017326,
// docs/gantry.md): a plan run on the simulated gantry or on a real machine running the plan's
// NC program, the evaluation of a stored run or of a measurement file, and the file's export.

#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "mtcal/acquisition/gantry_plan.h"
#include "mtcal/acquisition/gantry_run.h"
#include "mtcal/processing/gantry_accuracy.h"
#include "mtcal/services/session.h"
#include "mtcal/services/workshop.h"

namespace mtcal::services {

/// How a gantry point accuracy test is evaluated.
struct GantryEvaluateOptions {
  std::string tcp0 = "axes";  ///< axes (the patent) or tool-point (the measured nest)
  std::string fit = "auto";   ///< auto, patent (three-point frame) or lsq (Umeyama)
  int trials = -1;            ///< Monte Carlo trials; -1: the plan's (200 for a file), 0: none
  std::uint64_t seed = 1;     ///< of the Monte Carlo
};

/// An evaluation (processor "gantry-point-accuracy" when stored).
struct GantryAnalysis {
  storage::Id run_id = 0, result_id = 0;  ///< 0: a measurement file, not stored
  std::string title;                      ///< what was evaluated, for people
  GantryEvaluateOptions options;
  int trials = 0;  ///< Monte Carlo trials run
  processing::TrackerMpe mpe;
  processing::GantryEvaluation evaluation;
  std::optional<processing::GantryUncertainty> uncertainty;  ///< trials > 0
  nlohmann::json document() const;
};

/// Evaluates a stored gantry run and stores the result. @throws InputError
GantryAnalysis analyzeGantry(Session& session, storage::Id run_id, const GantryEvaluateOptions& options);
/// Evaluates an exported measurement file (docs/gantry.md). @throws InputError naming the key
GantryAnalysis evaluateGantryFile(const std::string& path, const GantryEvaluateOptions& options);
/// Writes a stored run's measurements as the file evaluateGantryFile reads. @return the holes written
std::size_t exportGantry(Session& session, storage::Id run_id, const std::string& path);

struct GantryRunRequest {
  acquisition::GantryPlan plan;
  std::string plan_path;  ///< named in the operator's requests
  std::string device_uri = "mock://tracker";
  SimulationOptions simulation;  ///< machine_file: the gantry (simulated), or a real one's kinematics
  GantryEvaluateOptions evaluation;
};

struct GantryRunResult {
  storage::Id run_id = 0;
  std::string status;  ///< completed or interrupted (the features measured are stored)
  std::string reason;
  std::size_t points = 0;
  std::optional<GantryAnalysis> analysis;  ///< completed runs
  nlohmann::json document() const;
};

/// Runs a gantry plan and evaluates it: on the simulated gantry through mock://tracker, or
/// with a real tracker on a real machine running the plan's NC program, the session's
/// operator placing the reflector and confirming the machine's positions. Progress: one step
/// per feature. @throws InputError for a request that cannot run (a hole outside the travel ...)
GantryRunResult runGantry(Session& session, const GantryRunRequest& request);
/// Continues an interrupted gantry run (the features it stored are kept) on the machine it was
/// measured on; a real machine's kinematics come from `simulation.machine_file`.
GantryRunResult resumeGantry(Session& session, storage::Id run_id, const SimulationOptions& simulation);

}  // namespace mtcal::services
