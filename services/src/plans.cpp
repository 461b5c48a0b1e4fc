#include "mtcal/services/plans.h"

#include <nlohmann/json.hpp>

#include "mtcal/acquisition/circle_plan.h"
#include "mtcal/acquisition/gantry_plan.h"
#include "mtcal/acquisition/linear_plan.h"
#include "mtcal/acquisition/thermal_run.h"
#include "mtcal/error.h"

namespace mtcal::services {

PartProgram partProgram(const std::string& plan_path, const std::string& machine_file) {
  const auto j = readJsonFile(plan_path);
  PartProgram p;
  p.type = j.is_object() && j.contains("type") && j["type"].is_string() ? j["type"].get<std::string>() : "linear";
  if (p.type == "est") {
    throw InputError(plan_path +
                     ": an EST plan has no part program yet: `mtcal run est` steps the simulated machine, or asks "
                     "the operator to step a real one (\"stepping\": \"hand\", docs/est.md)");
  }
  if (p.type == "circle") {
    p.program = acquisition::circleGcode(acquisition::CirclePlan::fromJson(j, plan_path));
  } else if (p.type == "thermal") {
    p.program = acquisition::thermalGcode(acquisition::ThermalPlan::fromJson(j, plan_path));
  } else if (p.type == "gantry") {
    if (machine_file.empty())
      throw InputError("a gantry plan's NC program needs the machine's kinematics: --machine-config FILE");
    const auto plan = acquisition::GantryPlan::fromJson(j, plan_path);
    const auto holes = acquisition::planHoles(plan, machineKinematics(machine_file));
    p.program = acquisition::gantryGcode(plan, holes);
    p.targets = holes.size();
  } else {
    const auto plan = acquisition::LinearPlan::load(plan_path);
    p.program = acquisition::linearGcode(plan);
    p.targets = acquisition::linearTargets(plan).size();
  }
  return p;
}

nlohmann::json PartProgram::document(const std::string& file) const {
  nlohmann::json j{{"schema_version", 1}, {"type", type}, {"targets", targets}};
  if (file.empty()) {
    j["text"] = program;
  } else {
    j["program"] = file;
  }
  return j;
}

std::vector<drivers::ScanResult> scanDevices(const SimulationOptions& simulation) {
  Simulation sim(mocks::VirtualMachineConfig::demo(simulation.seed.value_or(1)), demoInterferometer(),
                 simulation.time_scale);
  return sim.registry.scan();
}

}  // namespace mtcal::services
