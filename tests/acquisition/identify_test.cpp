#include <gtest/gtest.h>

#include <fstream>
#include <nlohmann/json.hpp>

#include "../support/temp_dir.h"
#include "../support/time_scale.h"
#include "mtcal/acquisition/error_models.h"
#include "mtcal/acquisition/linear_run.h"
#include "mtcal/app/simulation.h"
#include "mtcal/error.h"

namespace mtcal::acquisition {
namespace {

// Round trip: a known positioning error -> simulated ISO 230-2 run through the whole
// acquisition path -> direct identification -> the model's E_x equals minus the true EXX
// (relative to the datum), within the instrument noise and the spline's approximation.
// The machine has 2.5 um backlash and the demo's error curves (polynomial + 180 mm wave).
TEST(DirectIdentification, RecoversThePositioningErrorOfTheSimulatedMachine) {
  auto machine = mocks::VirtualMachineConfig::demo(4);
  for (auto& a : machine.axes) a.positioning_sigma_um = 0.0;  // every approach the same
  auto interferometer = app::demoInterferometer();
  app::Simulation sim(machine, interferometer, mtcal::testing::timeScale(400.0));
  const mtcal::testing::TempDir dir;
  storage::Store store(dir.file("id.sqlite"));
  auto device = sim.registry.openAs<drivers::interferometer::InterferometerDevice>("mock://interferometer");
  LinearPlan plan;
  plan.start_mm = 50;
  plan.end_mm = 290;
  plan.step_mm = 20;
  plan.repeats = 3;
  plan.datum_mm = 50;
  LinearRun run(store, *device, &sim.controller, {});
  const auto run_id = run.start(plan, store.addCampaign(store.ensureMachine("vm", "", "{}"), "c"), std::nullopt);

  const auto curves = curvesFromRuns(store, {run_id});
  ASSERT_EQ(curves.size(), 1u);
  EXPECT_EQ(curves[0].name, "EXX");
  EXPECT_EQ(curves[0].position_mm.size(), 13u);
  EXPECT_EQ(curves[0].repeats[0], 5);  // 3 + 3 cycles - 2 + 1

  std::ifstream in(std::string(MTCAL_EXAMPLES_DIR) + "/machines/vmc3-cn104200063.model.json");
  const processing::ErrorModel model(processing::MultibodyModel::fromJson(nlohmann::json::parse(in), "vmc3"),
                                     {processing::ErrorFunction::fit(curves[0], {})});
  // The truth relative to the datum. The laser was zeroed at a datum approached upwards, so
  // it carries that approach's lag of half the backlash, which the mean of both directions
  // does not have elsewhere: the identified curve sits b/2 above it, everywhere.
  const auto& truth = sim.world.machine;
  const double half_backlash = machine.axes[0].backlash_um / 2.0;
  auto geometric = [&](double x) { return truth.staticErrorUm(mocks::Axis::kX, {}, x, +1) + half_backlash; };
  for (double x = 50.0; x <= 290.0; x += 10.0) {  // nodes and midpoints
    const double true_exx = geometric(x) - geometric(50.0);
    EXPECT_NEAR(-model.predictUm(Eigen::Vector3d(x, 0.0, 120.0))(0), true_exx + half_backlash, 0.05) << x;
  }
  EXPECT_THROW(curvesFromRuns(store, {run_id, run_id}), InputError);  // two runs of one error
}

// Pitch (angular optics) and vertical straightness (straightness optics) of X measured on the
// simulated machine and identified: the model's functions follow the true EBX and EZX
// relative to the datum, within the instruments' noise (0.05 urad, 0.02 um) and the spline.
TEST(DirectIdentification, RecoversPitchAndStraightnessFromTheirRuns) {
  auto machine = mocks::VirtualMachineConfig::demo(6);
  for (auto& a : machine.axes) a.positioning_sigma_um = 0.0;
  auto interferometer = app::demoInterferometer();
  app::Simulation sim(machine, interferometer, mtcal::testing::timeScale(400.0));
  const mtcal::testing::TempDir dir;
  storage::Store store(dir.file("id.sqlite"));
  auto device = sim.registry.openAs<drivers::interferometer::InterferometerDevice>("mock://interferometer");
  const auto campaign = store.addCampaign(store.ensureMachine("vm", "", "{}"), "c");
  std::vector<storage::Id> runs;
  for (const char* error : {"EBX", "EZX"}) {
    LinearPlan plan;
    plan.start_mm = 50;
    plan.end_mm = 290;
    plan.step_mm = 40;
    plan.repeats = 3;
    plan.measures = error;
    sim.setUpFor(plan);
    LinearRun run(store, *device, &sim.controller, {});
    runs.push_back(run.start(plan, campaign, std::nullopt));
    EXPECT_EQ(store.run(runs.back()).value_unit, error[1] == 'B' ? "urad" : "um");
  }
  const auto curves = curvesFromRuns(store, runs);
  ASSERT_EQ(curves.size(), 2u);
  std::vector<processing::ErrorFunction> functions;
  for (const auto& c : curves) functions.push_back(processing::ErrorFunction::fit(c, {}));
  const auto& truth = sim.world.machine;
  for (const auto& f : functions) {
    const int component = f.name() == "EBX" ? 4 : 2;
    const double tolerance = f.name() == "EBX" ? 0.05 : 0.02;
    auto true_value = [&](double x) {
      return machine.trueError(component == 4 ? "EBX" : "EZX", x);
    };
    for (double x = 50.0; x <= 290.0; x += 40.0) {
      EXPECT_NEAR(f.value(x), true_value(x) - true_value(50.0), tolerance) << f.name() << " at " << x;
    }
  }
  (void)truth;
  // Neither is ISO 230-2 material, and a triggered run cannot measure them.
  LinearPlan pitch;
  pitch.measures = "EBX";
  EXPECT_THROW(LinearRun(store, *device, nullptr, {}).start(pitch, campaign, std::nullopt), InputError);
  pitch.measures = "EBY";
  EXPECT_THROW(measuredComponent(pitch), InputError);
}

}  // namespace
}  // namespace mtcal::acquisition
