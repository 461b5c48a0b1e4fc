#include "mtcal/services/est.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>

#include "../support/temp_dir.h"
#include "../support/time_scale.h"
#include "mtcal/acquisition/diagnosis_data.h"
#include "mtcal/error.h"
#include "mtcal/processing/diagnosis.h"
#include "mtcal/services/archive.h"
#include "mtcal/services/diagnose.h"
#include "mtcal/services/export.h"
#include "service_support.h"

// Straightness by error separation through services: readings with a known answer, and a
// probe stepping run on the simulated machine as a front end runs it.
namespace mtcal::services {
namespace {

/// A run of one of the example plans (examples/plans/est) on the simulated machine, its clock fast.
EstRunRequest examplePlan(const std::string& plan) {
  EstRunRequest request;
  request.plan = acquisition::EstPlan::load(std::string(MTCAL_EXAMPLES_DIR "/plans/est/") + plan);
  request.simulation.time_scale = mtcal::testing::timeScale(3000.0);
  return request;
}

// A guideway bent as the parabola 2e-5 x^2 um under a carriage that does not move: the
// two-probe separation returns the profile up to a straight line, which no straightness
// value sees.
TEST(EstService, TwoProbesRecoverAKnownProfile) {
  ProbeReadings r;
  const double d = 20.0;
  std::vector<double> truth;
  for (int k = 0; k <= 20; ++k) {
    const double x = d * k;
    r.position_mm.push_back(x);
    truth.push_back(2e-5 * x * x);
    r.v1_um.push_back(2e-5 * x * x);
    r.v2_um.push_back(2e-5 * (x + d) * (x + d));
  }
  const auto a = separate(r, {"two-probe", "carriage-at-rest", d});
  const auto expected = processing::evaluateStraightness(r.position_mm, truth);
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
  EstRunRequest request = examplePlan("x_guideway_two_probe.json");
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

// The example plans, two and three probes on the same guideway of the simulated machine: the
// three-probe run zeroes its probes on the reference flat first (the machine's probes are
// mounted with zeros 0, 2.5 and -1.8 um: c = -6.8 um, a -1292 um parabola unzeroed) and gives
// the straightness the two probes give, within the three-probe method's propagated noise
// (0.77 um at the last step, 1 sigma), with no warning.
// Steps beyond the machine's travel are refused before anything moves: a run stopped there
// could never be resumed.
TEST(EstService, StepsOutsideTheTravelAreRefusedBeforeAnythingMoves) {
  const mtcal::testing::TempDir dir;
  Session session({dir.file("e.sqlite"), "", nullptr, nullptr, nullptr});
  auto request = examplePlan("x_guideway_three_probe.json");
  request.plan.points = 60;  // 50 mm + 59 x 20 mm: X ends at 700 mm
  try {
    runEst(session, request);
    FAIL() << "ran steps beyond the travel";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("(start_mm, step_mm, points, line_position_mm) needs X at 710.000 mm, outside "
                                         "the machine's travel [0, 700] mm"),
              std::string::npos)
        << e.what();
  }
  EXPECT_FALSE(std::filesystem::exists(dir.file("e.sqlite")));
}

TEST(EstService, TheThreeProbeExampleIsZeroedAndAgreesWithTwoProbes) {
  const mtcal::testing::TempDir dir;
  Session session({dir.file("e.sqlite"), "", nullptr, nullptr, nullptr});
  const auto two = runEst(session, examplePlan("x_guideway_two_probe.json"));
  const auto three = runEst(session, examplePlan("x_guideway_three_probe.json"));
  ASSERT_TRUE(two.analysis && three.analysis);
  ASSERT_TRUE(three.analysis->zeroing.has_value());
  // Read on the flat once the machine is on its measured line: the probes' noise (0.02 um a
  // reading), not the other axes' moves (30 um when the zeroing did not wait for them), and the
  // combination within 3 of its standard errors of the mounted -6.8 um.
  const auto& zeroing = *three.analysis->zeroing;
  double variance = 0.0;
  for (std::size_t p = 0; p < 3; ++p) {
    EXPECT_LT(zeroing.s_um[p], 0.05) << "probe " << p + 1;
    variance += std::pow(p == 1 ? 2.0 : 1.0, 2) * zeroing.s_um[p] * zeroing.s_um[p] / zeroing.readings;
  }
  EXPECT_NEAR(zeroing.combinationUm(), -6.8, 3.0 * std::sqrt(variance));
  EXPECT_TRUE(three.analysis->warnings.empty());
  const double lsq2 = two.analysis->straightness.least_squares_um, lsq3 = three.analysis->straightness.least_squares_um;
  // Analysed again without a method: the run's own, three probes' (it was two-probe).
  const auto again = analyzeEst(session, three.run_id, {"", "carriage-at-rest", 0.0});
  EXPECT_EQ(again.method.method, "three-probe");
  EXPECT_DOUBLE_EQ(again.straightness.least_squares_um, lsq3);
  EXPECT_EQ(analyzeEst(session, two.run_id, {"", "carriage-at-rest", 0.0}).method.method, "two-probe");
  EXPECT_NEAR(lsq3, lsq2, 2.0 * three.analysis->noise_um.back());
  EXPECT_LT(lsq3, 5.0);
  std::cout << "straightness of the example guideway: two probes " << lsq2 << " um, three probes zeroed " << lsq3
            << " um\n";
  // The same readings without the zeroing: the parabola, and a warning.
  auto readings = ProbeReadings{};
  for (const auto& step : session.store().probeSteps(three.run_id)) {
    readings.position_mm.push_back(step.position_mm);
    readings.v1_um.push_back(step.channels[0].value_um);
    readings.v2_um.push_back(step.channels[1].value_um);
    readings.v3_um.push_back(step.channels[2].value_um);
  }
  const auto unzeroed = separate(readings, {"three-probe", "carriage-at-rest", 20.0});
  EXPECT_GT(unzeroed.straightness.least_squares_um, 100.0);
  ASSERT_EQ(unzeroed.warnings.size(), 1u);
  EXPECT_NE(unzeroed.warnings[0].find("without a zeroing"), std::string::npos);
  // Given with the readings (an import), the zeroing is stored with the run and taken off.
  const auto z = three.analysis->zeroing->zero_um;
  readings.zeroing = givenZeroing(fmt::format("{},{},{}", z[0], z[1], z[2]));
  EXPECT_NEAR(separate(readings, {"three-probe", "carriage-at-rest", 20.0}).straightness.least_squares_um, lsq3, 1e-6);
  EXPECT_THROW(givenZeroing("1,2,x"), InputError);
  EXPECT_THROW(givenZeroing("1"), InputError);
  // Exported, the run's import command carries the zeroing: imported again, the same profile.
  const auto exported = exportRun(session, three.run_id, dir.file("out"));
  const auto at = exported.import_command.find("--zero-readings-um ");
  ASSERT_NE(at, std::string::npos) << exported.import_command;
  const auto copy = importEst(session, dir.file("out") + "/run" + std::to_string(three.run_id) + "_steps.csv", 20.0, "",
                              "imported", {}, givenZeroing(exported.import_command.substr(at + 19)));
  EXPECT_NEAR(analyzeEst(session, copy.run_id, {"three-probe", "carriage-at-rest", 0.0}).straightness.least_squares_um,
              lsq3, 1e-9);
  // The run states its noise for its diagnosis: every probe's 10 readings at each step pooled,
  // probe 3's residual carrying four readings' means, (s1^2 + 2 s2^2 + s3^2) / 10, and their
  // correlation probe 2's share; the exported file carries the scatter and the counts, so the
  // imported copy and the file diagnosed as it is state the same; a file without them nothing.
  std::array<double, 3> ss{}, dof{};
  for (const auto& step : session.store().probeSteps(three.run_id)) {
    for (std::size_t p = 0; p < 3; ++p) {
      ASSERT_EQ(step.channels[p].readings, 10);
      ss[p] += 9.0 * *step.channels[p].s_um * *step.channels[p].s_um;
      dof[p] += 9.0;
    }
  }
  const double s1 = ss[0] / dof[0], s2 = ss[1] / dof[1], s3 = ss[2] / dof[2];
  const auto stated = acquisition::diagnosisInputOfRun(session.store(), three.run_id, {}).data;
  EXPECT_NEAR(stated.stated_noise_variance, (s1 + 2 * s2 + s3) / 10.0, 1e-12);
  EXPECT_NEAR(stated.lag1_correlation, s2 / (s1 + 2 * s2 + s3), 1e-12);
  EXPECT_GT(stated.stated_noise_dof, 9.0 * static_cast<double>(three.steps));
  const auto copied = acquisition::diagnosisInputOfRun(session.store(), copy.run_id, {}).data;
  EXPECT_EQ(copied.stated_noise_variance, stated.stated_noise_variance);
  EXPECT_EQ(copied.stated_noise_dof, stated.stated_noise_dof);
  EXPECT_EQ(copied.lag1_correlation, stated.lag1_correlation);
  DiagnoseRequest from_file;
  from_file.est_csv = dir.file("out") + "/run" + std::to_string(three.run_id) + "_steps.csv";
  from_file.spacing_mm = 20.0;
  const auto file_diagnosis = diagnose(session, from_file);
  EXPECT_EQ(file_diagnosis.data.stated_noise_variance, stated.stated_noise_variance);
  EXPECT_EQ(file_diagnosis.document()["stated_error"]["what"], "noise");
  // The separation of the copy has the run's noise propagation.
  const auto copy_separation = analyzeEst(session, copy.run_id, {"three-probe", "carriage-at-rest", 0.0});
  ASSERT_EQ(copy_separation.noise_um.size(), three.analysis->noise_um.size());
  EXPECT_EQ(copy_separation.noise_um.back(), three.analysis->noise_um.back());
  const auto plain = importEst(session, MTCAL_EXAMPLES_DIR "/est/guideway_400mm.csv", 20.0, "", "imported");
  EXPECT_EQ(acquisition::diagnosisInputOfRun(session.store(), plain.run_id, {}).data.stated_noise_dof, 0.0);
}

// A file states the probes' scatter with the counts it is over, or nothing: a step read once
// has no scatter; anything else is refused naming the line and the column.
TEST(EstService, AFileStatesTheProbesScatterWithTheCountsItIsOver) {
  const mtcal::testing::TempDir dir;
  const auto read = [&](const std::string& text) {
    const auto path = dir.file("probes.csv");
    std::ofstream(path) << text;
    return readProbeCsv(path, false);
  };
  const auto refusal = [&](const std::string& text) {
    try {
      read(text);
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  const auto r = read(
      "x_mm,v1_um,v2_um,v3_um,s1_um,s2_um,s3_um,readings\n"
      "0,1,2,3,0.1,0.2,0.3,4\n"
      "20,1,2,3,,,,1\n"
      "40,1,2,3,0.4,0.5,0.6,2\n");
  EXPECT_EQ(r.readings, (std::vector<int>{4, 1, 2}));
  EXPECT_EQ(r.scatter_um[1][0], 0.2);
  EXPECT_TRUE(std::isnan(r.scatter_um[2][1]));
  // A step read once has no scatter, whatever its cell says; a file of such steps gives none,
  // and its import says so.
  EXPECT_TRUE(std::isnan(read("x_mm,v1_um,v2_um,s1_um,s2_um,readings\n0,1,2,0.1,0.2,1\n").scatter_um[0][0]));
  Session session({dir.file("e.sqlite"), "", nullptr, nullptr, nullptr});
  read("x_mm,v1_um,v2_um,s1_um,s2_um,readings\n0,1,2,,,1\n20,1,2,0.1,,1\n40,1,2,,,1\n");
  EXPECT_FALSE(importEst(session, dir.file("probes.csv"), 20.0, "once", "imported").scatter);
  read("x_mm,v1_um,v2_um,s1_um,s2_um,readings\n0,1,2,,,1\n20,1,2,0.1,0.2,3\n40,1,2,,,1\n");
  EXPECT_TRUE(importEst(session, dir.file("probes.csv"), 20.0, "thrice", "imported").scatter);
  EXPECT_EQ(r.scatter_um[2][2], 0.6);
  // Uneven steps and positions that do not increase are refused where they are.
  EXPECT_NE(refusal("x_mm,v1_um,v2_um\n0,1,2\n20,1,2\n40,1,2\n50,1,2\n")
                .find("probes.csv:5: column 'x_mm': 50 mm after 40 mm: a step of 10 mm where the file steps by 20 mm"),
            std::string::npos);
  EXPECT_NE(refusal("x_mm,v1_um,v2_um\n0,1,2\n20,1,2\n20,1,2\n")
                .find("probes.csv:4: column 'x_mm': 20 mm after 20 mm: the positions must increase"),
            std::string::npos);
  // Two probes: their scatter only.
  const auto two = read("x_mm,v1_um,v2_um,s1_um,s2_um,readings\n0,1,2,0.1,0.2,3\n20,1,2,0.1,0.2,3\n");
  EXPECT_EQ(two.scatter_um[1], (std::vector<double>{0.2, 0.2}));
  EXPECT_TRUE(two.scatter_um[2].empty());
  // The stated noise of such a file, worked by hand: 12 steps of 4 readings each, every probe's
  // s 0.2 um at every step: (s1^2 + 2 s2^2 + s3^2) / 4 = 0.04 um^2.
  std::string rows = "x_mm,v1_um,v2_um,v3_um,s1_um,s2_um,s3_um,readings\n";
  for (int k = 0; k < 12; ++k) rows += fmt::format("{},0,0,0,0.2,0.2,0.2,4\n", 20 * k);
  auto even = read(rows);
  even.spacing_mm = 20.0;
  // What the scatter makes of a separated profile: the variance of one reading (0.04 um^2) times
  // the mean of 1 / the count over the steps; with counts of 4 and 16 in turn, (1/4 + 1/16) / 2.
  std::string uneven = "x_mm,v1_um,v2_um,v3_um,s1_um,s2_um,s3_um,readings\n";
  for (int k = 0; k < 12; ++k) uneven += fmt::format("{},0,0,0,0.2,0.2,0.2,{}\n", 20 * k, k % 2 ? 16 : 4);
  EXPECT_NEAR(separate(read(uneven), {"two-probe", "carriage-at-rest", 20.0}).noise_um.back(),
              processing::twoProbeNoiseUm(11, std::sqrt(0.04 * (0.25 + 0.0625) / 2)), 1e-12);
  EXPECT_NEAR(processing::estDiagnosisData(even).stated_noise_variance, 0.04, 1e-15);
  // What is refused, and where.
  const std::string three = "x_mm,v1_um,v2_um,v3_um,s1_um,s2_um,s3_um,readings\n0,1,2,3,";
  const std::vector<std::pair<std::string, std::string>> refused{
      {"x_mm,v1_um,v2_um,v3_um,s1_um,s2_um,s3_um\n0,1,2,3,0.1,0.2,0.3\n", "missing column 'readings'"},
      {"x_mm,v1_um,v2_um,v3_um,s1_um,s2_um,readings\n0,1,2,3,0.1,0.2,3\n", "missing column 's3_um'"},
      {three + "0.1,-0.2,0.3,3\n", "probes.csv:2: column 's2_um': -0.2 um: a scatter is not negative"},
      {three + "0.1,0.2,0.3,2.5\n", "probes.csv:2: column 'readings': 2.5 readings"},
      {three + "0.1,0.2,0.3,0\n", "probes.csv:2: column 'readings': 0 readings"},
      {three + "0.1,,0.3,5\n", "probes.csv:2: column 's2_um': empty where 5 readings were averaged"},
      {three + "0.1,0.2,0.3,2147483648\n", "column 'readings': 2147483648 readings: more than 1e9 at one step"},
      {"x_mm,v1_um,v2_um,s1_um,s2_um,s3_um,readings\n0,1,2,0.1,0.2,0.3,3\n",
       "probes.csv:1: column 's3_um' is a third probe's scatter, but the file has no v3_um"}};
  for (const auto& [text, why] : refused) EXPECT_NE(refusal(text).find(why), std::string::npos) << refusal(text);
}

// The diagnosis of a stored three-probe run takes the noise its probes' scatter states: the
// residuals of the diagnosis made without it agree with it (the emulated probes' noise is the
// same within a step and between steps), and one progress counts both diagnoses to its end.
// The zeros the run measured are taken off its readings, as the separation takes them off.
TEST(EstService, ADiagnosisOfAThreeProbeRunTakesTheNoiseItsProbesScatterStates) {
  const mtcal::testing::TempDir dir;
  mtcal::testing::RecordingObserver observer;
  Session session({dir.file("e.sqlite"), "", &observer, nullptr, nullptr});
  const auto three = runEst(session, examplePlan("x_guideway_three_probe.json"));
  observer.progress.clear();
  DiagnoseRequest request;
  request.run_id = three.run_id;
  const auto a = diagnose(session, request);
  const auto noted = std::find_if(a.diagnosis.notes.begin(), a.diagnosis.notes.end(), [](const std::string& n) {
    return n.find("the noise was taken as the probes' scatter over the readings averaged at each step") !=
           std::string::npos;
  });
  EXPECT_NE(noted, a.diagnosis.notes.end()) << a.document().dump(1);
  // The same as fields of the document.
  const auto stated = a.document()["stated_error"];
  EXPECT_EQ(stated["what"], "noise");
  EXPECT_EQ(stated["outcome"], "taken");
  EXPECT_GE(stated["p_value"].get<double>(), 0.01);
  // The residuals agree with it in all: the check from one point to the next is not weighed.
  EXPECT_TRUE(stated["p_value_point_to_point"].is_null()) << stated.dump();
  EXPECT_NEAR(stated["noise_rms_um"].get<double>(), std::sqrt(a.data.stated_noise_variance), 1e-12);
  // The zeros the run measured on the flat are taken off: they leave nothing to name (before,
  // the diagnosis named the -6.8 um the zeroing had measured and the separation takes off).
  EXPECT_TRUE(std::any_of(a.diagnosis.notes.begin(), a.diagnosis.notes.end(), [](const std::string& n) {
    return n.find("the probes' zeros the run measured (reference-flat: z3 - 2 z2 + z1 = -6.79") != std::string::npos;
  }));
  for (const auto& f : a.diagnosis.findings) EXPECT_NE(f.candidate.effect, "probe_offset");
  ASSERT_FALSE(observer.progress.empty());
  EXPECT_EQ(observer.progress.back().done, observer.progress.back().total);
  for (std::size_t k = 0; k < observer.progress.size(); ++k) {
    EXPECT_LE(observer.progress[k].done, observer.progress[k].total);
    if (k > 0) {
      EXPECT_GE(observer.progress[k].done, observer.progress[k - 1].done) << "the count went back";
    }
  }
  EXPECT_NE(observer.progress.back().what.find("twice: the noise estimated, then as stated)"), std::string::npos)
      << observer.progress.back().what;
  // The same plan run again on the same simulated machine reads the same (one seed): diagnosed
  // with the first in one fit it would count as twice the evidence, and is refused.
  const auto same = runEst(session, examplePlan("x_guideway_three_probe.json"));
  DiagnoseRequest twice;
  twice.run_id = three.run_id;
  twice.runs = {std::to_string(same.run_id)};
  try {
    diagnose(session, twice);
    ADD_FAILURE() << "the same readings twice were diagnosed in one fit";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("the same readings twice would count as twice the evidence"),
              std::string::npos)
        << e.what();
  }
  // A run of another machine's guideway (another seed) with it: the two runs' statement pooled,
  // and taken as each alone is.
  auto other_machine = examplePlan("x_guideway_three_probe.json");
  other_machine.simulation.seed = 2;
  const auto again = runEst(session, other_machine);
  DiagnoseRequest both;
  both.run_id = three.run_id;
  both.runs = {std::to_string(again.run_id)};
  const auto pooled = diagnose(session, both);
  const auto second = acquisition::diagnosisInputOfRun(session.store(), again.run_id, {}).data;
  EXPECT_NEAR(pooled.data.stated_noise_dof, a.data.stated_noise_dof + second.stated_noise_dof, 1e-9);
  const auto pooled_stated = pooled.document()["stated_error"];
  EXPECT_EQ(pooled_stated["outcome"], "taken") << pooled.document().dump(1);
  EXPECT_NEAR(pooled_stated["noise_rms_um"].get<double>(), std::sqrt(pooled.data.stated_noise_variance), 1e-12);
}

// A carriage stepped by hand (a real machine's workflow, rehearsed: the simulated operator
// moves the carriage to each step and confirms): the same guideway as when mtcal steps the
// machine, within the readings' noise (0.02 um per reading, 10 averaged: the profiles' 1-sigma
// at the last step is 0.09 um for two probes); a real probe box without "stepping": "hand" is
// refused before anything is opened.
TEST(EstService, ACarriageSteppedByHandGivesTheSameGuideway) {
  const mtcal::testing::TempDir dir;
  Session session({dir.file("e.sqlite"), "", nullptr, nullptr, nullptr});
  EstRunRequest request = examplePlan("x_guideway_two_probe.json");
  const auto machine = runEst(session, request);
  request.plan.stepping = "hand";
  const auto hand = runEst(session, request);
  ASSERT_TRUE(machine.analysis && hand.analysis);
  EXPECT_EQ(nlohmann::json::parse(showRun(session, hand.run_id).run.plan_json)["stepping"], "hand");
  const auto& a = machine.analysis->result.profile_um;
  const auto& b = hand.analysis->result.profile_um;
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t k = 0; k < a.size(); ++k) EXPECT_NEAR(b[k], a[k], 4.0 * 0.09 + 0.01) << k;
  request.device_uri = "serial:///dev/null";
  request.plan.stepping = "machine";
  try {
    runEst(session, request);
    FAIL() << "a real box stepped by the machine was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("\"stepping\": \"hand\""), std::string::npos) << e.what();
  }
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
