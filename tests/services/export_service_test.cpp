// mtcal export writes a run in the import format of its kind: importing the file again gives
// the same values, exactly (numbers are written in their shortest form that reads back to
// the same double).

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

#include "../support/temp_dir.h"
#include "../support/time_scale.h"
#include "mtcal/error.h"
#include "mtcal/services/circle.h"
#include "mtcal/services/est.h"
#include "mtcal/services/export.h"
#include "mtcal/services/linear.h"
#include "service_support.h"

namespace mtcal::services {
namespace {

std::string fileOf(const RunExport& e, const std::string& ending) {
  for (const auto& f : e.files) {
    if (f.path.size() >= ending.size() && f.path.compare(f.path.size() - ending.size(), ending.size(), ending) == 0)
      return f.path;
  }
  ADD_FAILURE() << "no file " << ending;
  return {};
}

std::size_t lines(const std::string& path) {
  std::ifstream in(path);
  std::size_t n = 0;
  for (std::string line; std::getline(in, line);) ++n;
  return n;
}

TEST(ExportService, AnAcquiredLinearRunReadsBackExactly) {
  const mtcal::testing::TempDir dir;
  Session session(mtcal::testing::onArchive(dir.file("e.sqlite")));
  LinearRunRequest request;
  request.plans = {mtcal::testing::smallLinearPlan()};
  request.simulation.time_scale = mtcal::testing::timeScale(400.0);
  const auto run = runLinear(session, request).runs.front();
  ASSERT_EQ(run.status, "completed");
  const auto e = exportRun(session, run.run_id, dir.file("out"));
  EXPECT_NE(e.import_command.find("mtcal import linear"), std::string::npos);
  EXPECT_EQ(lines(fileOf(e, "_samples.csv")), static_cast<std::size_t>(session.store().sampleCount(run.run_id)) + 1);
  acquisition::LinearImportOptions options;
  options.axis = "X";
  const auto copy = importLinear(session, fileOf(e, "_targets.csv"), options).run_ids.front();
  const auto a = session.store().targets(run.run_id), b = session.store().targets(copy);
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].target_mm, b[i].target_mm);
    EXPECT_EQ(a[i].direction, b[i].direction);
    EXPECT_EQ(a[i].cycle, b[i].cycle);
    EXPECT_EQ(a[i].deviation_um, b[i].deviation_um);
    EXPECT_EQ(a[i].time_s, b[i].time_s);
    EXPECT_EQ(a[i].air_temp_c, b[i].air_temp_c);
    EXPECT_EQ(a[i].air_pressure_pa, b[i].air_pressure_pa);
    EXPECT_EQ(a[i].material_temp_c, b[i].material_temp_c);
  }
  // The same analysis of both.
  EXPECT_EQ(analyzeIso230_2(session, run.run_id).result.E_um, analyzeIso230_2(session, copy).result.E_um);
  // Imported under the simulated machine's own name: readings from a file, with no truth of
  // the simulation (whose origin mtcal cannot know), where the acquired run has it.
  options.machine = session.store().run(run.run_id).machine_name;
  const auto named = importLinear(session, fileOf(e, "_targets.csv"), options).run_ids.front();
  EXPECT_EQ(session.store().run(named).machine_name, session.store().run(run.run_id).machine_name);
  EXPECT_TRUE(analyzeLinear(session, run.run_id, "iso230-2:2014").truth_E_um);
  const auto imported = analyzeLinear(session, named, "iso230-2:2014");
  EXPECT_FALSE(imported.truth_E_um);
  EXPECT_EQ(imported.iso230_2.result.E_um, analyzeIso230_2(session, run.run_id).result.E_um);
  // Never over files already there; nothing of the failed export is left.
  const auto before = std::distance(std::filesystem::directory_iterator(dir.file("out")), {});
  EXPECT_THROW(exportRun(session, run.run_id, dir.file("out")), InputError);
  EXPECT_EQ(std::distance(std::filesystem::directory_iterator(dir.file("out")), {}), before);
}

TEST(ExportService, ACircularTestReadsBackExactly) {
  const mtcal::testing::TempDir dir;
  Session session(mtcal::testing::onArchive(dir.file("e.sqlite")));
  const auto run = runCircle(session, mtcal::testing::quickCircleRequest());
  ASSERT_EQ(run.status, "completed");
  const auto e = exportRun(session, run.run_id, dir.file("out"));
  // The centre too: a model predicts a circle about its centre on the machine.
  const Eigen::Vector3d centre = mtcal::testing::quickCircleRequest().plan.centre_mm;
  EXPECT_NE(e.import_command.find(fmt::format("--radius-mm 50 --plane XY --feed-mm-min 2000 --centre-mm {},{},{}",
                                              centre.x(), centre.y(), centre.z())),
            std::string::npos)
      << e.import_command;
  acquisition::CircleImportOptions options;
  options.radius_mm = 50;
  options.feed_mm_per_min = 2000;
  // The centre as the printed command gives it.
  const auto given = e.import_command.substr(e.import_command.find("--centre-mm ") + 12);
  double x = 0.0, y = 0.0, z = 0.0;
  ASSERT_EQ(std::sscanf(given.c_str(), "%lf,%lf,%lf", &x, &y, &z), 3) << given;
  options.centre_mm = Eigen::Vector3d(x, y, z);
  const auto copy = importCircle(session, fileOf(e, "_points.csv"), options);
  EXPECT_EQ(nlohmann::json::parse(session.store().run(copy.run_id).plan_json)["centre_mm"],
            nlohmann::json::parse(session.store().run(run.run_id).plan_json)["centre_mm"]);
  const auto a = session.store().circlePoints(run.run_id), b = session.store().circlePoints(copy.run_id);
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].direction, b[i].direction);
    EXPECT_EQ(a[i].angle_deg, b[i].angle_deg);
    EXPECT_EQ(a[i].deviation_um, b[i].deviation_um);
    EXPECT_EQ(a[i].time_s, b[i].time_s);
  }
}

TEST(ExportService, AProbeSteppingRunReadsBackExactly) {
  const mtcal::testing::TempDir dir;
  Session session(mtcal::testing::onArchive(dir.file("e.sqlite")));
  EstRunRequest request;
  request.plan = acquisition::EstPlan::load(MTCAL_EXAMPLES_DIR "/plans/est/x_guideway_three_probe.json");
  request.simulation.time_scale = mtcal::testing::timeScale(3000.0);
  const auto run = runEst(session, request);
  ASSERT_EQ(run.status, "completed");
  const auto e = exportRun(session, run.run_id, dir.file("out"));
  const auto copy = importEst(session, fileOf(e, "_steps.csv"), request.plan.spacing_mm, "copy", "imported");
  const auto a = session.store().probeSteps(run.run_id), b = session.store().probeSteps(copy.run_id);
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].position_mm, b[i].position_mm);
    ASSERT_EQ(a[i].channels.size(), 3u);
    ASSERT_EQ(b[i].channels.size(), 3u);
    for (std::size_t c = 0; c < 3; ++c) {
      EXPECT_EQ(a[i].channels[c].value_um, b[i].channels[c].value_um);
      EXPECT_EQ(a[i].channels[c].s_um, b[i].channels[c].s_um);  // the scatter the diagnosis is told
      EXPECT_EQ(a[i].channels[c].readings, b[i].channels[c].readings);
    }
  }
}

}  // namespace
}  // namespace mtcal::services
