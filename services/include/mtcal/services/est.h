#pragma once
// Guideway straightness by error separation (docs/est.md): probe readings from a file, a
// probe stepping run on the simulated machine and a stored run, one separation for all three.

#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "mtcal/acquisition/csv.h"
#include "mtcal/acquisition/est_run.h"
#include "mtcal/processing/diagnosis.h"
#include "mtcal/processing/est.h"
#include "mtcal/services/session.h"
#include "mtcal/services/workshop.h"

namespace mtcal::services {

/// How the probes' readings are separated.
struct EstMethod {
  /// two-probe | three-probe | frequency; a stored run's own when empty (three-probe for three probes)
  std::string method = "two-probe";
  std::string start = "carriage-at-rest";  ///< two-probe: carriage-at-rest | second-point
  double spacing_mm = 0.0;                 ///< between neighbouring probes; a stored run's plan's when 0
};

/// The probes' readings along the guideway, as the diagnosis takes them (positions, readings,
/// and each probe's scatter and count per step where known; the spacing is the method's), and
/// the probes' readings on a reference flat (the run's zeroing, or given with a file).
struct ProbeReadings : processing::EstRunInput {
  std::optional<acquisition::EstZeroing> zeroing;
};

/// A separation (processor "est" when stored).
struct EstAnalysis {
  storage::Id run_id = 0, result_id = 0;  ///< 0: readings from a file, not stored
  EstMethod method;
  processing::EstResult result;
  processing::Straightness straightness;
  /// What the readings' scatter alone makes of the profile (1 sigma per point; stored runs).
  std::vector<double> noise_um;
  std::optional<acquisition::EstZeroing> zeroing;  ///< subtracted from the three-probe combination
  std::vector<std::string> warnings;               ///< what makes the result doubtful
  nlohmann::json document() const;
};

/// Readings of the probes on a reference flat, "z1,z2[,z3]" in um (--zero-readings-um).
/// @throws InputError naming the option
acquisition::EstZeroing givenZeroing(const std::string& readings_um);

/// x_mm,v1_um,v2_um[,v3_um] from a CSV file, and where the file states the probes' scatter,
/// s1_um,s2_um[,s3_um] with readings (how many were averaged at each step; a step read once has
/// an empty scatter). @throws InputError naming the line and column
ProbeReadings readProbeCsv(const std::string& path, bool three_probes, const acquisition::CsvDialect& csv = {});
/// @throws InputError for an unknown method or readings it cannot separate
EstAnalysis separate(const ProbeReadings& readings, const EstMethod& method);
/// Probe readings from other software stored as a probe stepping run (source imported), so
/// `analyzeEst` and the diagnosis take them like an acquired run.
struct EstImport {
  storage::Id run_id = 0;
  std::size_t steps = 0;
  int probes = 2;
  bool scatter = false;               ///< the file gave the probes' scatter (at a step that averaged several)
  std::vector<std::string> warnings;  ///< the same file imported before
  nlohmann::json document() const {
    return {{"schema_version", 1}, {"run_id", run_id},   {"steps", steps},
            {"probes", probes},    {"scatter", scatter}, {"warnings", warnings}};
  }
};
/// x_mm (even steps), v1_um, v2_um[, v3_um] (and the scatter readProbeCsv reads); `spacing_mm`
/// between neighbouring probes.
/// @throws InputError naming the file, line and column, or the plan key that does not hold; nothing is stored then
EstImport importEst(Session& session, const std::string& path, double spacing_mm, const std::string& name,
                    const std::string& machine, const acquisition::CsvDialect& csv = {},
                    const std::optional<acquisition::EstZeroing>& zeroing = std::nullopt);

/// Separates a stored probe stepping run and stores the result.
/// @throws InputError when the run is not a probe stepping run or has too few steps
EstAnalysis analyzeEst(Session& session, storage::Id run_id, EstMethod method);

struct EstRunRequest {
  acquisition::EstPlan plan;
  std::string device_uri = "mock://probes";
  SimulationOptions simulation;
  std::string machine = "real";  ///< a real machine's name (the campaign's)
};

struct EstRunResult {
  storage::Id run_id = 0;
  std::string status;  ///< completed or interrupted (the steps measured are stored)
  std::size_t steps = 0;
  std::optional<EstAnalysis> analysis;  ///< completed runs: two-probe (three-probe with 3 probes)
  nlohmann::json document() const;
};

/// Runs a probe stepping plan on the simulated machine (progress: one step per carriage
/// position), then separates it. @throws InputError for a real device (not built yet)
EstRunResult runEst(Session& session, const EstRunRequest& request);
/// Continues an interrupted probe stepping run on the simulated machine it ran on: the steps it
/// stored are kept, the others measured.
EstRunResult resumeEst(Session& session, storage::Id run_id, double time_scale);

}  // namespace mtcal::services
