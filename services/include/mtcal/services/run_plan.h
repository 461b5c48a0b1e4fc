#pragma once
// A plan of any kind run from its JSON, as `mtcal run TYPE PLAN` runs it: the dashboard's
// "start a plan" (docs/dashboard.md).

#include <nlohmann/json.hpp>
#include <string>

#include "mtcal/services/session.h"
#include "mtcal/services/workshop.h"

namespace mtcal::services {

struct PlanRunRequest {
  nlohmann::json plan;    ///< a plan file's content; its "type" (linear, circle, est, gantry, thermal) says the kind
  std::string plan_name;  ///< named in messages (its file's name)
  /// The instrument: empty for the kind's simulated one (mock://interferometer, mock://ballbar,
  /// mock://probes, mock://tracker); for a thermal plan the displacement instrument (the
  /// plan's probes or interferometer).
  std::string device_uri;
  std::string logger_uri;                   ///< thermal plans: the temperature logger (empty: mock://logger)
  std::string machine = "unnamed machine";  ///< real instruments: the machine measured
  SimulationOptions simulation;             ///< simulated instruments: the machine, its seed and pace
};

/// The plan's kind ("linear" ...). @throws InputError naming `source` when the plan has no known type
std::string planType(const nlohmann::json& plan, const std::string& source);

/// Runs the plan in a new campaign (progress, the operator and the stop request as the
/// session has them). @return the document `mtcal run TYPE --json` prints for it
/// @throws InputError for a plan or request that cannot run
nlohmann::json runPlan(Session& session, const PlanRunRequest& request);

}  // namespace mtcal::services
