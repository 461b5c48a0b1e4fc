// Circular tests on the virtual machine, through the ballbar emulator, the real driver and
// SQLite: each machine error injected alone and all together, then found by the diagnosis.
// Tolerances: the bar's noise is 0.1 um per sample over ~2 x 9000 samples; what remains is
// the diagnosis' first-order signatures against the machine's exact geometry, e.g. the
// servo loop's radius reduction (omega tau)^2 R / 2 (kept out of the scale cases by an ideal
// servo), and the lost motion ramp's dependence on the servo's lag.

#include "mtcal/acquisition/circle_run.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <sstream>

#include "../support/quick_circle.h"
#include "../support/temp_dir.h"
#include "../support/time_scale.h"
#include "mtcal/acquisition/circle_measurements.h"
#include "mtcal/acquisition/circle_plan.h"
#include "mtcal/error.h"
#include "mtcal/mocks/gcode_player.h"
#include "mtcal/processing/iso230_4.h"
#include "mtcal/services/workshop.h"

namespace mtcal::acquisition {
namespace {

// A machine with no error but the ones a test sets: ideal servo, no lost motion.
mocks::VirtualMachineConfig cleanMachine() {
  mocks::VirtualMachineConfig c;
  c.name = "clean";
  c.seed = 11;
  for (auto& a : c.axes) {
    a.min_mm = 0.0;
    a.max_mm = 700.0;
  }
  c.settle_time_constant_s = 0.01;
  return c;
}

struct Outcome {
  CircleRunResult run;
  processing::CircularTestResult iso;
  processing::BallbarDiagnosis diagnosis;
  std::vector<storage::CirclePointRecord> stored;
};

Outcome runOn(const mocks::VirtualMachineConfig& machine, const CirclePlan& plan, double bar_noise_um = 0.1) {
  mtcal::testing::TempDir dir;
  storage::Store store((dir.path() / "bb.sqlite").string());
  services::Simulation sim(machine, services::demoInterferometer(), mtcal::testing::timeScale(50.0));
  mocks::BallbarEmulatorConfig bar_config;
  bar_config.noise_um = bar_noise_um;
  sim.world.ballbar = std::make_shared<mocks::BallbarEmulator>(sim.world.machine, bar_config);
  sim.setUpFor(plan);
  auto bar = sim.registry.openAs<drivers::ballbar::BallbarDevice>("mock://ballbar");
  const auto campaign = store.addCampaign(store.ensureMachine(machine.name, "", "{}"), "test");
  CircleRunOptions options;
  options.mount_bar = [&sim] { sim.world.ballbar->mountOnMachine(); };
  options.run_clock = &sim.run_clock;
  Outcome o;
  o.run = runCircleTest(store, campaign, *bar, sim.controller, plan, options);
  EXPECT_EQ(o.run.outcome, RunOutcome::kCompleted) << o.run.reason;
  o.stored = store.circlePoints(o.run.run_id);
  const auto points = toCirclePoints(o.stored);
  o.iso = processing::evaluateCircularTest(plan.radius_mm, points);
  o.diagnosis = processing::diagnoseBallbar(plan.radius_mm, points, {plan.feed_mm_per_min, true, 6.0});
  return o;
}

/// The test as on a real machine: the virtual CNC runs the part program of `program_plan`
/// (the plan's own unless given) from cycle start; mtcal captures `plan` from the stream.
Outcome runTriggeredOn(const mocks::VirtualMachineConfig& machine, const CirclePlan& plan,
                       const CirclePlan& program_plan, bool start_program = true, double start_timeout_s = 600.0) {
  mtcal::testing::TempDir dir;
  storage::Store store((dir.path() / "bb.sqlite").string());
  services::Simulation sim(machine, services::demoInterferometer(), mtcal::testing::timeScale(50.0));
  sim.setUpFor(plan);
  auto bar = sim.registry.openAs<drivers::ballbar::BallbarDevice>("mock://ballbar");
  const auto campaign = store.addCampaign(store.ensureMachine(machine.name, "", "{}"), "test");
  const auto program = mocks::parseGcode(circleGcode(program_plan));
  std::optional<mocks::CncProgramRun> cnc;
  CircleRunOptions options;
  options.mount_bar = [&] {
    std::optional<double> at;
    for (const char* axis : {"Z", "X", "Y"})
      at = sim.controller.moveTo(axis, plan.centre_mm(std::string("XYZ").find(axis[0])));
    sim.run_clock.advanceTo(*at + plan.settle_s);
    sim.world.ballbar->mountOnMachine();
  };
  options.on_waiting_for_program = [&] {
    if (start_program) cnc.emplace(sim.world.machine, program);
  };
  options.program_start_timeout_s = start_timeout_s;
  options.run_clock = &sim.run_clock;
  Outcome o;
  o.run = runTriggeredCircleTest(store, campaign, *bar, plan, options);
  if (cnc) cnc->finish();
  o.stored = store.circlePoints(o.run.run_id);
  if (o.run.outcome == RunOutcome::kCompleted) {
    const auto points = toCirclePoints(o.stored);
    o.iso = processing::evaluateCircularTest(plan.radius_mm, points);
    o.diagnosis = processing::diagnoseBallbar(plan.radius_mm, points, {plan.feed_mm_per_min, true, 6.0, true});
  }
  return o;
}

TEST(BallbarRun, ACleanMachineGivesACircleAndNamesNothing) {
  const auto o = runOn(cleanMachine(), mtcal::testing::quickCirclePlan());
  EXPECT_EQ(o.run.stats.lost_samples, 0u);
  // 2 x 157 mm at 33.3 mm/s, one sample per ms: about 4712 points per direction.
  ASSERT_GT(o.stored.size(), 9000u);
  ASSERT_TRUE(o.iso.ccw && o.iso.cw);
  EXPECT_NEAR(o.iso.ccw->angle_span_deg, 360.0, 0.1);
  EXPECT_LT(o.iso.ccw->g_um, 1.0);  // noise 0.1 um: about +-4 sigma
  EXPECT_NEAR(o.iso.ccw->radius_deviation_um, 0.0, 0.05);
  const auto& d = o.diagnosis;
  EXPECT_FALSE(d.squareness_urad || d.servo_mismatch_ms || d.scale_mismatch_first_ppm || d.backlash_first_um ||
               d.backlash_second_um || d.reversal_spike_first_um || d.reversal_spike_second_um ||
               d.cyclic_amplitude_um);
}

TEST(BallbarRun, EachErrorAloneIsFoundWithItsValue) {
  {
    auto m = cleanMachine();
    m.errors["EC0Y"] = {{20.0}, {}};  // +Y leans to -X: the angle between +X and +Y is 90 deg + 20 urad
    const auto d = runOn(m, mtcal::testing::quickCirclePlan()).diagnosis;
    ASSERT_TRUE(d.squareness_urad);
    EXPECT_NEAR(*d.squareness_urad, 20.0, 0.5);
    EXPECT_FALSE(d.servo_mismatch_ms);
  }
  {
    auto m = cleanMachine();
    m.axes[0].kv_per_s = 25.0;  // tau 40 ms
    m.axes[1].kv_per_s = 27.0;  // tau 37.04 ms: X lags by 2.963 ms more
    const auto d = runOn(m, mtcal::testing::quickCirclePlan()).diagnosis;
    ASSERT_TRUE(d.servo_mismatch_ms);
    EXPECT_NEAR(*d.servo_mismatch_ms, 1000.0 / 25.0 - 1000.0 / 27.0, 0.05);
    EXPECT_FALSE(d.squareness_urad);
  }
  {
    auto m = cleanMachine();
    m.errors["EXX"] = {{0.0, 12.0}, {}};  // 12 um/m: 12 ppm
    m.errors["EYY"] = {{0.0, -7.0}, {}};
    const auto d = runOn(m, mtcal::testing::quickCirclePlan()).diagnosis;
    ASSERT_TRUE(d.scale_mismatch_first_ppm && d.scale_mismatch_second_ppm);
    EXPECT_NEAR(*d.scale_mismatch_first_ppm, 12.0, 0.5);
    EXPECT_NEAR(*d.scale_mismatch_second_ppm, -7.0, 0.5);
  }
  {
    auto m = cleanMachine();
    m.axes[0].backlash_um = 3.0;
    m.axes[1].backlash_um = 1.5;
    const auto d = runOn(m, mtcal::testing::quickCirclePlan()).diagnosis;
    ASSERT_TRUE(d.backlash_first_um && d.backlash_second_um);
    EXPECT_NEAR(*d.backlash_first_um, 3.0, 0.15);
    EXPECT_NEAR(*d.backlash_second_um, 1.5, 0.15);
  }
  {
    auto m = cleanMachine();
    m.errors["EXX"] = {{}, {{1.0, 8.0, 0.4}}};  // a lead error of 1 um, 8 mm pitch
    const auto d = runOn(m, mtcal::testing::quickCirclePlan()).diagnosis;
    ASSERT_TRUE(d.cyclic_amplitude_um && d.cyclic_period_mm);
    EXPECT_EQ(d.cyclic_axis, 0);
    EXPECT_NEAR(*d.cyclic_period_mm, 8.0, 0.05);
    EXPECT_NEAR(*d.cyclic_amplitude_um, 1.0, 0.1);
  }
}

TEST(BallbarRun, AllTogetherOnALaggingServoWithSticks) {
  auto m = cleanMachine();
  m.errors["EC0Y"] = {{-15.0}, {}};
  m.axes[0].kv_per_s = 30.0;
  m.axes[1].kv_per_s = 31.0;
  m.axes[0].backlash_um = 2.5;
  m.axes[1].backlash_um = 2.0;
  m.axes[0].reversal_spike_um = 2.0;
  m.axes[1].reversal_spike_um = 1.2;
  const auto d = runOn(m, mtcal::testing::quickCirclePlan()).diagnosis;
  SCOPED_TRACE(::testing::PrintToString(d.notes));
  ASSERT_TRUE(d.squareness_urad && d.servo_mismatch_ms && d.backlash_first_um && d.backlash_second_um &&
              d.reversal_spike_first_um && d.reversal_spike_second_um);
  EXPECT_NEAR(*d.squareness_urad, -15.0, 1.0);
  EXPECT_NEAR(*d.servo_mismatch_ms, 1000.0 / 30.0 - 1000.0 / 31.0, 0.05);
  EXPECT_NEAR(*d.backlash_first_um, 2.5, 0.2);
  EXPECT_NEAR(*d.backlash_second_um, 2.0, 0.2);
  EXPECT_NEAR(*d.reversal_spike_first_um, 2.0, 0.3);
  EXPECT_NEAR(*d.reversal_spike_second_um, 1.2, 0.3);
  EXPECT_LT(d.rms_after_um, 0.15);
}

TEST(BallbarRun, TheSameSeedGivesTheSamePoints) {
  auto m = cleanMachine();
  m.axes[0].backlash_um = 2.0;
  const auto a = runOn(m, mtcal::testing::quickCirclePlan());
  const auto b = runOn(m, mtcal::testing::quickCirclePlan());
  ASSERT_EQ(a.stored.size(), b.stored.size());
  for (std::size_t i = 0; i < a.stored.size(); i += 97) {
    // equal but for the rounding of the runs' different absolute world times
    EXPECT_NEAR(a.stored[i].angle_deg, b.stored[i].angle_deg, 1e-9);
    EXPECT_NEAR(a.stored[i].deviation_um, b.stored[i].deviation_um, 1e-9);
  }
}

TEST(BallbarRun, OverRangeInTheMeasuringArcInterruptsAndKeepsTheFinishedDirection) {
  // A 1.5 mm centre offset after the first direction: the CW run leaves the bar's +-1 mm.
  mtcal::testing::TempDir dir;
  storage::Store store((dir.path() / "bb.sqlite").string());
  services::Simulation sim(cleanMachine(), services::demoInterferometer(), mtcal::testing::timeScale(50.0));
  const auto plan = mtcal::testing::quickCirclePlan();
  sim.setUpFor(plan);
  auto bar = sim.registry.openAs<drivers::ballbar::BallbarDevice>("mock://ballbar");
  const auto campaign = store.addCampaign(store.ensureMachine("clean", "", "{}"), "test");
  class OffsetController final : public MachineController {
   public:
    explicit OffsetController(services::VirtualMachineController& inner) : inner_(inner) {}
    std::optional<double> moveTo(const std::string& axis, double position) override {
      return inner_.moveTo(axis, position);
    }
    std::optional<std::pair<double, double>> followPath(const processing::ContourPath& path) override {
      if (paths_++ == 0) return inner_.followPath(path);
      // The same path about a centre 1.5 mm off in X.
      processing::ContourPath off(path.start() + Eigen::Vector3d(1.5, 0, 0));
      for (const auto& s : path.segments())
        off.arc(s.centre_mm + Eigen::Vector3d(1.5, 0, 0), s.plane, s.sweep_rad, s.feed_mm_per_min);
      inner_.moveTo("X", off.start().x());
      return inner_.followPath(off);
    }

   private:
    services::VirtualMachineController& inner_;
    int paths_ = 0;
  } controller(sim.controller);
  CircleRunOptions options;
  options.mount_bar = [&sim] { sim.world.ballbar->mountOnMachine(); };
  options.run_clock = &sim.run_clock;
  const auto r = runCircleTest(store, campaign, *bar, controller, plan, options);
  EXPECT_EQ(r.outcome, RunOutcome::kInterrupted);
  EXPECT_NE(r.reason.find("over range"), std::string::npos) << r.reason;
  EXPECT_NE(r.reason.find("cw run"), std::string::npos) << r.reason;
  EXPECT_EQ(store.run(r.run_id).status, "interrupted");
  const auto kept = store.circlePoints(r.run_id);
  ASSERT_FALSE(kept.empty());
  for (const auto& p : kept) EXPECT_EQ(p.direction, "ccw");  // the completed direction, whole
}

// A real machine's workflow rehearsed: the virtual CNC runs the plan's part program by itself
// (G2/G3 interpolated with the servo's dynamics), mtcal streams the bar and finds each
// direction by its feed-in and feed-out. The capture gives what the controlled run gives: the
// same measuring arcs (points within 2 of the controlled count), the same errors found with the
// same tolerances (squareness 20 urad within 0.5, X lost motion 3 um within 0.15), and the
// timing in the run's events. A program at another feed (an override of 110 %) is refused
// with the reason; a program never started times out with what the bar read, nothing stored.
TEST(BallbarRun, APartProgramRunByTheCncIsCapturedByItsFeedInAndFeedOut) {
  auto m = cleanMachine();
  m.errors["EC0Y"] = {{20.0}, {}};
  m.axes[0].backlash_um = 3.0;
  const auto plan = mtcal::testing::quickCirclePlan();
  const auto controlled = runOn(m, plan);
  const auto captured = runTriggeredOn(m, plan, plan);
  ASSERT_EQ(captured.run.outcome, RunOutcome::kCompleted) << captured.run.reason;
  ASSERT_TRUE(captured.iso.ccw && captured.iso.cw);
  EXPECT_NEAR(static_cast<double>(captured.stored.size()), static_cast<double>(controlled.stored.size()), 2.0);
  EXPECT_NEAR(captured.iso.ccw->angle_span_deg, 360.0, 0.1);
  ASSERT_TRUE(captured.diagnosis.squareness_urad && captured.diagnosis.backlash_first_um);
  EXPECT_NEAR(*captured.diagnosis.squareness_urad, 20.0, 0.5);
  EXPECT_NEAR(*captured.diagnosis.backlash_first_um, 3.0, 0.15);
  // Timed from the feed-in, which the axes reach late by their lag: the radius the loops cost is
  // not put back from the reversals' reading, and the note says so.
  const auto noted = [](const processing::BallbarDiagnosis& d, const std::string& text) {
    return std::any_of(d.notes.begin(), d.notes.end(),
                       [&](const std::string& n) { return n.find(text) != std::string::npos; });
  };
  EXPECT_TRUE(noted(captured.diagnosis,
                    "scale not corrected for the servo loops' radius reduction: the angles are "
                    "timed from the bar's feed-in"));
  EXPECT_FALSE(noted(captured.diagnosis, "scale corrected for"));
  EXPECT_NEAR(captured.iso.ccw->g_um, controlled.iso.ccw->g_um, 0.3);
  EXPECT_NEAR(captured.iso.cw->g_um, controlled.iso.cw->g_um, 0.3);

  auto faster = plan;
  faster.feed_mm_per_min = 2200.0;
  const auto override = runTriggeredOn(m, plan, faster);
  EXPECT_EQ(override.run.outcome, RunOutcome::kInterrupted);
  EXPECT_NE(override.run.reason.find("at 100 % feed override"), std::string::npos) << override.run.reason;
  EXPECT_TRUE(override.stored.empty());

  const auto idle = runTriggeredOn(m, plan, plan, false, 5.0);
  EXPECT_EQ(idle.run.outcome, RunOutcome::kInterrupted);
  EXPECT_NE(idle.run.reason.find("no feed-in of the ccw run within 5 s"), std::string::npos) << idle.run.reason;
  EXPECT_TRUE(idle.stored.empty());
}

// The virtual CNC reads the circular test's program (G17/G18 arcs with I/J/K offsets) into
// contours that end where the plan's path ends and take as long.
TEST(CirclePlan, TheVirtualCncReadsThePartProgramsArcs) {
  for (const auto plane : {processing::Plane::kXY, processing::Plane::kZX}) {
    auto plan = mtcal::testing::quickCirclePlan();
    plan.plane = plane;
    std::vector<std::shared_ptr<processing::ContourPath>> contours;
    for (const auto& b : mocks::parseGcode(circleGcode(plan)))
      if (b.kind == mocks::GcodeBlock::Kind::kContour) contours.push_back(b.path);
    ASSERT_EQ(contours.size(), plan.directions.size());
    for (std::size_t i = 0; i < contours.size(); ++i) {
      const auto path = circlePath(plan, plan.directions[i]);
      EXPECT_LT((contours[i]->end() - path.end()).norm(), 1e-3);
      EXPECT_NEAR(contours[i]->durationS(), path.durationS(), 1e-4);
    }
  }
  EXPECT_THROW(mocks::parseGcode("G3 X1 Y1 I1 J0 F100\n"), InputError);               // where from?
  EXPECT_THROW(mocks::parseGcode("G0 X0 Y0 Z0\nG3 X2 Y0 I1 J0\n"), InputError);       // no feed
  EXPECT_THROW(mocks::parseGcode("G0 X0 Y0 Z0\nG3 X3 Y0 I1 J0 F100\n"), InputError);  // not one circle
}

TEST(CirclePlan, RejectsBadPlansNamingTheKey) {
  auto bad = [](const char* text) {
    try {
      CirclePlan::fromJson(nlohmann::json::parse(text), "plan.json");
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  EXPECT_NE(bad(R"({"radius_mm": -5})").find("radius_mm"), std::string::npos);
  EXPECT_NE(bad(R"({"plane": "XW"})").find("plane"), std::string::npos);
  EXPECT_NE(bad(R"({"directions": ["up"]})").find("directions"), std::string::npos);
  EXPECT_NE(bad(R"({"arc_deg": 45})").find("arc_deg"), std::string::npos);
  // The feeds an import takes: 0.5 mm/min is in m/min, 2e6 in um/min.
  EXPECT_EQ(bad(R"({"feed_mm_per_min": 0.5})"), "plan.json: key 'feed_mm_per_min': must be 1..1000000 mm/min");
  EXPECT_EQ(bad(R"({"feed_mm_per_min": 2e6})"), "plan.json: key 'feed_mm_per_min': must be 1..1000000 mm/min");
  EXPECT_EQ(bad(R"({"feed_mm_per_min": 1})"), "accepted");
  EXPECT_NE(bad(R"({"radius": 100})").find("unknown key"), std::string::npos);
  EXPECT_NE(bad(R"({"type": "linear"})").find("type"), std::string::npos);
  EXPECT_EQ(bad(R"({"centre_mm": [0, null, 0]})"), "plan.json: key 'centre_mm': its y is not a finite number (mm)");
  EXPECT_EQ(bad(R"({"centre_mm": [0, 0, 2e5]})"),
            "plan.json: key 'centre_mm': its z is 200000 mm: beyond 100 m of the origin (mm, not um)");
  EXPECT_EQ(bad(R"({"plane": "ZX", "radius_mm": 150, "directions": ["cw"], "calibrator_length_mm": null})"),
            "accepted");
}

TEST(CirclePlan, ThePartProgramTracesTheSamePath) {
  CirclePlan plan = mtcal::testing::quickCirclePlan();
  plan.plane = processing::Plane::kZX;
  const std::string g = circleGcode(plan);
  EXPECT_NE(g.find("G18"), std::string::npos);
  EXPECT_NE(g.find("F2000"), std::string::npos);
  // Replay every G2/G3 block (end point and centre offsets I/K of G18) and check it ends where
  // the path ends: the program and the simulation share one geometry.
  for (auto d : plan.directions) {
    const auto path = circlePath(plan, d);
    EXPECT_NEAR((path.start() - plan.centre_mm).norm(), plan.radius_mm - plan.feed_in_mm, 1e-9)
        << "the feed-in starts inside";
    EXPECT_NEAR(path.segments()[1].sweep_rad,
                static_cast<int>(d) * (2 * 3.14159265358979 + 2 * 30.0 * 3.14159265358979 / 180), 1e-9);
  }
  // G18: words Z X for the end point, K I for the centre offsets from the block's start.
  auto word = [](const std::string& line, char w) {
    const auto at = line.find(std::string(" ") + w);
    return at == std::string::npos ? std::optional<double>() : std::optional<double>(std::stod(line.substr(at + 2)));
  };
  std::istringstream in(g);
  std::string line;
  std::vector<Eigen::Vector2d> ends;  // (Z, X) at the end of each direction's last arc
  Eigen::Vector2d at(0, 0);
  int arcs = 0;
  while (std::getline(in, line)) {
    if (line.rfind("G0 ", 0) == 0) {
      if (auto z = word(line, 'Z')) at.x() = *z;
      if (auto x = word(line, 'X')) at.y() = *x;
    }
    if (line.rfind("G2 ", 0) != 0 && line.rfind("G3 ", 0) != 0) continue;
    ++arcs;
    const Eigen::Vector2d end(*word(line, 'Z'), *word(line, 'X'));
    const Eigen::Vector2d centre = at + Eigen::Vector2d(*word(line, 'K'), *word(line, 'I'));
    EXPECT_NEAR((end - centre).norm(), (at - centre).norm(), 2e-4) << line;  // a true arc (4 decimals)
    at = end;
    if (line.find("G4") == std::string::npos) ends.push_back(end);
  }
  EXPECT_EQ(arcs, 2 * (1 + 3 + 1));  // per direction: feed-in, 420 deg in 3 pieces, feed-out
  const auto last_ccw = circlePath(plan, processing::CircleDirection::kCcw).end();
  EXPECT_NEAR(ends[4].x(), last_ccw.z(), 1e-4);
  EXPECT_NEAR(ends[4].y(), last_ccw.x(), 1e-4);
}

}  // namespace
}  // namespace mtcal::acquisition
