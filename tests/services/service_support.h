#pragma once
// What the service tests share: an observer that records what it is told, and an operator
// who answers from a script.

#include <string>
#include <vector>

#include "../support/quick_circle.h"
#include "../support/time_scale.h"
#include "mtcal/error.h"
#include "mtcal/services/circle.h"
#include "mtcal/services/gantry.h"
#include "mtcal/services/linear.h"
#include "mtcal/services/session.h"

namespace mtcal::testing {

struct RecordingObserver final : services::Observer {
  std::vector<services::Progress> progress;
  std::vector<std::string> warnings;
  void onProgress(const services::Progress& p) override { progress.push_back(p); }
  void onMessage(const std::string& level, const std::string& text) override {
    if (level == "warning") warnings.push_back(text);
  }
};

/// Confirms the first `answers` requests, then stops answering (as a closed stdin does).
struct ScriptedOperator final : services::Operator {
  explicit ScriptedOperator(std::size_t answers) : answers_(answers) {}
  std::vector<std::string> requests, told;
  void confirm(const std::string& request) override {
    requests.push_back(request);
    if (requests.size() > answers_) throw InputError("no answer from the operator at: " + request);
  }
  void tell(const std::string& text) override { told.push_back(text); }

 private:
  std::size_t answers_;
};

/// A linear plan of 3 targets x 2 cycles x 2 directions (12 targets) on the demo machine's X.
inline acquisition::LinearPlan smallLinearPlan() {
  acquisition::LinearPlan p;
  p.name = "X, 3 targets";
  p.start_mm = 50;
  p.end_mm = 90;
  p.step_mm = 20;
  p.repeats = 2;
  p.datum_mm = 50;
  p.dwell_s = 0.5;
  p.window_s = 0.05;
  p.sample_rate_hz = 1000;
  return p;
}

/// That plan on the simulated demo machine: the seed, the pace (timeScale's nominal factor),
/// the axis measured.
inline services::LinearRunRequest smallLinearRun(std::uint64_t seed, double time_scale, const std::string& axis = "X") {
  services::LinearRunRequest r;
  r.plans = {smallLinearPlan()};
  r.plans.front().axis = axis;
  r.simulation.seed = seed;
  r.simulation.time_scale = timeScale(time_scale);
  return r;
}

/// A 50 mm circle at 2000 mm/min in XY, both directions, on the demo machine.
/// A session on the archive `db_path`, with nobody watching or asked.
inline services::SessionOptions onArchive(std::string db_path) {
  services::SessionOptions options;
  options.db_path = std::move(db_path);
  return options;
}

inline services::CircleRunRequest quickCircleRequest() {
  services::CircleRunRequest request;
  request.plan = quickCirclePlan();
  request.simulation.time_scale = timeScale(50.0);
  return request;
}

/// The quick gantry plan (12 holes) on the simulated gantry, without Monte Carlo trials.
inline services::GantryRunRequest quickGantryRequest() {
  services::GantryRunRequest request;
  request.plan_path = MTCAL_EXAMPLES_DIR "/plans/gantry/quick-6x2.json";
  request.plan = acquisition::GantryPlan::fromJson(nlohmann::json::parse(services::readTextFile(request.plan_path)),
                                                   request.plan_path);
  request.simulation.machine_file = MTCAL_EXAMPLES_DIR "/machines/gantry-drilling.json";
  request.simulation.time_scale = timeScale(400.0);
  request.evaluation.trials = 0;
  return request;
}

}  // namespace mtcal::testing
