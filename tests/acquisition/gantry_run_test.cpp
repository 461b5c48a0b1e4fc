// Gantry point accuracy on the simulated gantry (examples/machines/gantry-drilling.json):
// the laser tracker emulator on 127.0.0.1, the real driver over TCP, SQLite, then the
// patent's evaluation, against the truth the session captures (../support/gantry_session.h).

#include "mtcal/acquisition/gantry_run.h"

#include <gtest/gtest.h>

#include <fstream>
#include <nlohmann/json.hpp>
#include <tuple>

#include "../support/gantry_session.h"
#include "mtcal/acquisition/gantry_measurements.h"
#include "mtcal/acquisition/gantry_plan.h"
#include "mtcal/error.h"
#include "mtcal/mocks/tracker_emulator.h"
#include "mtcal/services/workshop.h"

namespace mtcal::acquisition {
namespace {

using mtcal::testing::GantrySession;
using mtcal::testing::runSession;
using mtcal::testing::truthUm;

mocks::VirtualMachineConfig gantryMachine() {
  const std::string path = std::string(MTCAL_EXAMPLES_DIR) + "/machines/gantry-drilling.json";
  return mocks::VirtualMachineConfig::fromJson(nlohmann::json::parse(std::ifstream(path)), path);
}

GantryPlan smallPlan() {
  GantryPlan p;
  p.name = "test gantry";
  p.integration_ms = 50;
  p.points_per_face = 4;
  p.gantry_from_mm = 0.0;
  p.gantry_to_mm = 2000.0;
  p.track_rate_hz = 50;
  p.c_sweep_deg = {0, 60, 120, 180, 240, 300};
  p.a_sweep_deg = {-30, -15, 0, 15, 30};
  p.gantry_positions_mm = {600.0, 1800.0};
  p.hole_y_mm = {500.0, 1000.0, 3};
  p.hole_z_mm = {-500.0, -100.0, 2};
  p.settle_s = 2.0;  // the simulated machine is exactly settled after 40 x 0.05 s: reproducible readings
  p.monte_carlo_trials = 0;
  return p;
}

TEST(GantryRun, NoiseFreeTrackerGivesTheMachinesTruthAndThePatentsTcp0MissesTheAxisOffset) {
  const GantryPlan plan = smallPlan();
  const GantrySession run = runSession(plan, gantryMachine(), {0, 0, 0, 0, 25, 0, 100, 0});
  ASSERT_EQ(run.result.outcome, RunOutcome::kCompleted) << run.result.reason;
  // 4 tops + 2 sides x 4 points, 2 passes, 6 + 5 sweep points, TCP + 3 targets, 12 holes x 3.
  ASSERT_EQ(run.measured.holes.size(), 12u);
  const Eigen::Vector3d initial_np = run.measured.initial_np_mm;
  // TCP0 from the tool-point nest: the motion of the actual tool point, to the protocol's
  // 1 nm resolution amplified by the targets' lever arms (the tool point is ~300 mm from them).
  const auto ev = processing::evaluateGantry(run.measured, {.tcp0 = processing::Tcp0Source::kToolPoint});
  double largest = 0.0;
  for (std::size_t i = 0; i < run.holes.size(); ++i) {
    const Eigen::Vector3d truth = truthUm(run, ev, run.holes[i], initial_np);
    EXPECT_LT((ev.holes[i].dp_um - truth).norm(), 5e-3) << run.holes[i].id;
    largest = std::max(largest, truth.norm());
  }
  EXPECT_GT(largest, 30.0);
  // The patent's TCP0 from the axes: the A axis passes 25 um beside the C axis (EY0A) and
  // the head's location errors put the tool off the C axis; the common perpendicular shows
  // the offset, and the holes with a tilted head inherit the swung difference.
  const auto patent = processing::evaluateGantry(run.measured);
  EXPECT_NEAR(patent.axes.distance_mm * 1000.0, 25.0, 1.5);
  ASSERT_TRUE(patent.tcp0_axes_minus_tool_point_um.has_value());
  EXPECT_GT(patent.tcp0_axes_minus_tool_point_um->norm(), 5.0);
  EXPECT_LT(patent.gantry_line_rms_um, 20.0);
}

TEST(GantryRun, ACncThatDoesNotReportItsTimesRunsWithTheOperatorConfirming) {
  // A real CNC runs the NC program and says nothing: the operator confirms each position and
  // the end of each pass; the passes keep their still ends. Same truth as above.
  const GantryPlan plan = smallPlan();
  const GantrySession run = runSession(plan, gantryMachine(), {0, 0, 0, 0, 25, 0, 100, 0}, {}, 5, 400.0, true);
  ASSERT_EQ(run.result.outcome, RunOutcome::kCompleted) << run.result.reason;
  const auto ev = processing::evaluateGantry(run.measured, {.tcp0 = processing::Tcp0Source::kToolPoint});
  ASSERT_EQ(ev.holes.size(), run.holes.size());
  for (std::size_t i = 0; i < run.holes.size(); ++i) {
    EXPECT_LT((ev.holes[i].dp_um - truthUm(run, ev, run.holes[i], run.measured.initial_np_mm)).norm(), 5e-3)
        << run.holes[i].id;
  }
  // Without anybody to confirm, the run stops at the first wait, saying why, and keeps the faces.
  mocks::VirtualMachineConfig config = gantryMachine();
  mtcal::testing::TempDir dir;
  storage::Store store((dir.path() / "s.sqlite").string());
  mocks::WorldClock clock(mtcal::testing::timeScale(400.0), mocks::WorldClock::Mode::kLockStep);
  services::WorldRunClock run_clock(clock);
  mocks::VirtualMachine machine(config, clock);
  mtcal::testing::SilentController silent(machine);
  mocks::TrackerEmulator emulator(machine, mocks::TrackerEmulatorConfig::forGantry(config, 5));
  auto tracker_device = emulator.connect("mock://tracker");
  drivers::tracker::TrackerDevice& tracker = *tracker_device;
  GantryRunOptions options;
  options.place_reflector = [&](const std::string& place) { emulator.placeReflector(place); };
  options.run_clock = &run_clock;
  const auto result = runGantryTest(store, store.addCampaign(store.ensureMachine("g", "", "{}"), "c"), tracker, silent,
                                    plan, config.kinematics(), options);
  EXPECT_EQ(result.outcome, RunOutcome::kInterrupted);
  EXPECT_NE(result.reason.find("nobody confirms them: the start of the passes"), std::string::npos) << result.reason;
  EXPECT_EQ(result.points, 4u * 4u + 2u * 4u);  // the corner faces
}

TEST(GantryRun, RealisticNoiseStaysWithinTheMonteCarloUncertainty) {
  const GantryPlan plan = smallPlan();
  mocks::TrackerNoise noise;
  noise.outlier_probability = 0.0;
  const GantrySession run = runSession(plan, gantryMachine(), noise);
  ASSERT_EQ(run.result.outcome, RunOutcome::kCompleted) << run.result.reason;
  const processing::GantryOptions options{.tcp0 = processing::Tcp0Source::kToolPoint};
  const auto ev = processing::evaluateGantry(run.measured, options);
  // The emulator's noise at 50 ms (sigma_1s x sqrt(1.5)) is inside the default MPE / 2.
  const auto u = processing::monteCarloGantry(run.measured, options, processing::TrackerMpe{}, 100, 1);
  int outside = 0;
  for (std::size_t i = 0; i < run.holes.size(); ++i) {
    const Eigen::Vector3d error = ev.holes[i].dp_um - truthUm(run, ev, run.holes[i], run.measured.initial_np_mm);
    for (int k = 0; k < 3; ++k) outside += std::abs(error(k)) > 2.0 * u.holes[i].dp_sigma_um(k) ? 1 : 0;
  }
  EXPECT_LE(outside, 3);  // of 36 components: 2 sigma of the MPE's budget, which exceeds the noise
  EXPECT_GT(u.max_norm_u95_um, 5.0);
}

TEST(GantryRun, TheSameSeedGivesTheSameMeasurements) {
  // The emulator's default noise, outliers included; the world runs in lock step with the run.
  const auto a = runSession(smallPlan(), gantryMachine(), mocks::TrackerNoise{});
  const auto b = runSession(smallPlan(), gantryMachine(), mocks::TrackerNoise{});
  ASSERT_EQ(a.result.outcome, RunOutcome::kCompleted) << a.result.reason;
  EXPECT_EQ(measurementsToJson(a.measured), measurementsToJson(b.measured));
  const auto c = runSession(smallPlan(), gantryMachine(), mocks::TrackerNoise{}, {}, 6);
  EXPECT_NE(measurementsToJson(a.measured), measurementsToJson(c.measured));
}

TEST(GantryRun, ABrokenBeamInterruptsTheRunAndKeepsTheHolesDone) {
  const GantrySession run = runSession(smallPlan(), gantryMachine(), {0, 0, 0, 0, 25, 0, 100, 0},
                                       [](mocks::TrackerEmulator& e, const std::string& feature) {
                                         if (feature == "hole g1-h02 (2 of 12)") e.breakBeam();
                                       });
  EXPECT_EQ(run.result.outcome, RunOutcome::kInterrupted);
  EXPECT_NE(run.result.reason.find("MEAS 50: error 4 (beam broken)"), std::string::npos) << run.result.reason;
  // Everything up to the first hole is stored and evaluates.
  ASSERT_EQ(run.measured.holes.size(), 1u);
  EXPECT_EQ(run.measured.holes[0].id, "g1-h01");
  const auto ev = processing::evaluateGantry(run.measured);
  EXPECT_EQ(ev.holes.size(), 1u);
}

TEST(GantryPlanFile, ValidatesAndWritesTheNcProgram) {
  const GantryPlan plan = smallPlan();
  const auto back = GantryPlan::fromJson(plan.toJson(), "plan");
  EXPECT_EQ(back.toJson(), plan.toJson());
  auto bad = plan.toJson();
  bad["targets"] = {"TB1", "TB2"};
  EXPECT_THROW(GantryPlan::fromJson(bad, "p.json"), InputError);
  // A target twice (the frame's three points would coincide, found only after the run), a tool
  // of 1e300 mm (found as an infinite dP after it).
  for (const auto& [key, value, why] : std::vector<std::tuple<std::string, nlohmann::json, std::string>>{
           {"targets", nlohmann::json{"TB1", "TB1", "TB2"}, "p.json: key 'targets': 'TB1' is given twice"},
           {"tool_length_mm", 1e300, "p.json: key 'tool_length_mm': 1e+300 mm: a tool is at most 2000 mm long"}}) {
    bad = plan.toJson();
    bad[key] = value;
    try {
      GantryPlan::fromJson(bad, "p.json");
      ADD_FAILURE() << key;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(why), std::string::npos) << e.what();
    }
  }
  bad = plan.toJson();
  bad["reflector"] = "RRR2";
  try {
    GantryPlan::fromJson(bad, "p.json");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("p.json: key 'reflector'"), std::string::npos) << e.what();
  }
  const auto kinematics = gantryMachine().kinematics();
  const auto holes = planHoles(plan, kinematics);
  ASSERT_EQ(holes.size(), 12u);
  // The programmed tool point is where the plan put it, whatever the head's orientation.
  EXPECT_NEAR(holes[4].np_mm.x(), 600.0, 1e-9);
  EXPECT_NEAR(holes[4].np_mm.y(), 1500.0, 1e-9);
  EXPECT_NEAR(holes[4].np_mm.z(), -600.0, 1e-9);
  // Orientation [20, 45]: A 20 deg about X, then C 45 deg about Z: the tool vector (tip to
  // spindle) is Rz(45) Rx(20) (0, 0, 1).
  const double a = 20.0 * std::numbers::pi / 180.0, c = 45.0 * std::numbers::pi / 180.0;
  EXPECT_LT((holes[3].tool_vector - Eigen::Vector3d(std::sin(a) * std::sin(c), -std::sin(a) * std::cos(c), std::cos(a)))
                .norm(),
            1e-12);
  const std::string nc = gantryGcode(plan, holes);
  EXPECT_NE(nc.find("G0 X"), std::string::npos);
  // Header 3, start 3, 2 passes, initial state 1, C sweep 6 x 2 + 1, A sweep 5 x 2 + 1, the
  // initial state's M0 1, 2 positions, 12 holes x 2, end 2.
  EXPECT_EQ(std::count(nc.begin(), nc.end(), '\n'), 3 + 3 + 2 + 1 + 13 + 11 + 1 + 2 + 24 + 2);
  EXPECT_NE(nc.find("G1 X2000.000 F3000 (gantry pass 1)"), std::string::npos);
  EXPECT_NE(nc.find("G0 A-30.000"), std::string::npos);
}

TEST(GantryMeasurementFile, RoundTripsAndNamesWhatIsWrong) {
  processing::GantryMeasurements m;
  m.reflector_radius_mm = 19.05;
  m.origin_corner = "A";
  m.corners = {{"A", {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}, {{0, 0, -1}}, {{0, 0, -2}}}};
  m.gantry_passes = {{-1, {{1, 2, 3}, {4, 5, 6}}}};
  m.c_sweep = {{1, 1, 1}};
  m.a_sweep = {{2, 2, 2}};
  m.tool_length_mm = 300;
  m.tool_point = Eigen::Vector3d(7, 8, 9);
  m.initial_targets = {{1, 0, 0}};
  m.initial_np_mm = {0, 1500, -550};
  m.holes = {{"h1", 2, {1, 2, 3}, {0, 0, 1}, {{4, 5, 6}}}};
  const auto back = measurementsFromJson(measurementsToJson(m), "file");
  EXPECT_EQ(measurementsToJson(back), measurementsToJson(m));
  auto j = measurementsToJson(m);
  j["holes"][0]["targets"][0] = {1, "x", 3};
  try {
    measurementsFromJson(j, "m.json");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("holes[0].targets[0]"), std::string::npos) << e.what();
  }
  j = measurementsToJson(m);
  j["version"] = 2;
  EXPECT_THROW(measurementsFromJson(j, "m.json"), InputError);
  // A key mistyped is not read as absent (the tool point's nest check left out without a word);
  // two holes of one id are refused.
  const auto refusal = [&](const nlohmann::json& file) {
    try {
      measurementsFromJson(file, "m.json");
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  j = measurementsToJson(m);
  j["tool_pointt"] = j["tool_point"];
  EXPECT_EQ(refusal(j).rfind("m.json: key 'tool_pointt': not a key of a measurement file (its keys: ", 0), 0u)
      << refusal(j);
  j = measurementsToJson(m);
  j["holes"][0]["np"] = {1, 2, 3};
  EXPECT_EQ(refusal(j).rfind("m.json: key 'holes[0].np': not a key of holes[0] (its keys: ", 0), 0u) << refusal(j);
  j = measurementsToJson(m);
  j["holes"].push_back(j["holes"][0]);
  EXPECT_EQ(refusal(j), "m.json: key 'holes[1].id': 'h1' is another hole's id too: each names one");
}

}  // namespace
}  // namespace mtcal::acquisition
