#pragma once
// Circular tests with a ballbar (docs/ballbar.md): a plan run on the simulated machine,
// circle data from other software, the ISO 230-4 evaluation and the ballbar diagnosis of a
// stored test, each stored with its result.

#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "mtcal/acquisition/circle_measurements.h"
#include "mtcal/acquisition/circle_plan.h"
#include "mtcal/acquisition/circle_run.h"
#include "mtcal/processing/iso230_4.h"
#include "mtcal/services/session.h"
#include "mtcal/services/workshop.h"

namespace mtcal::services {

/// What a stored circular test was measured with.
struct CircleSetting {
  processing::Plane plane = processing::Plane::kXY;
  double radius_mm = 0.0, feed_mm_per_min = 1000.0;
};

/// The ISO 230-4 evaluation of a stored test (processor "iso230-4").
struct Iso230_4Analysis {
  storage::Id run_id = 0, result_id = 0;
  CircleSetting setting;
  processing::CircularTestResult result;
  std::vector<processing::CirclePoint> points;  ///< the radial deviations evaluated (for plots)
  /// G per direction, G(b), H, the centre (named by the plane's axes), every path's figures.
  nlohmann::json document() const;
};

/// The ballbar diagnosis of a stored test (processor "ballbar-diagnosis").
struct BallbarAnalysis {
  storage::Id run_id = 0, result_id = 0;
  CircleSetting setting;
  processing::BallbarDiagnosis diagnosis;
  nlohmann::json document() const;
};

/// @throws InputError when the run is not a circular test or has no points
Iso230_4Analysis analyzeIso230_4(Session& session, storage::Id run_id);
BallbarAnalysis analyzeBallbar(Session& session, storage::Id run_id);

struct CircleImport {
  storage::Id run_id = 0;
  std::size_t points = 0;
  std::vector<std::string> warnings;  ///< what was taken as given (a feed not given)
  nlohmann::json document() const {
    return {{"schema_version", 1}, {"run_id", run_id}, {"points", points}, {"warnings", warnings}};
  }
};
/// @throws InputError naming the line and column; nothing is stored then
CircleImport importCircle(Session& session, const std::string& path, acquisition::CircleImportOptions options);

struct CircleRunRequest {
  acquisition::CirclePlan plan;
  std::string device_uri = "mock://ballbar";
  SimulationOptions simulation;
  /// mock:// only: the virtual CNC runs the plan's part program and the test is captured from
  /// the stream (feed-in and feed-out), as on a real machine. A real device always is.
  bool triggered = false;
  std::string plan_path;         ///< named to the operator of a real machine
  std::string machine = "real";  ///< a real machine's name (the campaign's)
};

struct CircleRunResult {
  storage::Id run_id = 0;
  std::string status;                           ///< completed or interrupted
  std::string reason;                           ///< why it was interrupted
  std::size_t points = 0;                       ///< in the measuring arcs
  std::uint64_t samples = 0, lost_samples = 0;  ///< streamed in this session (a resumed run: since it resumed)
  bool resumed = false;
  std::optional<Iso230_4Analysis> iso230_4;  ///< completed tests
  std::optional<BallbarAnalysis> ballbar;
  /// What `mtcal run ballbar --json` prints.
  nlohmann::json document() const;
};

/// Runs a circular test on the simulated machine (progress: one step per direction), then
/// evaluates and diagnoses it. A test interrupted (over range, the stop request) keeps the
/// directions completed. @throws InputError for a real device (the simulated machine only)
CircleRunResult runCircle(Session& session, const CircleRunRequest& request);
/// Continues an interrupted test on the simulated machine it ran on: the directions it stored
/// are kept, the bar zeroed and mounted again, the others measured.
CircleRunResult resumeCircle(Session& session, storage::Id run_id, double time_scale);

}  // namespace mtcal::services
