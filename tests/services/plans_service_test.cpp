#include <gtest/gtest.h>

#include <regex>

#include "mtcal/acquisition/gcode.h"
#include "mtcal/acquisition/linear_plan.h"
#include "mtcal/acquisition/thermal_run.h"
#include "mtcal/error.h"
#include "mtcal/services/plans.h"

// Every plan kind's part program states its dwells in the dialect's unit, seconds: a linear
// plan holds each target for two dwells, two windows and a second; a circular test pauses
// 2 s between directions; a thermal plan holds each spindle phase for its duration.
namespace mtcal::services {
namespace {

std::vector<double> dwellsS(const std::string& program) {
  std::vector<double> out;
  const std::regex dwell(R"((?:G4 P|G04 X)([0-9.]+))");
  for (auto it = std::sregex_iterator(program.begin(), program.end(), dwell); it != std::sregex_iterator(); ++it) {
    out.push_back(std::stod((*it)[1]));
  }
  return out;
}

TEST(PlansService, EveryPlanKindsDwellsAreInSeconds) {
  const std::string plans = MTCAL_EXAMPLES_DIR "/plans";
  const auto linear_plan = acquisition::LinearPlan::load(plans + "/x_axis_iso230-2.json");
  const auto linear = partProgram(plans + "/x_axis_iso230-2.json", "");
  EXPECT_EQ(linear.type, "linear");
  const double hold_s = 2.0 * linear_plan.dwell_s + 2.0 * linear_plan.window_s + 1.0;
  const auto linear_dwells = dwellsS(linear.program);
  ASSERT_EQ(linear_dwells.size(), linear.targets + 1);  // every target and the datum
  for (const double d : linear_dwells) EXPECT_NEAR(d, hold_s, 5e-4);

  const auto circle = partProgram(plans + "/ballbar/circle_xy_100.json", "");
  const auto circle_dwells = dwellsS(circle.program);
  ASSERT_FALSE(circle_dwells.empty());
  for (const double d : circle_dwells) EXPECT_DOUBLE_EQ(d, 2.0);

  const auto thermal_plan = acquisition::ThermalPlan::fromJson(
      nlohmann::json::parse(readTextFile(plans + "/thermal/quick-2h.json")), "quick-2h.json");
  const auto thermal_dwells = dwellsS(partProgram(plans + "/thermal/quick-2h.json", "").program);
  ASSERT_EQ(thermal_dwells.size(), thermal_plan.phases.size());
  for (std::size_t i = 0; i < thermal_dwells.size(); ++i)
    EXPECT_NEAR(thermal_dwells[i], thermal_plan.phases[i].duration_s, 5e-4);

  EXPECT_EQ(acquisition::gcodeDwell("iso", 3600.0), "G4 P3600.000");
  EXPECT_EQ(acquisition::gcodeDwell("fanuc", 2.4), "G04 X2.400");
  EXPECT_THROW(acquisition::gcodeDwell("heidenhain", 1.0), InputError);
}

TEST(PlansService, AGantryProgramNeedsTheMachinesKinematics) {
  const std::string plan = MTCAL_EXAMPLES_DIR "/plans/gantry/quick-6x2.json";
  EXPECT_THROW(partProgram(plan, ""), InputError);
  const auto from_machine = partProgram(plan, MTCAL_EXAMPLES_DIR "/machines/gantry-drilling.json");
  EXPECT_EQ(from_machine.targets, 12u);
  // A kinematic description places the same holes.
  const auto from_model = partProgram(plan, MTCAL_EXAMPLES_DIR "/machines/gantry-xyz-ca-cn106017326.model.json");
  EXPECT_EQ(from_model.targets, 12u);
}

}  // namespace
}  // namespace mtcal::services
