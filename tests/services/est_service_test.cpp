#include "mtcal/services/est.h"

#include <gtest/gtest.h>

#include <fstream>

#include "../support/temp_dir.h"
#include "../support/time_scale.h"
#include "mtcal/error.h"
#include "mtcal/services/archive.h"
#include "service_support.h"

// Straightness by error separation through services: readings with a known answer, and a
// probe stepping run on the simulated machine as a front end runs it.
namespace mtcal::services {
namespace {

// A guideway bent as the parabola 2e-5 x^2 um under a carriage that does not move: the
// two-probe separation returns the profile up to a straight line, which no straightness
// value sees.
TEST(EstService, TwoProbesRecoverAKnownProfile) {
  ProbeReadings r;
  const double d = 20.0;
  std::vector<double> truth;
  for (int k = 0; k <= 20; ++k) {
    const double x = d * k;
    r.x_mm.push_back(x);
    truth.push_back(2e-5 * x * x);
    r.v1_um.push_back(2e-5 * x * x);
    r.v2_um.push_back(2e-5 * (x + d) * (x + d));
  }
  const auto a = separate(r, {"two-probe", "carriage-at-rest", d});
  const auto expected = processing::evaluateStraightness(r.x_mm, truth);
  EXPECT_NEAR(a.straightness.min_zone_um, expected.min_zone_um, 1e-9);
  EXPECT_NEAR(a.straightness.least_squares_um, expected.least_squares_um, 1e-9);
  // A parabola's minimum zone over [0, L] is its sagitta against the chord: 2e-5 (L/2)^2.
  EXPECT_NEAR(a.straightness.min_zone_um, 2e-5 * 200.0 * 200.0, 1e-9);
  EXPECT_EQ(a.document()["schema_version"], 1);
  EXPECT_FALSE(a.document().contains("run_id"));                                  // from a file: nothing stored
  EXPECT_THROW(separate(r, {"three-probe", "carriage-at-rest", d}), InputError);  // no third probe
}

TEST(EstService, ARunIsStoredWithItsSeparationInstrumentAndOperator) {
  const mtcal::testing::TempDir dir;
  mtcal::testing::RecordingObserver observer;
  Session session({dir.file("e.sqlite"), "A. Tester", &observer, nullptr, nullptr});
  EstRunRequest request;
  request.plan = acquisition::EstPlan::load(MTCAL_EXAMPLES_DIR "/plans/est/x_guideway_two_probe.json");
  request.simulation.time_scale = mtcal::testing::timeScale(3000.0);
  const auto r = runEst(session, request);
  EXPECT_EQ(r.status, "completed");
  EXPECT_EQ(r.steps, static_cast<std::size_t>(request.plan.points));
  ASSERT_TRUE(r.analysis.has_value());
  EXPECT_EQ(r.analysis->method.method, "two-probe");
  EXPECT_EQ(r.analysis->result.x_mm.size(), r.steps);
  // One progress report per step, the last complete.
  ASSERT_EQ(observer.progress.size(), r.steps);
  EXPECT_EQ(observer.progress.back().done, r.steps);
  EXPECT_EQ(observer.progress.back().total, r.steps);
  // The stored result is the analysis' document.
  const auto results = session.store().results(r.run_id);
  ASSERT_EQ(results.size(), 1u);
  EXPECT_EQ(results.front().id, r.analysis->result_id);
  EXPECT_EQ(nlohmann::json::parse(results.front().output_json), r.analysis->document());
  // Who measured, with what.
  const auto shown = showRun(session, r.run_id);
  EXPECT_EQ(shown.run.operator_name, "A. Tester");
  EXPECT_EQ(shown.run.measurement_count, static_cast<std::int64_t>(r.steps));
  ASSERT_EQ(shown.instruments.size(), 1u);
  EXPECT_EQ(shown.instruments.front().info.kind, "probes");
  EXPECT_EQ(shown.instruments.front().role, "measuring");
  EXPECT_FALSE(shown.instruments.front().info.serial.empty());
  // Again by the frequency method: a second result of the same run.
  const auto again = analyzeEst(session, r.run_id, {"frequency", "carriage-at-rest", 0.0});
  EXPECT_EQ(again.method.spacing_mm, request.plan.spacing_mm);  // the plan's
  EXPECT_EQ(session.store().results(r.run_id).size(), 2u);
  EXPECT_THROW(analyzeEst(session, r.run_id, {"three-probe", "carriage-at-rest", 0.0}), InputError);
  EXPECT_EQ(session.store().results(r.run_id).size(), 2u);  // a refused analysis stores nothing
}

// Readings from another program, imported as a run: its separation is the file's.
TEST(EstService, ImportedReadingsSeparateAsTheFileDoes) {
  const mtcal::testing::TempDir dir;
  Session session({dir.file("e.sqlite"), "", nullptr, nullptr, nullptr});
  const std::string file = MTCAL_EXAMPLES_DIR "/est/guideway_400mm.csv";
  const auto imported = importEst(session, file, 20.0, "", "imported");
  EXPECT_EQ(imported.probes, 3);
  const auto stored = analyzeEst(session, imported.run_id, {"three-probe", "carriage-at-rest", 0.0});
  const auto direct = separate(readProbeCsv(file, true), {"three-probe", "carriage-at-rest", 20.0});
  ASSERT_EQ(stored.result.profile_um.size(), direct.result.profile_um.size());
  for (std::size_t k = 0; k < direct.result.profile_um.size(); ++k) {
    EXPECT_NEAR(stored.result.profile_um[k], direct.result.profile_um[k], 1e-9) << k;
  }
  EXPECT_EQ(showRun(session, imported.run_id).run.source, "imported");
  EXPECT_THROW(importEst(session, file, 30.0, "", "imported"), InputError);  // not a whole number of 20 mm steps
  EXPECT_EQ(listRuns(session).size(), 1u);                                   // nothing stored by the refusal
}

}  // namespace
}  // namespace mtcal::services
