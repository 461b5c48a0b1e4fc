#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <sstream>

#include "../support/temp_dir.h"
#include "mtcal/error.h"
#include "mtcal/services/archive.h"
#include "mtcal/services/thermal.h"
#include "service_support.h"

// Thermal error through services: a drift made from two temperatures by known coefficients
// is imported, fitted and stored; real instruments need an operator to start the spindle.
namespace mtcal::services {
namespace {

// 300 samples a minute apart: T1 warms by a first-order step, T2 swings slowly, T3 is a
// sensor the drift does not follow; drift = 1.5 - 2.0 um/K (T1 - 20) + 0.8 um/K (T2 - 20)
// plus a small deterministic ripple (the AR(1) part has something to fit).
std::string writeSeries(const mtcal::testing::TempDir& dir) {
  const std::string path = dir.file("series.csv");
  std::ofstream out(path);
  out << "time_s,T1,T2,T3,drift_um\n";
  for (int i = 0; i < 300; ++i) {
    const double t = 60.0 * i;
    const double t1 = 20.0 + 5.0 * (1.0 - std::exp(-t / 3600.0));
    const double t2 = 20.0 + 0.7 * std::sin(2 * std::numbers::pi * t / 9000.0);
    const double t3 = 20.0 + 0.3 * std::cos(2 * std::numbers::pi * t / 2500.0);
    const double drift = 1.5 - 2.0 * (t1 - 20.0) + 0.8 * (t2 - 20.0) + 0.01 * std::sin(1.7 * i);
    out << t << "," << t1 << "," << t2 << "," << t3 << "," << drift << "\n";
  }
  return path;
}

TEST(ThermalService, ImportsFitsAndStoresAModelThatFindsTheCoefficients) {
  const mtcal::testing::TempDir dir;
  Session session({dir.file("t.sqlite"), "", nullptr, nullptr, nullptr});
  const auto imported = importThermal(session, writeSeries(dir), {});
  EXPECT_EQ(imported.samples, 300u);
  EXPECT_EQ(imported.missing_values, 0u);
  ASSERT_EQ(imported.channels.size(), 4u);
  EXPECT_EQ(imported.document()["schema_version"], 1);

  ThermalFitRequest request;
  request.target = "drift_um";
  request.predictions_path = dir.file("predictions.csv");
  const auto a = fitThermal(session, imported.run_id, request);
  // The chosen model follows T1 and T2 with their coefficients (the ripple is 0.01 um).
  const auto& chosen = a.fit.chosen;
  std::map<std::string, double> b;
  for (std::size_t i = 0; i < chosen.sensors.size(); ++i)
    b[chosen.sensors[i]] = chosen.coefficients(static_cast<Eigen::Index>(i) + 1);
  ASSERT_TRUE(b.count("T1") && b.count("T2")) << a.document().dump(1);
  EXPECT_NEAR(b["T1"], -2.0, 0.02);
  EXPECT_NEAR(b["T2"], 0.8, 0.02);
  EXPECT_LT(chosen.rms_test_um, 0.05);
  // Stored as its document; the predictions file has a row per sample.
  const auto results = session.store().results(imported.run_id);
  ASSERT_EQ(results.size(), 1u);
  EXPECT_EQ(results.front().id, a.result_id);
  EXPECT_EQ(nlohmann::json::parse(results.front().output_json), a.document());
  std::ifstream predictions(request.predictions_path);
  std::string line;
  std::size_t rows = 0;
  std::getline(predictions, line);
  EXPECT_EQ(line, "time_s,measured_um,open_loop_um,one_step_um,part");
  while (std::getline(predictions, line)) ++rows;
  EXPECT_EQ(rows, 300u);

  // Exported, the run reads back as the same series.
  std::ostringstream exported;
  exportThermal(session, imported.run_id, exported);
  std::istringstream text(exported.str());
  std::size_t data_rows = 0;
  bool header = false;
  while (std::getline(text, line)) {
    if (line.empty() || line[0] == '#') continue;
    if (!header) {
      header = true;
      EXPECT_NE(line.find("drift_um"), std::string::npos) << line;
      continue;
    }
    ++data_rows;
  }
  EXPECT_EQ(data_rows, 300u);
}

// An option wrong whatever the file is refused before the file is read (a pipe would be waited
// for): a file that is not there is not even looked for.
TEST(ThermalService, AWrongOptionIsRefusedBeforeTheFileIsRead) {
  const mtcal::testing::TempDir dir;
  Session session({dir.file("t.sqlite"), "", nullptr, nullptr, nullptr});
  acquisition::ThermalImportOptions options;
  options.interval_s = -60.0;
  try {
    importThermal(session, dir.file("not-there.csv"), options);
    ADD_FAILURE() << "imported";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), "--interval-s must be > 0 and at most 86400 s (a day), got -60");
  }
  options.interval_s = 1e300;  // rows 1e300 s apart: no record
  try {
    importThermal(session, dir.file("not-there.csv"), options);
    ADD_FAILURE() << "imported";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), "--interval-s must be > 0 and at most 86400 s (a day), got 1e+300");
  }
  // A file that gives each row's time takes no interval beside it.
  const std::string timed = dir.file("timed.csv");
  std::ofstream(timed) << "time_s,T1,drift_um\n0,20.0,0.5\n60,20.1,0.7\n";
  options.interval_s = 30.0;
  try {
    importThermal(session, timed, options);
    ADD_FAILURE() << "imported";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), timed + ":1: --interval-s 30: the file's column 'time_s' gives each row's time");
  }
  // A speed of 1e9 rpm is no spindle's.
  options.interval_s.reset();
  std::ofstream(timed) << "time_s,T1,drift_um,spindle_rpm\n0,20.0,0.5,-8000\n60,20.1,0.7,1e9\n";
  try {
    importThermal(session, timed, options);
    ADD_FAILURE() << "imported";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(timed + ":3: column 'spindle_rpm': 1e+09 rpm is beyond +-300000 rpm"),
              std::string::npos)
        << e.what();
  }
  EXPECT_FALSE(std::filesystem::exists(dir.file("t.sqlite")));
}

TEST(ThermalService, RealInstrumentsNeedSomeoneToStartTheSpindle) {
  const mtcal::testing::TempDir dir;
  Session session({dir.file("t.sqlite"), "", nullptr, nullptr, nullptr});
  ThermalRunRequest request;
  request.plan = acquisition::ThermalPlan::fromJson(
      nlohmann::json::parse(readTextFile(MTCAL_EXAMPLES_DIR "/plans/thermal/quick-2h.json")), "quick-2h.json");
  request.logger_uri = "serial:///dev/null";
  request.probes_uri = "serial:///dev/null";
  try {
    runThermal(session, request);
    FAIL() << "ran without an operator";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("nobody to ask"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(std::filesystem::exists(dir.file("t.sqlite")));  // no archive left behind
  request.probes_uri = "mock://probes";
  EXPECT_THROW(runThermal(session, request), InputError);  // mixed real and simulated
}

}  // namespace
}  // namespace mtcal::services
