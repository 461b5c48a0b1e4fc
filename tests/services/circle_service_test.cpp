#include <fmt/format.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>

#include "../support/temp_dir.h"
#include "../support/time_scale.h"
#include "mtcal/error.h"
#include "mtcal/services/archive.h"
#include "mtcal/services/circle.h"
#include "service_support.h"

// Circular tests through services: a run on the simulated demo machine with its progress, the
// stored results equal to the documents returned, an imported export evaluated.
namespace mtcal::services {
namespace {

TEST(CircleService, RunsATestReportsEachDirectionAndStoresItsResults) {
  const mtcal::testing::TempDir dir;
  mtcal::testing::RecordingObserver recorder;
  Session session({dir.file("c.sqlite"), "", &recorder, nullptr, nullptr});
  const auto r = runCircle(session, mtcal::testing::quickCircleRequest());
  ASSERT_EQ(r.status, "completed") << r.reason;
  EXPECT_EQ(r.lost_samples, 0u);
  ASSERT_EQ(recorder.progress.size(), 2u);  // counter-clockwise, then clockwise
  EXPECT_EQ(recorder.progress[1].done, 2u);
  EXPECT_EQ(recorder.progress[1].total, 2u);
  ASSERT_TRUE(r.iso230_4 && r.ballbar);
  // The demo machine's servo loops: X 30 /s, Y 30.5 /s -> X lags 1/30 - 1/30.5 s; lost motion 2.5 um per axis.
  EXPECT_NEAR(*r.ballbar->diagnosis.servo_mismatch_ms, 1000.0 / 30.0 - 1000.0 / 30.5, 0.03);
  EXPECT_NEAR(*r.ballbar->diagnosis.backlash_first_um, 2.5, 0.2);
  const auto results = session.store().results(r.run_id);
  ASSERT_EQ(results.size(), 2u);
  EXPECT_EQ(nlohmann::json::parse(results[0].output_json), r.iso230_4->document());
  EXPECT_EQ(nlohmann::json::parse(results[1].output_json), r.ballbar->document());
  EXPECT_EQ(r.document()["ballbar"]["diagnosis"]["backlash_x_um"], r.ballbar->document()["diagnosis"]["backlash_x_um"]);
}

// A circle that would leave the machine's travel is refused before anything moves: a run stopped
// there could never be resumed.
TEST(CircleService, ACircleOutsideTheTravelIsRefusedBeforeAnythingMoves) {
  const mtcal::testing::TempDir dir;
  Session session({dir.file("c.sqlite"), "", nullptr, nullptr, nullptr});
  auto request = mtcal::testing::quickCircleRequest();
  request.plan_path = "far.json";
  request.plan.centre_mm.x() = 650.0;  // the demo machine's X ends at 700 mm
  try {
    runCircle(session, request);
    FAIL() << "ran a circle beyond the travel";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("far.json: the circle (centre_mm, radius_mm, arc and overshoot, feed_in_mm) "
                                         "needs X at 7"),
              std::string::npos)
        << e.what();
  }
  EXPECT_FALSE(std::filesystem::exists(dir.file("c.sqlite")));
}

// The real-machine workflow on the simulated one (--triggered): the virtual CNC runs the part
// program and the run is captured from the stream; the demo machine's servo mismatch and lost
// motion come out as from the controlled run, the plan is stored with its capture and the
// crossings timed in the events.
TEST(CircleService, APartProgramRunByTheVirtualCncIsCapturedAndEvaluated) {
  const mtcal::testing::TempDir dir;
  mtcal::testing::RecordingObserver recorder;
  Session session({dir.file("c.sqlite"), "", &recorder, nullptr, nullptr});
  auto request = mtcal::testing::quickCircleRequest();
  request.triggered = true;
  const auto r = runCircle(session, request);
  ASSERT_EQ(r.status, "completed") << r.reason;
  ASSERT_TRUE(r.iso230_4 && r.ballbar);
  EXPECT_NEAR(*r.ballbar->diagnosis.servo_mismatch_ms, 1000.0 / 30.0 - 1000.0 / 30.5, 0.03);
  EXPECT_NEAR(*r.ballbar->diagnosis.backlash_first_um, 2.5, 0.2);
  // Its angles timed from the feed-in, the loops' lag is not read from the reversals: no radius
  // correction, and the note says why (the stored plan's capture decides).
  const auto& notes = r.ballbar->diagnosis.notes;
  EXPECT_TRUE(std::any_of(notes.begin(), notes.end(), [](const std::string& n) {
    return n.rfind("scale not corrected for the servo loops' radius reduction", 0) == 0;
  })) << fmt::format("{}", fmt::join(notes, "\n"));
  EXPECT_FALSE(std::any_of(notes.begin(), notes.end(),
                           [](const std::string& n) { return n.rfind("scale corrected for", 0) == 0; }));
  ASSERT_EQ(recorder.progress.size(), 2u);
  const auto shown = showRun(session, r.run_id);
  EXPECT_EQ(nlohmann::json::parse(shown.run.plan_json)["capture"], "part program");
  int timed = 0;
  for (const auto& e : shown.events) timed += e.message.find("feed-in at") != std::string::npos;
  EXPECT_EQ(timed, 2);
}

TEST(CircleService, EvaluatesAnImportedExportAndRefusesOtherRuns) {
  const mtcal::testing::TempDir dir;
  Session session(mtcal::testing::onArchive(dir.file("c.sqlite")));
  acquisition::CircleImportOptions options;
  options.radius_mm = 100;
  options.feed_mm_per_min = 1000;
  const auto imported = importCircle(session, MTCAL_EXAMPLES_DIR "/circle/xy_r100_export.csv", options);
  EXPECT_GT(imported.points, 100u);
  const auto iso = analyzeIso230_4(session, imported.run_id);
  EXPECT_EQ(iso.document()["run_id"], imported.run_id);
  EXPECT_TRUE(iso.result.h_um.has_value());
  // The export was made with +25 urad of squareness (examples/generate/circle_export.py).
  const auto ballbar = analyzeBallbar(session, imported.run_id);
  ASSERT_TRUE(ballbar.diagnosis.squareness_urad.has_value());
  EXPECT_NEAR(*ballbar.diagnosis.squareness_urad, 25.0, 0.5);
  EXPECT_EQ(session.store().results(imported.run_id).size(), 2u);
  EXPECT_THROW(analyzeIso230_4(session, imported.run_id + 1), Error);
}

}  // namespace
}  // namespace mtcal::services
