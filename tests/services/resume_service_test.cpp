// Every run kind stopped part-way (the operator's Ctrl-C, through the session's stop flag) and
// continued by mtcal resume: what was stored is kept, the rest measured, the run completes,
// and its events tell the story.

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <set>
#include <string>

#include "../support/temp_dir.h"
#include "../support/time_scale.h"
#include "mtcal/acquisition/thermal_data.h"
#include "mtcal/error.h"
#include "mtcal/processing/thermal_model.h"
#include "mtcal/services/resume.h"
#include "service_support.h"

namespace mtcal::services {
namespace {

/// Presses Ctrl-C once `after` steps of the operation are done.
struct StopAfter final : Observer {
  StopAfter(std::atomic<bool>& stop, std::size_t after) : stop_(stop), after_(after) {}
  void onProgress(const Progress& p) override {
    if (p.done >= after_) stop_ = true;
  }

 private:
  std::atomic<bool>& stop_;
  std::size_t after_;
};

bool hasEvent(Session& session, storage::Id run, const std::string& text) {
  for (const auto& e : session.store().events(run)) {
    if (e.message.find(text) != std::string::npos) return true;
  }
  return false;
}

/// The session that runs until `after` steps, and the one that resumes.
struct Sessions {
  explicit Sessions(const std::string& db, std::size_t after)
      : stopper(stop, after), first({db, "", &stopper, nullptr, &stop}), again(mtcal::testing::onArchive(db)) {}
  std::atomic<bool> stop{false};
  StopAfter stopper;
  Session first, again;
};

TEST(ResumeService, ACircularTestContinuesWithTheDirectionItHasNotMeasured) {
  const mtcal::testing::TempDir dir;
  Sessions s(dir.file("r.sqlite"), 1);
  const auto request = mtcal::testing::quickCircleRequest();
  const auto stopped = runCircle(s.first, request);
  ASSERT_EQ(stopped.status, "interrupted");
  const auto ccw_points = stopped.points;
  EXPECT_GT(ccw_points, 100u);
  const auto resumed = std::get<CircleRunResult>(resumeRun(s.again, stopped.run_id, request.simulation));
  ASSERT_EQ(resumed.status, "completed") << resumed.reason;
  EXPECT_EQ(resumed.run_id, stopped.run_id);
  std::set<std::string> directions;
  for (const auto& p : s.again.store().circlePoints(stopped.run_id)) directions.insert(p.direction);
  EXPECT_EQ(directions, (std::set<std::string>{"ccw", "cw"}));
  EXPECT_GT(resumed.points, ccw_points);
  // The samples are this session's: the one direction it streamed, fewer than the run's points.
  EXPECT_TRUE(resumed.resumed);
  EXPECT_EQ(resumed.document()["resumed"], true);
  EXPECT_LT(resumed.samples, resumed.points);
  EXPECT_GT(resumed.samples, resumed.points - ccw_points);
  EXPECT_FALSE(stopped.document().contains("resumed"));
  // The same machine (the demo, seed 1): the lost motion and the servo mismatch as in one go.
  ASSERT_TRUE(resumed.ballbar);
  EXPECT_NEAR(*resumed.ballbar->diagnosis.backlash_first_um, 2.5, 0.2);
  EXPECT_NEAR(*resumed.ballbar->diagnosis.servo_mismatch_ms, 1000.0 / 30.0 - 1000.0 / 30.5, 0.03);
  EXPECT_TRUE(hasEvent(s.again, stopped.run_id, "1 of 2 directions were measured before"));
  EXPECT_TRUE(hasEvent(s.again, stopped.run_id, "run completed"));
}

TEST(ResumeService, AProbeSteppingRunKeepsItsStepsAndMeasuresTheRest) {
  const mtcal::testing::TempDir dir;
  Sessions s(dir.file("r.sqlite"), 5);
  EstRunRequest request;
  request.plan = acquisition::EstPlan::load(MTCAL_EXAMPLES_DIR "/plans/est/x_guideway_two_probe.json");
  request.simulation.time_scale = mtcal::testing::timeScale(3000.0);
  const auto stopped = runEst(s.first, request);
  ASSERT_EQ(stopped.status, "interrupted");
  EXPECT_EQ(stopped.steps, 5u);
  const auto before = s.again.store().probeSteps(stopped.run_id);
  const auto resumed = std::get<EstRunResult>(resumeRun(s.again, stopped.run_id, request.simulation));
  ASSERT_EQ(resumed.status, "completed");
  EXPECT_EQ(resumed.steps, static_cast<std::size_t>(request.plan.points));
  const auto after = s.again.store().probeSteps(stopped.run_id);
  for (std::size_t k = 0; k < before.size(); ++k) {  // what was stored stays as it was
    EXPECT_EQ(after[k].step, before[k].step);
    EXPECT_EQ(after[k].channels[0].value_um, before[k].channels[0].value_um);
  }
  // Against the same separation of an uninterrupted run of the same machine.
  Session whole(mtcal::testing::onArchive(dir.file("whole.sqlite")));
  const auto reference = runEst(whole, request);
  ASSERT_TRUE(resumed.analysis && reference.analysis);
  EXPECT_NEAR(resumed.analysis->straightness.min_zone_um, reference.analysis->straightness.min_zone_um, 0.2);
  EXPECT_TRUE(hasEvent(s.again, stopped.run_id, "5 of 21 steps were measured before"));
}

TEST(ResumeService, AGantryRunContinuesFromTheFeatureItStoppedAt) {
  const mtcal::testing::TempDir dir;
  Sessions s(dir.file("r.sqlite"), 8);
  auto request = mtcal::testing::quickGantryRequest();
  const auto stopped = runGantry(s.first, request);
  ASSERT_EQ(stopped.status, "interrupted");
  EXPECT_NE(stopped.reason.find("stopped by the user"), std::string::npos) << stopped.reason;
  SimulationOptions resume_options;
  resume_options.time_scale = request.simulation.time_scale;
  const auto resumed = std::get<GantryRunResult>(resumeRun(s.again, stopped.run_id, resume_options));
  ASSERT_EQ(resumed.status, "completed") << resumed.reason;
  ASSERT_TRUE(resumed.analysis);
  EXPECT_EQ(resumed.analysis->evaluation.holes.size(), 12u);
  // Every feature once: as many points as a run in one go, the features of the first session
  // exactly as they were.
  Session whole(mtcal::testing::onArchive(dir.file("whole.sqlite")));
  request.evaluation.trials = 200;  // the evaluation's uncertainty from the tracker's MPE
  const auto reference = runGantry(whole, request);
  EXPECT_EQ(resumed.points, reference.points);
  ASSERT_TRUE(reference.analysis && reference.analysis->uncertainty);
  const auto a = s.again.store().trackerPoints(stopped.run_id), b = whole.store().trackerPoints(reference.run_id);
  for (std::size_t i = 0; i < a.size() && a[i].feature.rfind("pass:2", 0) != 0; ++i) EXPECT_EQ(a[i].x_mm, b[i].x_mm);
  // The second session's points carry other draws of the tracker's noise: the two evaluations
  // of the holes differ by at most what two independent ones would, sqrt(2) x their 95 %
  // uncertainty (seeded: the same every time).
  const auto& resumed_holes = resumed.analysis->evaluation.holes;
  const auto& reference_holes = reference.analysis->evaluation.holes;
  const auto& u = reference.analysis->uncertainty->holes;
  for (std::size_t h = 0; h < resumed_holes.size(); ++h)
    EXPECT_LT((resumed_holes[h].dp_um - reference_holes[h].dp_um).norm(), std::sqrt(2.0) * u[h].norm_u95_um) << h;
  EXPECT_TRUE(hasEvent(s.again, stopped.run_id, "features were measured before"));
}

TEST(ResumeService, AThermalRunContinuesInANewSegmentAfterItsGap) {
  const mtcal::testing::TempDir dir;
  Sessions s(dir.file("r.sqlite"), 70);
  ThermalRunRequest request;
  request.plan = acquisition::ThermalPlan::fromJson(
      nlohmann::json::parse(readTextFile(MTCAL_EXAMPLES_DIR "/plans/thermal/quick-2h.json")), "quick-2h.json");
  request.simulation.time_scale = mtcal::testing::timeScale(3000.0);
  request.simulation.seed = 5;
  const auto stopped = runThermal(s.first, request);
  ASSERT_FALSE(stopped.complete);
  EXPECT_EQ(stopped.samples, 70);
  ThermalFitRequest fit;
  fit.target = "drift_z_um";
  {
    // Fitted as it stands, the run cut short is said to be so.
    mtcal::testing::RecordingObserver seen;
    Session watched({dir.file("r.sqlite"), "", &seen, nullptr, nullptr});
    fitThermal(watched, stopped.run_id, fit);
    ASSERT_EQ(seen.warnings.size(), 1u);
    EXPECT_NE(seen.warnings[0].find(fmt::format("run {} is interrupted after 70 ", stopped.run_id)), std::string::npos)
        << seen.warnings[0];
    EXPECT_NE(seen.warnings[0].find(fmt::format("mtcal resume {}", stopped.run_id)), std::string::npos);
  }
  const auto resumed = std::get<ThermalRunResult>(resumeRun(s.again, stopped.run_id, request.simulation));
  ASSERT_TRUE(resumed.complete) << resumed.stopped_because;
  EXPECT_EQ(resumed.samples, 121);
  const auto samples = s.again.store().thermalSamples(stopped.run_id);
  ASSERT_EQ(samples.size(), 121u);
  EXPECT_EQ(samples[69].segment, 0);
  EXPECT_EQ(samples[70].segment, 1);
  EXPECT_EQ(samples[120].segment, 1);
  EXPECT_TRUE(hasEvent(s.again, stopped.run_id, "gap: the run continues at sample 70 in segment 1"));
  // The fit takes the gap as a gap: as good on the resumed run as on one without a gap.
  const auto gap = fitThermal(s.again, stopped.run_id, fit);
  Session whole(mtcal::testing::onArchive(dir.file("whole.sqlite")));
  const auto reference = runThermal(whole, request);
  ASSERT_TRUE(reference.complete);
  const auto straight = fitThermal(whole, reference.run_id, fit);
  // The same data taken as continuous (the gap ignored): the jump at the restart spoils it.
  auto blind = acquisition::thermalDataOfRun(s.again.store(), stopped.run_id, "drift_z_um");
  blind.segment.clear();
  const auto gap_blind = processing::fitThermalModel(blind);
  std::printf(
      "thermal fit: rms test %.3f um with the gap as segments, %.3f um with the gap ignored, %.3f um in one go\n",
      gap.fit.chosen.rms_test_um, gap_blind.chosen.rms_test_um, straight.fit.chosen.rms_test_um);
  EXPECT_LT(gap.fit.chosen.rms_test_um, gap_blind.chosen.rms_test_um);
  EXPECT_EQ(gap.fit.chosen.segment_level_um.size(), 2u);
  EXPECT_LT(gap.fit.chosen.rms_test_um, 2.0 * straight.fit.chosen.rms_test_um + 0.1);
}

TEST(ResumeService, WhatCannotBeResumedSaysWhy) {
  const mtcal::testing::TempDir dir;
  Session session(mtcal::testing::onArchive(dir.file("r.sqlite")));
  acquisition::CircleImportOptions options;
  options.radius_mm = 100;
  options.feed_mm_per_min = 1000;
  const auto imported = importCircle(session, MTCAL_EXAMPLES_DIR "/circle/xy_r100_export.csv", options);
  try {
    resumeRun(session, imported.run_id, {});
    FAIL() << "resumed an import";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("was imported: there is nothing to resume"), std::string::npos) << e.what();
  }
  EXPECT_THROW(resumeRun(session, 99, {}), InputError);  // no such run
}

}  // namespace
}  // namespace mtcal::services
