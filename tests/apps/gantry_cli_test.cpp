#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "../support/cli_run.h"
#include "../support/temp_dir.h"
#include "../support/time_scale.h"
#include "mtcal/mocks/tracker_emulator.h"

// The gantry commands end to end: a quick plan on the simulated gantry through mock://tracker
// (a real TCP connection to the emulator), its analysis, export, evaluation of the export,
// the NC program, and bad input refused with where and why.
namespace mtcal::app {
namespace {

using mtcal::testing::cli;

const std::string kPlan = std::string(MTCAL_EXAMPLES_DIR) + "/plans/gantry/quick-6x2.json";
const std::string kMachine = std::string(MTCAL_EXAMPLES_DIR) + "/machines/gantry-drilling.json";

TEST(GantryCli, RunsAnalyzesExportsAndEvaluatesTheSameNumbers) {
  const mtcal::testing::TempDir dir;
  const std::string db = dir.file("g.sqlite");
  auto r = cli({"--db", db, "--json", "gantry", "run", kPlan, "--machine-config", kMachine, "--time-scale",
                mtcal::testing::timeScaleArg(400.0), "--trials", "20"});
  ASSERT_EQ(r.code, 0) << r.err;
  const auto run = nlohmann::json::parse(r.out);
  const auto run_id = run["run_id"].get<long long>();
  ASSERT_EQ(run["holes"].size(), 12u);
  for (const auto& h : run["holes"]) {
    ASSERT_EQ(h["dP_um"].size(), 3u);
    const double norm =
        std::hypot(h["dP_um"][0].get<double>(), h["dP_um"][1].get<double>(), h["dP_um"][2].get<double>());
    EXPECT_NEAR(h["dP_norm_um"].get<double>(), norm, 1e-9);
    EXPECT_LE(h["dP_perp_um"].get<double>(), norm + 1e-9);
    EXPECT_GT(h["dP_norm_u95_um"].get<double>(), 0.0);
  }
  EXPECT_EQ(run["summary"]["holes"], 12);
  EXPECT_EQ(run["per_gantry_position"].size(), 2u);
  EXPECT_EQ(run["target_fit"], "patent-frame");
  EXPECT_GT(run["axes_offset_um"].get<double>(), 0.0);

  r = cli({"--db", db, "--json", "analyze", "gantry", std::to_string(run_id), "--trials", "0", "--tcp0", "tool-point"});
  ASSERT_EQ(r.code, 0) << r.err;
  const auto analyzed = nlohmann::json::parse(r.out);
  EXPECT_EQ(analyzed["tcp0_source"], "tool-point");
  EXPECT_FALSE(analyzed.contains("uncertainty"));

  r = cli({"--db", db, "--json", "export", std::to_string(run_id), "--csv", dir.file("export")});
  ASSERT_EQ(r.code, 0) << r.err;
  const std::string file = nlohmann::json::parse(r.out)["files"][0]["path"];
  EXPECT_NE(nlohmann::json::parse(r.out)["import_command"].get<std::string>().find("mtcal gantry evaluate"),
            std::string::npos);
  {  // the same file without its holes: nothing to evaluate, said
    auto measured = nlohmann::json::parse(std::ifstream(file));
    measured["holes"] = nlohmann::json::array();
    std::ofstream(dir.file("no-holes.json")) << measured.dump();
    const auto refused = cli({"gantry", "evaluate", dir.file("no-holes.json")});
    EXPECT_EQ(refused.code, 2);
    EXPECT_NE(refused.err.find("key 'holes': must be an array of at least one hole"), std::string::npos) << refused.err;
  }
  r = cli({"--json", "gantry", "evaluate", file, "--trials", "0", "--tcp0", "tool-point"});
  ASSERT_EQ(r.code, 0) << r.err;
  const auto evaluated = nlohmann::json::parse(r.out);
  ASSERT_EQ(evaluated["holes"].size(), 12u);
  for (std::size_t i = 0; i < 12; ++i) {
    for (int k = 0; k < 3; ++k) {
      EXPECT_NEAR(evaluated["holes"][i]["dP_um"][k].get<double>(), analyzed["holes"][i]["dP_um"][k].get<double>(),
                  1e-6);
    }
  }
  r = cli({"--db", db, "show", std::to_string(run_id)});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("tracker points"), std::string::npos) << r.out;
  // Text output names the method and the summaries.
  r = cli({"--db", db, "analyze", "gantry", std::to_string(run_id), "--trials", "0"});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("patent CN106017326"), std::string::npos);
  EXPECT_NE(r.out.find("position 2"), std::string::npos);
}

TEST(GantryCli, WritesTheNcProgramAndRefusesBadInput) {
  const mtcal::testing::TempDir dir;
  auto r = cli({"plan", "gcode", kPlan, "--machine-config", kMachine});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("g2-h06"), std::string::npos);
  EXPECT_NE(r.out.find("M30"), std::string::npos);
  r = cli({"plan", "gcode", kPlan});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("--machine-config"), std::string::npos) << r.err;
  r = cli({"--db", dir.file("x.sqlite"), "gantry", "run", kPlan});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("--machine-config"), std::string::npos) << r.err;
  r = cli({"--db", dir.file("x.sqlite"), "gantry", "run", kPlan, "--device", "tcp://127.0.0.1:1", "--machine-config",
           kMachine});
  EXPECT_EQ(r.code, 1);  // nothing listens there
  EXPECT_NE(r.err.find("127.0.0.1:1"), std::string::npos) << r.err;
  auto plan = nlohmann::json::parse(std::ifstream(kPlan));
  plan["hole_z_mm"] = {-500, -600, 2};  // the second row 1100 mm down: Z below its travel
  const std::string deep = dir.file("deep.json");
  std::ofstream(deep) << plan.dump();
  r = cli({"--db", dir.file("x.sqlite"), "gantry", "run", deep, "--machine-config", kMachine});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("hole g1-h04 needs Z at"), std::string::npos) << r.err;
  for (const auto& [trials, because] : std::vector<std::pair<std::string, std::string>>{
           {"-5", "must be from 0 to 100000, got -5"}, {"1", "one trial has no spread"}, {"2.5", "whole number"}}) {
    r = cli({"--db", dir.file("x.sqlite"), "gantry", "run", kPlan, "--machine-config", kMachine, "--trials", trials});
    EXPECT_EQ(r.code, 2) << trials;
    EXPECT_NE(r.err.find("--trials"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find(because), std::string::npos) << r.err;
  }
  EXPECT_FALSE(std::filesystem::exists(dir.file("x.sqlite")));
  const std::string bad = dir.file("bad.json");
  std::ofstream(bad)
      << R"({"format": "mtcal-gantry-measurements", "version": 1, "corners": [], "gantry_passes": [{"direction": 2, "points": []}]})";
  r = cli({"gantry", "evaluate", bad});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("gantry_passes[0].direction"), std::string::npos) << r.err;
}

TEST(GantryCli, ARealTrackerOnARealMachinePromptsTheOperatorAndKeepsWhatWasMeasured) {
  // A tracker on the network (the emulator on 127.0.0.1, its machine standing still: nobody
  // runs the NC program here) and an operator who answers the first prompt, then leaves.
  const mtcal::testing::TempDir dir;
  const std::string db = dir.file("real.sqlite");
  mocks::WorldClock clock(mtcal::testing::timeScale(400.0));
  const auto config = mocks::VirtualMachineConfig::fromJson(nlohmann::json::parse(std::ifstream(kMachine)), kMachine);
  mocks::VirtualMachine machine(config, clock);
  mocks::TrackerEmulator tracker(machine, mocks::TrackerEmulatorConfig::forGantry(config, 2));
  const std::string kinematics = std::string(MTCAL_EXAMPLES_DIR) + "/machines/gantry-xyz-ca-cn106017326.model.json";
  auto r = cli(
      {"--db", db, "gantry", "run", kPlan, "--device",
       "tcp://127.0.0.1:" + std::to_string(tracker.port()) + "?reply_timeout_ms=10000", "--machine-config", kinematics},
      "\n");
  EXPECT_EQ(r.code, 1) << r.err;
  EXPECT_NE(r.err.find("put the reflector on A.top [Enter]"), std::string::npos) << r.err;
  EXPECT_NE(r.out.find("no operator input (standard input closed) at: put the reflector on A.side1"), std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find("continue it with: mtcal resume 1"), std::string::npos) << r.out;
  r = cli({"--db", db, "show", "1"});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("status interrupted"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find(", 4 tracker points"), std::string::npos) << r.out;  // A's top face
}

}  // namespace
}  // namespace mtcal::app
