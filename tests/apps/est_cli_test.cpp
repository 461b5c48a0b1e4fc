#include "mtcal/processing/est.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <nlohmann/json.hpp>
#include <sstream>

#include "../support/cli_run.h"
#include "../support/temp_dir.h"
#include "../support/time_scale.h"
#include "mtcal/app/cli.h"

// `mtcal est` on probe readings written from a known profile and carriage motion: the
// separated profile is the profile, and the evaluations are those of the profile itself.
namespace mtcal::app {
namespace {

using mtcal::testing::cli;

TEST(EstCli, SeparatesTheProfileOfAFile) {
  const mtcal::testing::TempDir dir;
  const std::string path = dir.file("probes.csv");
  std::vector<double> x, s;
  {
    std::ofstream csv(path);
    csv << std::setprecision(17) << "# two probes 25 mm apart, carriage stepped 25 mm\nx_mm,v1_um,v2_um\n";
    auto profile = [](int k) { return 2.0 * std::sin(0.5 * k) + 0.01 * k * k; };
    for (int k = 0; k < 17; ++k) {
      const double carriage = k == 0 ? 0.0 : 0.4 * std::cos(1.3 * k);
      csv << 25.0 * k << "," << profile(k) + carriage << "," << profile(k + 1) + carriage << "\n";
      x.push_back(25.0 * k);
      s.push_back(profile(k));
    }
  }
  auto r = cli({"est", path, "--spacing-mm", "25", "--json"});
  ASSERT_EQ(r.code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  ASSERT_EQ(j["straightness_um"].size(), 17u);
  for (std::size_t k = 0; k < 17; ++k) EXPECT_NEAR(j["straightness_um"][k].get<double>(), s[k], 1e-9) << k;
  EXPECT_NEAR(j["carriage_um"][3].get<double>(), 0.4 * std::cos(3.9), 1e-9);
  const auto truth = processing::evaluateStraightness(x, s);
  EXPECT_NEAR(j["straightness_lsq_um"].get<double>(), truth.least_squares_um, 1e-9);
  EXPECT_NEAR(j["straightness_minzone_um"].get<double>(), truth.min_zone_um, 1e-9);
  EXPECT_GT(truth.least_squares_um, truth.min_zone_um);  // the two evaluations differ here

  r = cli({"est", path, "--spacing-mm", "20"});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("not a whole number of steps"), std::string::npos) << r.err;
  r = cli({"est", path, "--spacing-mm", "25", "--method", "three-probe"});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("missing column 'v3_um'"), std::string::npos) << r.err;
}

TEST(EstCli, ABadCellIsNamed) {
  const mtcal::testing::TempDir dir;
  const std::string path = dir.file("bad.csv");
  std::ofstream(path) << "x_mm,v1_um,v2_um\n0,1,2\n10,1,x2\n";
  const auto r = cli({"est", path, "--spacing-mm", "10"});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("bad.csv:3: column 'v2_um': 'x2' is not a number"), std::string::npos) << r.err;
}

// What a careless line asks of the separation is refused, naming the option and why: a spacing
// as long as the line stepped (the second probe never reads where the first did), zero readings
// beyond a probe's range or for a method that takes none, a two-probe start for another method;
// an import of such a spacing stores nothing.
TEST(EstCli, OptionsTheMethodCannotTakeAreRefused) {
  const mtcal::testing::TempDir dir;
  const std::string path = dir.file("line.csv"), two = dir.file("two.csv"), db = dir.file("a.sqlite");
  {
    std::ofstream csv(path), two_probes(two);
    csv << "x_mm,v1_um,v2_um,v3_um\n";
    two_probes << "x_mm,v1_um,v2_um\n";
    for (int k = 0; k < 21; ++k) {
      csv << 20 * k << "," << 0.1 * k << "," << 0.1 * (k + 1) << "," << 0.1 * (k + 2) << "\n";
      two_probes << 20 * k << "," << 0.1 * k << "," << 0.1 * (k + 1) << "\n";
    }
  }
  auto r = cli({"est", path, "--spacing-mm", "420"});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("EST: the probe spacing 420 mm is not shorter than the line read (0 to 400 mm): the second "
                       "probe would never read where the first did"),
            std::string::npos)
      << r.err;
  r = cli({"--db", db, "import", "est", two, "--spacing-mm", "400"});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("--spacing-mm 400 (the file steps by 20 mm): 400 mm is not shorter than the line stepped (21 "
                       "points of 20 mm: 400 mm)"),
            std::string::npos)
      << r.err;
  EXPECT_FALSE(std::filesystem::exists(db));
  r = cli({"--db", db, "import", "est", path, "--spacing-mm", "20", "--zero-readings-um", "1e20,0,0"});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("--zero-readings-um: '1e20' is beyond +-100000 um: not a probe's reading on a flat"),
            std::string::npos)
      << r.err;
  EXPECT_FALSE(std::filesystem::exists(db));
  r = cli({"est", path, "--spacing-mm", "20", "--zero-readings-um", "1,2,3"});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("--zero-readings-um: the two-probe method does not use the probes' zeros"), std::string::npos)
      << r.err;
  r = cli({"est", path, "--spacing-mm", "20", "--method", "three-probe", "--start", "second-point"});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("--start second-point: an initial condition of the two-probe method, not of the three-probe "
                       "method"),
            std::string::npos)
      << r.err;
  // Three probes' zeros, not two (they were dropped, with the warning of no zeroing), nor one left
  // empty or none.
  for (const auto& [zeros, why] : std::vector<std::pair<std::string, std::string>>{
           {"1,2", ": 3 probes, but 2 zero readings given"},
           {"1,2,", "--zero-readings-um takes the probes' readings on a reference flat, z1,z2,z3 in um; got '1,2,'"},
           {"", "a reading per probe is needed, got ''"}}) {
    r = cli({"est", path, "--spacing-mm", "20", "--method", "three-probe", "--zero-readings-um", zeros});
    EXPECT_EQ(r.code, 2) << zeros;
    EXPECT_NE(r.err.find(why), std::string::npos) << r.err;
  }
  // The same line as the method takes it: separated.
  r = cli({"est", path, "--spacing-mm", "20", "--method", "three-probe", "--zero-readings-um", "0,0,0"});
  EXPECT_EQ(r.code, 0) << r.err;
}

}  // namespace
}  // namespace mtcal::app

namespace mtcal::app {
namespace {

// The whole chain from the command line: a probe stepping plan on the simulated machine
// (mock://probes over a pseudo-terminal), stored, separated; the stored run analysed again by
// another method, and by its own without one; bad plans and non-probe runs refused by name.
TEST(EstCli, RunsAStoredProbePlanAndAnalysesItAgain) {
  const mtcal::testing::TempDir dir;
  const std::string db = dir.file("e.sqlite");
  const std::string plan = std::string(MTCAL_EXAMPLES_DIR) + "/plans/est/x_guideway_three_probe.json";
  auto r = cli({"--db", db, "run", "est", plan, "--time-scale", mtcal::testing::timeScaleArg(200), "--json"});
  ASSERT_EQ(r.code, 0) << r.err;
  const auto first = nlohmann::json::parse(r.out);
  EXPECT_EQ(first["method"], "three-probe");
  EXPECT_EQ(first["x_mm"].size(), 21u);
  r = cli({"--db", db, "analyze", "est", "1", "--method", "two-probe", "--json"});
  ASSERT_EQ(r.code, 0) << r.err;
  const auto second = nlohmann::json::parse(r.out);
  EXPECT_EQ(second["method"], "two-probe");
  EXPECT_EQ(second["carriage_um"].size(), 21u);
  // The same guideway by both methods: the straightness values differ by what each method
  // gets wrong (yaw for two probes, the zero mismatch parabola for three), both finite.
  EXPECT_GT(second["straightness_minzone_um"].get<double>(), 0.5);
  // Without --method, by the run's own: three probes.
  r = cli({"--db", db, "analyze", "est", "1", "--json"});
  ASSERT_EQ(r.code, 0) << r.err;
  const auto own = nlohmann::json::parse(r.out);
  EXPECT_EQ(own["method"], "three-probe");
  EXPECT_EQ(own["straightness_minzone_um"], first["straightness_minzone_um"]);
  r = cli({"--db", db, "analyze", "est", "7"});
  EXPECT_EQ(r.code, 2);
  const std::string bad = dir.file("bad.json");
  std::ofstream(bad) << R"({"type": "est", "probes": 4})";
  r = cli({"--db", db, "run", "est", bad});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("'probes'"), std::string::npos) << r.err;
}

}  // namespace
}  // namespace mtcal::app
