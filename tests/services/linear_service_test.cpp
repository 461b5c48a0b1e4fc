#include <gtest/gtest.h>

#include <atomic>

#include "../support/temp_dir.h"
#include "../support/time_scale.h"
#include "mtcal/error.h"
#include "mtcal/services/archive.h"
#include "mtcal/services/linear.h"
#include "service_support.h"

// The linear calibration operations called as a front end calls them: a session on a
// temporary archive, an observer that records what it is told.
namespace mtcal::services {
namespace {

struct Recorder final : Observer {
  std::vector<Progress> progress;
  void onProgress(const Progress& p) override { progress.push_back(p); }
};

acquisition::LinearPlan smallPlan() { return mtcal::testing::smallLinearPlan(); }

LinearRunRequest simulated(const acquisition::LinearPlan& plan) {
  LinearRunRequest r;
  r.plans = {plan};
  r.simulation.seed = 3;
  r.simulation.time_scale = mtcal::testing::timeScale(400.0);
  return r;
}

TEST(LinearService, RunsAPlanStoresItsEvaluationAndReportsProgress) {
  const mtcal::testing::TempDir dir;
  Recorder recorder;
  Session session({dir.file("a.sqlite"), "", &recorder, nullptr, nullptr});
  const auto campaign = runLinear(session, simulated(smallPlan()));
  ASSERT_EQ(campaign.runs.size(), 1u);
  const auto& run = campaign.runs.front();
  EXPECT_EQ(run.status, "completed");
  EXPECT_EQ(run.targets, 12);  // 3 targets x 2 cycles x 2 directions
  ASSERT_TRUE(run.iso230_2.has_value());
  ASSERT_TRUE(run.simulation_check.has_value());
  EXPECT_EQ(run.simulation_check->compared_means, 6u);
  EXPECT_LT(run.simulation_check->rms_um, 0.5);  // the demo machine's 0.6 um scatter over 2 approaches
  // The stored result is the document, with its schema version and run.
  const auto results = session.store().results(run.run_id);
  ASSERT_EQ(results.size(), 1u);
  EXPECT_EQ(results.front().id, run.iso230_2->result_id);
  const auto stored = nlohmann::json::parse(results.front().output_json);
  EXPECT_EQ(stored, run.iso230_2->document());
  EXPECT_EQ(stored["schema_version"], 1);
  EXPECT_EQ(stored["run_id"], run.run_id);
  // The campaign, the run and what the archive lists agree.
  EXPECT_EQ(session.store().run(run.run_id).campaign_id, campaign.campaign_id);
  const auto listed = listRuns(session);
  ASSERT_EQ(listed.size(), 1u);
  EXPECT_EQ(runDocument(listed.front())["targets"], 12);
  EXPECT_EQ(showRun(session, run.run_id).document()["target_values"].size(), 12u);
  // One progress report per target, the last one complete; the time left once a step is done.
  ASSERT_EQ(recorder.progress.size(), 12u);
  EXPECT_EQ(recorder.progress.back().done, 12u);
  EXPECT_EQ(recorder.progress.back().total, 12u);
  EXPECT_DOUBLE_EQ(*recorder.progress.back().eta_s, 0.0);
  EXPECT_TRUE(recorder.progress.front().eta_s.has_value());
}

TEST(LinearService, AStoppedRunIsResumedToTheEnd) {
  const mtcal::testing::TempDir dir;
  std::atomic<bool> stop{false};
  struct StopAfterTwoCycles final : Observer {
    std::atomic<bool>* stop;
    void onProgress(const Progress& p) override {
      if (p.done == 12) *stop = true;
    }
  } observer;
  observer.stop = &stop;
  Session session({dir.file("a.sqlite"), "", &observer, nullptr, &stop});
  auto plan = smallPlan();
  plan.repeats = 3;
  const auto first = runLinear(session, simulated(plan));
  ASSERT_EQ(first.runs.size(), 1u);
  EXPECT_TRUE(first.interrupted());
  EXPECT_EQ(first.runs.front().targets, 12);
  EXPECT_FALSE(first.runs.front().iso230_2.has_value());
  EXPECT_EQ(first.runs.front().document()["status"], "interrupted");
  // Its figures, asked for before it is resumed, say what they stand on.
  const auto part = analyzeIso230_2(session, first.runs.front().run_id);
  ASSERT_EQ(part.warnings.size(), 2u);  // and 2 cycles of the standard's 5
  EXPECT_EQ(part.warnings[0],
            fmt::format("run {} is interrupted: 12 targets measured, part of its plan (mtcal resume {})",
                        first.runs.front().run_id, first.runs.front().run_id));
  EXPECT_EQ(part.document()["warnings"][0], part.warnings[0]);
  stop = false;
  Session again({dir.file("a.sqlite"), "", nullptr, nullptr, &stop});
  const auto resumed = resumeLinear(again, first.runs.front().run_id, mtcal::testing::timeScale(400.0));
  EXPECT_EQ(resumed.status, "completed");
  EXPECT_EQ(resumed.targets, 18);
  ASSERT_TRUE(resumed.iso230_2.has_value());
  EXPECT_EQ(resumed.iso230_2->result.positions.size(), 3u);
}

TEST(LinearService, ARealMachineNeedsAnOperatorAndAnalysisNeedsAPositioningRun) {
  const mtcal::testing::TempDir dir;
  Session session(mtcal::testing::onArchive(dir.file("a.sqlite")));
  LinearRunRequest request;
  request.plans = {smallPlan()};
  request.device_uri = "usb://1209:c417";
  try {
    runLinear(session, request);
    FAIL() << "a real machine without an operator";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("nobody to ask"), std::string::npos) << e.what();
  }
  auto pitch = smallPlan();
  pitch.measures = "EBX";
  const auto run = runLinear(session, simulated(pitch)).runs.front();
  EXPECT_EQ(run.status, "completed");
  EXPECT_FALSE(run.iso230_2.has_value());
  EXPECT_EQ(run.document()["measures"], "EBX");
  EXPECT_EQ(run.document()["unit"], "urad");
  try {
    analyzeIso230_2(session, run.run_id);
    FAIL() << "a pitch run is not ISO 230-2 material";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("measures EBX, not positioning"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace mtcal::services
