// Device faults in the middle of a run, through the real drivers against the emulators: the
// run stops cleanly, keeps every committed capture, names the device and the reason, and
// (the device back) resumes to completion.

#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "../support/gantry_session.h"
#include "../support/quick_circle.h"
#include "../support/temp_dir.h"
#include "../support/time_scale.h"
#include "mtcal/acquisition/circle_run.h"
#include "mtcal/error.h"
#include "mtcal/mocks/ballbar_emulator.h"
#include "mtcal/services/workshop.h"

namespace mtcal::acquisition {
namespace {

/// Injects a fault into the ballbar as the machine starts its second circle.
class FaultOnSecondCircle final : public MachineController {
 public:
  FaultOnSecondCircle(services::VirtualMachineController& inner, std::function<void()> fault)
      : inner_(inner), fault_(std::move(fault)) {}
  std::optional<double> moveTo(const std::string& axis, double position) override {
    return inner_.moveTo(axis, position);
  }
  std::optional<std::pair<double, double>> followPath(const processing::ContourPath& path) override {
    if (++paths_ == 2) fault_();
    return inner_.followPath(path);
  }

 private:
  services::VirtualMachineController& inner_;
  std::function<void()> fault_;
  int paths_ = 0;
};

/// A circular test on the demo machine into a temporary archive.
struct CircleRig {
  CircleRig() {
    sim.setUpFor(plan);
    options.mount_bar = [this] { sim.world.ballbar->mountOnMachine(); };
    options.run_clock = &sim.run_clock;
  }
  mtcal::testing::TempDir dir;
  storage::Store store{dir.file("bb.sqlite")};
  services::Simulation sim{mocks::VirtualMachineConfig::demo(1), services::demoInterferometer(),
                           mtcal::testing::timeScale(50.0)};
  CirclePlan plan = mtcal::testing::quickCirclePlan();
  storage::Id campaign = store.addCampaign(store.ensureMachine("demo", "", "{}"), "faults");
  CircleRunOptions options;
};

struct BallbarFaultCase {
  const char* name;
  std::function<void(mocks::BallbarFaults&)> fault;
  const char* reason;  ///< what the interruption says
};

class BallbarFault : public ::testing::TestWithParam<BallbarFaultCase> {};

TEST_P(BallbarFault, StopsKeepsTheFirstDirectionAndResumesWhenTheBarIsBack) {
  const auto& c = GetParam();
  CircleRig rig;
  auto& [dir, store, sim, plan, campaign, options] = rig;
  CircleRunResult first;
  {
    auto bar = sim.registry.openAs<drivers::ballbar::BallbarDevice>("mock://ballbar");
    FaultOnSecondCircle controller(sim.controller, [&] { sim.world.ballbar->updateFaults(c.fault); });
    first = runCircleTest(store, campaign, *bar, controller, plan, options);
  }
  EXPECT_EQ(first.outcome, RunOutcome::kInterrupted);
  EXPECT_NE(first.reason.find(c.reason), std::string::npos) << first.reason;
  EXPECT_EQ(store.run(first.run_id).status, "interrupted");
  const auto kept = store.circlePoints(first.run_id);
  ASSERT_FALSE(kept.empty());
  for (const auto& p : kept) EXPECT_EQ(p.direction, "ccw");  // the finished direction, whole
  bool logged = false;
  for (const auto& e : store.events(first.run_id)) logged |= e.message.find(c.reason) != std::string::npos;
  EXPECT_TRUE(logged);

  // The bar is plugged in again: the run resumes with the direction it lacks.
  sim.world.ballbar->updateFaults([](mocks::BallbarFaults& f) { f = {}; });
  sim.setUpFor(plan);
  auto bar = sim.registry.openAs<drivers::ballbar::BallbarDevice>("mock://ballbar");
  options.resume_run = first.run_id;
  const auto resumed = runCircleTest(store, campaign, *bar, sim.controller, plan, options);
  EXPECT_EQ(resumed.outcome, RunOutcome::kCompleted) << resumed.reason;
  const auto all = store.circlePoints(first.run_id);
  ASSERT_GT(all.size(), kept.size());
  for (std::size_t i = 0; i < kept.size(); ++i) EXPECT_EQ(all[i].deviation_um, kept[i].deviation_um);
  EXPECT_EQ(all.back().direction, "cw");
}

INSTANTIATE_TEST_SUITE_P(Faults, BallbarFault,
                         ::testing::Values(BallbarFaultCase{
                             "Unplugged", [](mocks::BallbarFaults& f) { f.unplugged = true; }, "ballbar"}),
                         [](const auto& info) { return std::string(info.param.name); });

TEST(BallbarFault, GarbledReportsAreCountedAndSkippedNotTakenAsReadings) {
  CircleRig rig;
  auto& [dir, store, sim, plan, campaign, options] = rig;
  auto bar = sim.registry.openAs<drivers::ballbar::BallbarDevice>("mock://ballbar");
  FaultOnSecondCircle controller(sim.controller, [&] {
    sim.world.ballbar->updateFaults([](mocks::BallbarFaults& f) { f.garble_next_reports = 20; });
  });
  const auto r = runCircleTest(store, campaign, *bar, controller, plan, options);
  EXPECT_EQ(r.outcome, RunOutcome::kCompleted) << r.reason;
  EXPECT_GE(r.stats.crc_errors + r.stats.lost_samples, 20u);  // every garbled report dropped and counted
  // What was stored is readings, not garbage: every point within the bar's range.
  for (const auto& p : store.circlePoints(r.run_id)) EXPECT_LT(std::abs(p.deviation_um), 1000.0);
}

/// Runs the quick gantry plan with `fault` injected as the reflector is placed for the second hole.
mtcal::testing::GantrySession gantryWithFault(const std::function<void(mocks::TrackerEmulator&)>& fault) {
  const auto plan = GantryPlan::fromJson(
      nlohmann::json::parse(services::readTextFile(MTCAL_EXAMPLES_DIR "/plans/gantry/quick-6x2.json")), "quick");
  const auto machine = mocks::VirtualMachineConfig::fromJson(
      nlohmann::json::parse(services::readTextFile(MTCAL_EXAMPLES_DIR "/machines/gantry-drilling.json")),
      MTCAL_EXAMPLES_DIR "/machines/gantry-drilling.json");
  return mtcal::testing::runSession(plan, machine, {0, 0, 0, 0, 25, 0, 100, 0},
                                    [fault](mocks::TrackerEmulator& e, const std::string& feature) {
                                      if (feature == "hole g1-h02 (2 of 12)") fault(e);
                                    });
}

TEST(TrackerFault, ASilentTrackerStopsTheRunNamingItAndKeepsTheHolesDone) {
  const auto run = gantryWithFault([](mocks::TrackerEmulator& e) { e.setSilent(true); });
  EXPECT_EQ(run.result.outcome, RunOutcome::kInterrupted);
  EXPECT_NE(run.result.reason.find("tcp://127.0.0.1:"), std::string::npos) << run.result.reason;  // the device
  EXPECT_NE(run.result.reason.find("timed out"), std::string::npos) << run.result.reason;
  ASSERT_EQ(run.measured.holes.size(), 1u);  // the first hole, whole
  EXPECT_EQ(run.measured.holes[0].id, "g1-h01");
}

TEST(TrackerFault, ATrackerThatDropsTheConnectionAndReappearsIsReconnected) {
  const auto run = gantryWithFault([](mocks::TrackerEmulator& e) { e.dropConnection(); });
  EXPECT_EQ(run.result.outcome, RunOutcome::kCompleted) << run.result.reason;
  EXPECT_EQ(run.measured.holes.size(), 12u);
}

}  // namespace
}  // namespace mtcal::acquisition
