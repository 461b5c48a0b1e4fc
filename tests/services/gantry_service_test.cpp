#include <gtest/gtest.h>

#include <filesystem>

#include "../support/temp_dir.h"
#include "../support/time_scale.h"
#include "mtcal/error.h"
#include "mtcal/services/archive.h"
#include "mtcal/services/gantry.h"
#include "service_support.h"

// Gantry point accuracy through services: the quick plan on the simulated gantry, the
// tracker recorded with the run, progress by feature, and the export evaluating to the
// stored analysis.
namespace mtcal::services {
namespace {

TEST(GantryService, RunsRecordsTheTrackerAndExportsWhatItEvaluated) {
  const mtcal::testing::TempDir dir;
  mtcal::testing::RecordingObserver observer;
  Session session({dir.file("g.sqlite"), "B. Tester", &observer, nullptr, nullptr});
  const auto request = mtcal::testing::quickGantryRequest();
  const auto r = runGantry(session, request);
  ASSERT_EQ(r.status, "completed") << r.reason;
  ASSERT_TRUE(r.analysis.has_value());
  EXPECT_EQ(r.analysis->evaluation.holes.size(), 12u);
  EXPECT_FALSE(r.analysis->uncertainty.has_value());  // no trials asked
  // Progress: one report as each feature starts. The quick plan: 4 corners (the origin's 3
  // faces, the others' tops), 2 passes, 2 sweeps, the initial state, 12 holes.
  const std::size_t features = 3 + 3 + 2 + 2 + 1 + 12;
  // One report as each starts and one when all are measured.
  ASSERT_EQ(observer.progress.size(), features + 1);
  EXPECT_EQ(observer.progress.front().done, 0u);
  EXPECT_EQ(observer.progress[features - 1].done, features - 1);
  EXPECT_EQ(observer.progress.back().done, features);
  EXPECT_EQ(observer.progress.back().total, features);
  // The tracker is the run's instrument, with its identity.
  const auto shown = showRun(session, r.run_id);
  ASSERT_EQ(shown.instruments.size(), 1u);
  EXPECT_EQ(shown.instruments.front().info.kind, "tracker");
  EXPECT_FALSE(shown.instruments.front().info.serial.empty());
  EXPECT_EQ(shown.run.instrument_id, shown.instruments.front().instrument_id);
  EXPECT_EQ(shown.run.operator_name, "B. Tester");
  EXPECT_EQ(shown.run.measurement_count, static_cast<std::int64_t>(r.points));
  // Stored as printed; the export evaluates to the same dP.
  const auto results = session.store().results(r.run_id);
  ASSERT_EQ(results.size(), 1u);
  EXPECT_EQ(nlohmann::json::parse(results.front().output_json), r.analysis->document());
  const std::string file = dir.file("export.json");
  EXPECT_EQ(exportGantry(session, r.run_id, file), 12u);
  const auto again = evaluateGantryFile(file, request.evaluation);
  ASSERT_EQ(again.evaluation.holes.size(), 12u);
  for (std::size_t i = 0; i < 12; ++i) {
    EXPECT_LT((again.evaluation.holes[i].dp_um - r.analysis->evaluation.holes[i].dp_um).norm(), 1e-6) << i;
  }
}

TEST(GantryService, AHoleOutsideTheTravelIsRefusedBeforeAnythingMoves) {
  const mtcal::testing::TempDir dir;
  Session session({dir.file("g.sqlite"), "", nullptr, nullptr, nullptr});
  GantryRunRequest request;
  request.plan_path = "far.json";
  request.plan = acquisition::GantryPlan::fromJson(
      nlohmann::json::parse(readTextFile(MTCAL_EXAMPLES_DIR "/plans/gantry/quick-6x2.json")), request.plan_path);
  request.simulation.machine_file = MTCAL_EXAMPLES_DIR "/machines/gantry-drilling.json";
  const auto refused = [&](const std::string& because) {
    try {
      runGantry(session, request);
      ADD_FAILURE() << "ran a plan outside the travel";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(because), std::string::npos) << e.what();
    }
    EXPECT_FALSE(std::filesystem::exists(dir.file("g.sqlite")));  // no archive left behind
  };
  const auto plan = request.plan;
  request.plan.gantry_positions_mm = {500.0, 99000.0};
  refused("far.json: hole ");
  refused("outside the machine's travel");
  // The tracked pass, which a run would stop in with the frame measured: refused before it too.
  request.plan = plan;
  request.plan.gantry_to_mm = 99999.0;
  refused(
      "far.json: the tracked pass (gantry_from_mm, gantry_to_mm) needs X at 99999.000 mm, outside the "
      "machine's travel");
  // A target the simulated machine has no nest for would interrupt the run for good: refused
  // before it starts, with the places there are.
  request.plan = plan;
  request.plan.targets = {"TB1", "TB2", "TB9"};
  refused(
      "far.json: the plan puts the reflector on 'TB9', which the simulated machine has no place for (it has: "
      "TB1, TB2, TB3, TB4, TB5, TCP, A.top");
  request.plan = plan;
  request.plan.corners = {"A", "B", "E"};
  refused("'E.top'");
}

TEST(GantryService, APlanPutsTheReflectorOnEachPlaceItMeasuresOnce) {
  acquisition::GantryPlan plan;
  plan.corners = {"A", "B", "C"};
  plan.origin_corner = "B";
  plan.sweep_target = "TB2";
  plan.targets = {"TB1", "TB2", "TB3"};
  EXPECT_EQ(plan.reflectorPlaces(),
            (std::vector<std::string>{"A.top", "B.top", "B.side1", "B.side2", "C.top", "TB2", "TCP", "TB1", "TB3"}));
  plan.measure_tool_point = false;
  EXPECT_EQ(plan.reflectorPlaces().size(), 8u);
}

}  // namespace
}  // namespace mtcal::services
