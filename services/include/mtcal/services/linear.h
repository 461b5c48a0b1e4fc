#pragma once
// Linear axis calibration with a laser interferometer (docs/linear-calibration.md): running
// plans on the simulated or a real machine, resuming, importing other software's data and
// the ISO 230-2 evaluation, each stored with its result.

#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "mtcal/acquisition/import_linear.h"
#include "mtcal/acquisition/linear_plan.h"
#include "mtcal/processing/air_index.h"
#include "mtcal/processing/iso230_2.h"
#include "mtcal/processing/positioning_standards.h"
#include "mtcal/services/session.h"
#include "mtcal/services/workshop.h"

namespace mtcal::services {

/// The ISO 230-2 evaluation of a run, as stored in its results (processor "iso230-2").
struct Iso230Analysis {
  storage::Id run_id = 0;
  storage::Id result_id = 0;
  std::string axis, run_name;  ///< of the run, for people
  processing::Iso230Result result;
  /// What the figures stand on: a run that measured part of its plan, fewer cycles than the
  /// standard's 5.
  std::vector<std::string> warnings;
  /// The result document: the figures, every position's, warnings; `run_id`.
  nlohmann::json document() const;
};

/// The measured means against the virtual machine's true errors, after removing the common
/// offset of the datum capture (ISO 230-2 values are all ranges and differences).
struct SimulationCheck {
  double datum_offset_um = 0.0, max_abs_um = 0.0, rms_um = 0.0;
  std::size_t compared_means = 0;
  nlohmann::json document() const;
};

/// One run of a linear campaign as it ended.
struct LinearRunResult {
  storage::Id run_id = 0;
  storage::Id campaign_id = 0;
  std::string name;                                 ///< the run's (its plan's) name
  std::string status;                               ///< completed or interrupted
  std::int64_t targets = 0;                         ///< captured
  std::string measures;                             ///< EXX, EYX, EBX ... (the plan's error)
  std::string unit;                                 ///< of the deviations: um or urad
  std::optional<Iso230Analysis> iso230_2;           ///< completed positioning runs
  std::optional<SimulationCheck> simulation_check;  ///< ... on the simulated machine
  /// What `mtcal run linear --json` prints for this run.
  nlohmann::json document() const;
};

struct LinearCampaignResult {
  storage::Id campaign_id = 0;
  std::vector<LinearRunResult> runs;  ///< in the plans' order; an interrupted run is the last
  bool interrupted() const { return !runs.empty() && runs.back().status != "completed"; }
  /// `schema_version`, `campaign_id`, `runs` (each run's document).
  nlohmann::json document() const;
};

struct LinearRunRequest {
  /// One campaign. Several plans only on the simulated machine with the scheduler moving it
  /// (the simulated operator sets up the optics for each).
  std::vector<acquisition::LinearPlan> plans;
  std::string plan_path;  ///< the (first) plan's file, named in messages
  std::string device_uri = "mock://interferometer";
  SimulationOptions simulation;  ///< for mock:// devices
  /// The machine runs the plan's part program and each target is captured when the reading
  /// holds still at it: always on a real machine; on the simulated one its virtual CNC runs it.
  bool triggered = false;
  std::string machine = "unnamed machine";  ///< real devices: the machine measured
};

/// Runs the plans in a new campaign. Progress: one step per target; the operator is told
/// when to start the part program (real machine). A run interrupted by the stop request or a
/// device error keeps its targets and ends the campaign there.
/// @throws InputError for a request that cannot run; StorageError
LinearCampaignResult runLinear(Session& session, const LinearRunRequest& request);

/// Continues an interrupted acquired linear run on the simulated machine it was measured on.
/// @throws InputError naming why it cannot be resumed
LinearRunResult resumeLinear(Session& session, storage::Id run_id, double time_scale);

/// Imports another software's export (acquisition::importLinearCsv): one run, or one per error
/// column. Its warnings (times that cannot be one clock's) are also told to the observer.
acquisition::LinearImport importLinear(Session& session, const std::string& path,
                                       acquisition::LinearImportOptions options);
/// Imports a whole campaign of linear runs from its manifest (acquisition::importLinearCampaign),
/// its warnings told as importLinear's.
acquisition::CampaignImport importCampaign(Session& session, const std::string& manifest_path,
                                           acquisition::CampaignImportOptions options);

/// The refractive index of air for a laser's vacuum wavelength.
struct AirIndex {
  std::string model;  ///< edlen (modified Edlen, Boensch and Potulski 1998) or ciddor (Ciddor 1996)
  double n = 1.0, wavelength_air_nm = 0.0;
  nlohmann::json document() const;
};
/// @throws InputError for another model or conditions outside the equations' range
AirIndex airIndex(const std::string& model, const processing::AirState& air, double vacuum_wavelength_nm);

/// Evaluates a positioning run per ISO 230-2 and stores the result.
/// @throws InputError when the run is not a linear positioning run or has no targets
Iso230Analysis analyzeIso230_2(Session& session, storage::Id run_id);

/// A positioning run's figures under a standard (processing::positioningStandards()).
struct PositioningAnalysis {
  Iso230Analysis iso230_2;  ///< the per-target means and deviations the standard's figures come from
  processing::StandardEvaluation evaluation;
  /// What the simulated machine itself does at the run's targets (the truth the run measures,
  /// with the controller's tables it ran, without the per-approach scatter): ISO 230-2's E and
  /// M of it. None for a real machine.
  std::optional<double> truth_E_um, truth_M_um;
  /// The standard's figures, its notes, the per-target means for plots, the warnings of
  /// iso230_2 (what limits the figures); `run_id`.
  nlohmann::json document() const;
};

/// Evaluates a positioning run under `standard` and stores the result (processor "positioning").
/// @throws InputError as analyzeIso230_2, or naming the standards there are
PositioningAnalysis analyzeLinear(Session& session, storage::Id run_id, const std::string& standard);

/// Two positioning runs of one axis side by side (e.g. before and after compensation).
struct RunComparison {
  PositioningAnalysis before, after;
  /// What makes the two hard to compare: the same run twice, different ranges of targets.
  std::vector<std::string> warnings;
  /// Per figure: before, after, the change (after - before) and the change in % of before.
  nlohmann::json document() const;
};

/// @throws InputError when a run is not a positioning run or they measured different axes
RunComparison compareRuns(Session& session, storage::Id before, storage::Id after, const std::string& standard);

}  // namespace mtcal::services
