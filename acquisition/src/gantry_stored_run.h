#pragma once
// The stored form of a gantry run, written by runGantryTest (gantry_run.cpp) and read back
// by loadGantryMeasurements and gantryPlanOfRun (gantry_measurements.cpp): the feature names
// of its points and its plan with the run's expansion.

#include <fmt/format.h>

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "mtcal/acquisition/gantry_plan.h"
#include "mtcal/processing/multibody.h"

namespace mtcal::acquisition::gantry_stored_run {

/// Feature names of the stored points: a pass (odd passes increase X).
inline int passDirection(int pass) { return pass % 2 == 1 ? 1 : -1; }
inline std::string passFeature(int pass) {
  return fmt::format("pass:{}:{}", pass, passDirection(pass) > 0 ? "+" : "-");
}

/// The plan a run stores: the plan as given with the expansion (reflector_radius_mm,
/// initial_np_mm, holes with their machine coordinates, tool points and tool vectors) by
/// which the stored run is evaluated without the machine file; gantryPlanOfRun removes it.
/// @throws InputError for an unknown reflector or kinematics without x, y, z, c, a
nlohmann::json expandedPlan(const GantryPlan& plan, const processing::MultibodyModel& kinematics,
                            const std::vector<PlannedHole>& holes);

}  // namespace mtcal::acquisition::gantry_stored_run
