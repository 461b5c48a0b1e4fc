#include "mtcal/services/run_plan.h"

#include <fmt/format.h>

#include "mtcal/error.h"
#include "mtcal/services/circle.h"
#include "mtcal/services/est.h"
#include "mtcal/services/gantry.h"
#include "mtcal/services/linear.h"
#include "mtcal/services/thermal.h"

namespace mtcal::services {

std::string planType(const nlohmann::json& plan, const std::string& source) {
  const std::string type = plan.is_object() && plan.contains("type") && plan["type"].is_string()
                               ? plan["type"].get<std::string>()
                               : std::string();
  if (!plan.is_object()) throw InputError(source + ": no plan (a plan is a JSON object with a key 'type')");
  for (const char* known : {"linear", "circle", "est", "gantry", "thermal"}) {
    if (type == known) return type;
  }
  throw InputError(
      fmt::format("{}: key 'type' is '{}': a plan is of type linear, circle, est, gantry or thermal", source, type));
}

nlohmann::json runPlan(Session& session, const PlanRunRequest& request) {
  const std::string& source = request.plan_name.empty() ? std::string("the plan") : request.plan_name;
  const auto type = planType(request.plan, source);
  const auto device = [&](const char* simulated) {
    return request.device_uri.empty() ? std::string(simulated) : request.device_uri;
  };
  if (type == "linear") {
    LinearRunRequest r;
    r.plans = {acquisition::LinearPlan::fromJson(request.plan, source)};
    r.plan_path = source;
    r.device_uri = device("mock://interferometer");
    r.simulation = request.simulation;
    r.machine = request.machine;
    const auto campaign = runLinear(session, r);
    return campaign.runs.front().document();
  }
  if (type == "circle") {
    CircleRunRequest r;
    r.plan = acquisition::CirclePlan::fromJson(request.plan, source);
    r.device_uri = device("mock://ballbar");
    r.simulation = request.simulation;
    return runCircle(session, r).document();
  }
  if (type == "est") {
    EstRunRequest r;
    r.plan = acquisition::EstPlan::fromJson(request.plan, source);
    r.device_uri = device("mock://probes");
    r.simulation = request.simulation;
    return runEst(session, r).document();
  }
  if (type == "gantry") {
    GantryRunRequest r;
    r.plan = acquisition::GantryPlan::fromJson(request.plan, source);
    r.plan_path = source;
    r.device_uri = device("mock://tracker");
    r.simulation = request.simulation;
    return runGantry(session, r).document();
  }
  ThermalRunRequest r;
  r.plan = acquisition::ThermalPlan::fromJson(request.plan, source);
  if (!request.logger_uri.empty()) r.logger_uri = request.logger_uri;
  if (!request.device_uri.empty()) {
    (r.plan.displacement_device == "interferometer" ? r.interferometer_uri : r.probes_uri) = request.device_uri;
  }
  r.machine = request.machine;
  r.simulation = request.simulation;
  return runThermal(session, r).document();
}

}  // namespace mtcal::services
