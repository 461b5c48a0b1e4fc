#include <fmt/format.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <tuple>
#include <vector>

#include "../support/temp_dir.h"
#include "../support/time_scale.h"
#include "mtcal/app/cli.h"
#include "mtcal/storage/store.h"

namespace mtcal::app {
namespace {

class ModelCliTest : public ::testing::Test {
 protected:
  struct Result {
    int code;
    std::string out, err;
    nlohmann::json json() const { return nlohmann::json::parse(out); }
  };
  Result run(std::vector<std::string> args) {
    args.insert(args.begin(), {"--db", db_});
    std::ostringstream out, err;
    const int code = runCli(args, out, err);
    return {code, out.str(), err.str()};
  }
  std::string write(const std::string& name, const std::string& text) {
    const std::string path = dir_.file(name);
    std::ofstream(path) << text;
    return path;
  }
  const std::string machine_ = std::string(MTCAL_EXAMPLES_DIR) + "/machines/vmc3-cn104200063.model.json";
  mtcal::testing::TempDir dir_;
  std::string db_ = dir_.file("m.sqlite");
};

// EXX = 0.01 um/mm x (exact, 3 identical repeats per node) and EC0Y = 10 urad. At (300, 200, 250)
// the tool point moves by EXX(300) = 3 um and by EC0Y x r = -10e-6 * 200 mm = -2 um in x:
// E_x = P_ideal - P = -(3 - 2) = -1 um; nothing in y and z.
TEST_F(ModelCliTest, ImportedCurvesPredictTheHandComputedError) {
  std::string csv = "error,position_mm,value\n";
  for (int p = 50; p <= 600; p += 50) {
    for (int r = 0; r < 3; ++r) csv += "EXX," + std::to_string(p) + "," + std::to_string(0.01 * p) + "\n";
  }
  csv += "EC0Y,,10\n";
  auto r = run({"model", "import", write("c.csv", csv), "--machine", machine_, "--json"});
  ASSERT_EQ(r.code, 0) << r.err;
  const int id = r.json()["model_id"].get<int>();
  const std::string points = write("p.csv", "x_mm,y_mm,z_mm\n300,200,250\n");
  r = run({"model", "predict", std::to_string(id), "--points", points, "--json"});
  ASSERT_EQ(r.code, 0) << r.err;
  const auto p = r.json()["points"][0];
  EXPECT_NEAR(p["ex_um"].get<double>(), -1.0, 1e-6);
  // The full model keeps second-order terms: eps^2 r = (1e-5)^2 x 200 mm = 2e-5 um.
  EXPECT_NEAR(p["ey_um"].get<double>(), 0.0, 1e-4);
  EXPECT_NEAR(p["ez_um"].get<double>(), 0.0, 1e-4);
  r = run({"model", "predict", std::to_string(id), "--grid", "50:600:3,0:100:2,200:200:1", "--json"});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(r.json()["points"].size(), 6u);
  r = run({"model", "list", "--json"});
  EXPECT_EQ(r.json()["models"][0]["method"], "imported");
}

TEST_F(ModelCliTest, KeyErrorsAndBandsOnTheExampleCurves) {
  auto r = run({"model", "import", std::string(MTCAL_EXAMPLES_DIR) + "/models/vmc3-error-curves.csv", "--machine",
                machine_, "--json"});
  ASSERT_EQ(r.code, 0) << r.err;
  r = run({"model", "key-errors", "1", "--json"});
  ASSERT_EQ(r.code, 0) << r.err;
  const auto keys = r.json()["key_errors"];
  double sum_x = 0.0;
  for (const auto& k : keys) sum_x += k["share_x"].get<double>();
  EXPECT_NEAR(sum_x, 1.0, 1e-9);
  EXPECT_EQ(r.json()["at"], (std::vector<double>{325.0, 325.0, 325.0}));
  EXPECT_EQ(r.json()["outside_measured_range"], false);
  // A point a kilometre away is extrapolated, and said so; a Sobol sample of none is no request.
  r = run({"model", "key-errors", "1", "--at", "1e6,0,0", "--json"});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(r.json()["outside_measured_range"], true);
  EXPECT_NE(r.err.find("warning: the point lies outside the range the model was measured over"), std::string::npos)
      << r.err;
  r = run({"model", "key-errors", "1", "--sobol", "0"});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("--sobol: must be from 10 to 1000000, got 0"), std::string::npos) << r.err;
  // With --json the points' CSV still goes where -o says.
  const std::string points = write("points.csv", "");
  r = run({"model", "predict", "1", "--grid", "50:600:2,0:100:2,200:200:1", "-o", points, "--json"});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(r.json()["points"].size(), 4u);
  std::ifstream csv(points);
  std::string line;
  int lines = 0;
  while (std::getline(csv, line)) ++lines;
  EXPECT_EQ(lines, 5);  // the header and the 4 points
  r = run({"model", "bands", "1", "--plane", "XY", "--grid", "2", "--json"});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(r.json()["points"].size(), 4u);
  // The least certain error sets the band: the squareness values have 5 repeats, 4 degrees
  // of freedom, so +-3 sigma widens to t(0.998650, 4) = 6.6202 (checked by integrating the
  // t density).
  EXPECT_NEAR(r.json()["coverage_k"].get<double>(), 6.6202, 1e-3);
}

// The example curves as ISG's volumetric compensation: one JSON document, the file as -o wrote
// it, no check (an imported model has no simulated machine); the options of one axis' table
// and a run refused.
TEST_F(ModelCliTest, VolumetricCompensationOfTheExampleCurves) {
  auto r = run(
      {"model", "import", std::string(MTCAL_EXAMPLES_DIR) + "/models/vmc3-error-curves.csv", "--machine", machine_});
  ASSERT_EQ(r.code, 0) << r.err;
  const std::string file = write("vc.csv", "");
  r = run({"compensate", "m1", "--controller", "isg-volumetric", "--interval", "50", "-o", file, "--json"});
  ASSERT_EQ(r.code, 0) << r.err;
  const auto j = r.json();
  EXPECT_EQ(j["controller"], "isg-volumetric");
  EXPECT_FALSE(j.contains("verification"));
  std::stringstream written;
  written << std::ifstream(file).rdbuf();
  EXPECT_EQ(j["file"].get<std::string>(), written.str());
  EXPECT_EQ(j["axes"].size(), 3u);
  EXPECT_NE(j["setup"].get<std::string>().find("file[0] vc.csv"), std::string::npos);
  r = run({"compensate", "m1", "--controller", "isg-volumetric", "--axis", "X"});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("compensates every axis of the model at once"), std::string::npos) << r.err;
  r = run({"compensate", "1", "--controller", "isg-volumetric"});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("isg-volumetric needs a model (mN): a run measures one axis"), std::string::npos) << r.err;
}

// The demo's X run identified directly: the model's E_x at each target is minus the ISO 230-2
// mean bidirectional deviation of that target relative to the first (motion errors are zero
// at the first node; the node means pass through them closely).
TEST_F(ModelCliTest, IdentifiesTheDemoRun) {
  auto r = run({"demo", "--time-scale", mtcal::testing::timeScaleArg(400), "--json"});
  ASSERT_EQ(r.code, 0) << r.err;
  const auto positions = r.json()["iso230_2"]["positions"];
  r = run({"model", "identify", "1", "--machine", machine_, "--json"});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(r.json()["errors"], nlohmann::json::array({"EXX"}));
  const std::string points = write("p.csv", "x_mm,y_mm,z_mm\n50,0,0\n310,0,0\n600,0,0\n");
  r = run({"model", "predict", "1", "--points", points, "--json"});
  ASSERT_EQ(r.code, 0) << r.err;
  const auto p = r.json()["points"];
  const double first_um = positions[0]["mean_um"].get<double>();
  EXPECT_NEAR(-p[0]["ex_um"].get<double>(), 0.0, 1e-9);
  EXPECT_NEAR(-p[1]["ex_um"].get<double>(), positions[13]["mean_um"].get<double>() - first_um, 0.05);
  EXPECT_NEAR(-p[2]["ex_um"].get<double>(), positions[28]["mean_um"].get<double>() - first_um, 0.05);
  r = run({"model", "list", "--json"});
  EXPECT_EQ(r.json()["models"][0]["method"], "direct");
  EXPECT_EQ(r.json()["models"][0]["provenance"]["runs"], nlohmann::json::array({1}));
  r = run({"model", "identify", "1", "--machine", machine_, "--method", "9-line"});
  EXPECT_EQ(r.code, 2);  // one displacement line cannot give pitch and yaw
  EXPECT_NE(r.err.find("9-line method: the displacement lines of axis x leave EBX, ECX undetermined"),
            std::string::npos)
      << r.err;
  r = run({"model", "identify", "c1", "--machine", machine_, "--json"});  // the demo's campaign
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(r.json()["axes"][0]["errors"], nlohmann::json::array({"EXX"}));
  EXPECT_EQ(r.json()["axes"][0]["lines"], nlohmann::json::array({"run 1"}));
  EXPECT_FALSE(r.json()["notes"].empty());  // the other errors of X were not measured
  r = run({"model", "identify", "c9", "--machine", machine_});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("campaign c9 does not exist"), std::string::npos) << r.err;
}

// The patent's validation on the demo machine: the model from the 20 mm x 9 nodes predicts a
// second run at random points about every 3 mm (examples/plans/x_axis_validation_3mm.json,
// two cycles up). The machine scatters 0.6 um per approach, so the residual RMS should be
// 0.6 / sqrt(2) = 0.42 um from the validation run plus ~0.14 um from the model's nodes
// (0.6 / sqrt(18)): about 0.45 um. Far above means a model that misses something; far
// below, a validation that does not test.
TEST_F(ModelCliTest, ValidatesTheDemoModelAgainstRandomPointsEvery3mm) {
  auto r = run({"demo", "--time-scale", mtcal::testing::timeScaleArg(400)});
  ASSERT_EQ(r.code, 0) << r.err;
  r = run({"model", "identify", "1", "--machine", machine_});
  ASSERT_EQ(r.code, 0) << r.err;
  r = run({"run", "linear", std::string(MTCAL_EXAMPLES_DIR) + "/plans/x_axis_validation_3mm.json", "--time-scale",
           mtcal::testing::timeScaleArg(400)});
  ASSERT_EQ(r.code, 0) << r.err;
  r = run({"model", "validate", "1", "2", "--json"});
  ASSERT_EQ(r.code, 0) << r.err;
  const auto v = r.json()["runs"][0];
  EXPECT_EQ(v["measures"], "EXX");
  EXPECT_EQ(v["points"], 185);
  EXPECT_GT(v["rms"].get<double>(), 0.3);
  EXPECT_LT(v["rms"].get<double>(), 0.6);
  EXPECT_LT(v["peak"].get<double>(), 4.0 * 0.45);
  EXPECT_EQ(v["nodes"].size(), 185u);
  storage::Store store(db_);  // kept with the run, for later comparisons
  const auto results = store.results(2);
  ASSERT_FALSE(results.empty());
  EXPECT_EQ(results.back().processor, "model-validation");
  EXPECT_EQ(nlohmann::json::parse(results.back().parameters_json)["model_id"], 1);
  EXPECT_DOUBLE_EQ(nlohmann::json::parse(results.back().output_json)["rms"].get<double>(), v["rms"].get<double>());
  r = run({"model", "validate", "1", "99"});
  EXPECT_EQ(r.code, 2);
  // A run given twice would be listed twice and stored twice.
  const auto results_before = store.results(2).size();
  r = run({"model", "validate", "1", "2", "2"});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("validate: run 2 is given twice (each run is compared once)"), std::string::npos) << r.err;
  EXPECT_EQ(store.results(2).size(), results_before);
  // An empty file name is not stdout.
  for (const auto& args : std::vector<std::vector<std::string>>{
           {"report", "m1", "-o", ""}, {"model", "predict", "1", "--grid", "50:600:2,0:100:2,200:200:1", "-o", ""}}) {
    r = run(args);
    EXPECT_EQ(r.code, 2) << args[0];
    EXPECT_NE(r.err.find("a file name is needed, got ''"), std::string::npos) << r.err;
    EXPECT_EQ(r.out, "") << args[0];
  }
  // Identified along X only: a table of Y says what the model holds.
  r = run({"compensate", "m1", "--axis", "Y"});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("model 1 was not measured along Y (only x 50 to 600 mm): a table of Y needs a model"),
            std::string::npos)
      << r.err;
  // A table's grid checked before the model is read on it: a 1 nm interval was 5.5e11 readings.
  for (const auto& [option, value, why] : std::vector<std::tuple<std::string, std::string, std::string>>{
           {"--interval", "1e-9", "compensation: the interval 1e-09 mm is finer than 0.1 mm (mm, not um?)"},
           {"--interval", "1e9", "compensation: an interval of 1000000000 mm is longer than the range 50 to 600 mm"},
           {"--start", "nan", "compensation: the start nan is not a number"}}) {
    r = run({"compensate", "m1", "--axis", "X", option, value});
    EXPECT_EQ(r.code, 2) << option << " " << value;
    EXPECT_NE(r.err.find(why), std::string::npos) << r.err;
  }
  // The model's report checks it against the runs given, and names the run it was identified from.
  const auto html = dir_.file("model.html");
  r = run({"report", "m1", "--validate", "2", "-o", html});
  ASSERT_EQ(r.code, 0) << r.err;
  std::stringstream text;
  text << std::ifstream(html).rdbuf();
  EXPECT_NE(text.str().find("<tr><th>Identified from</th><td>runs 1</td></tr>"), std::string::npos);
  EXPECT_NE(text.str().find("<td>run 2 RMS</td><td>EXX measured minus predicted (rms)</td>"), std::string::npos);
  EXPECT_EQ(text.str().find("<td>run 1 RMS</td>"), std::string::npos);
  // Without runs given, the fit to its own run: zero to the arithmetic's precision, said as 0.000.
  r = run({"report", "m1", "-o", html});
  ASSERT_EQ(r.code, 0) << r.err;
  std::stringstream own;
  own << std::ifstream(html).rdbuf();
  EXPECT_NE(own.str().find("<tr><td>1</td><td>EXX</td><td class=\"num\">29</td><td class=\"num\">0.000 µm</td><td "
                           "class=\"num\">0.000 µm</td>"),
            std::string::npos)
      << own.str();
}

TEST_F(ModelCliTest, BadInputIsNamedAndStoresNothing) {
  auto r = run(
      {"model", "import", write("bad.csv", "error,position_mm,value\nEXX,50,1\nEXX,70,abc\n"), "--machine", machine_});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("bad.csv:3: column 'value'"), std::string::npos) << r.err;
  r = run({"model", "import", write("unknown.csv", "error,position_mm,value\nEQQ,,1\n"), "--machine", machine_});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("no error term EQQ"), std::string::npos) << r.err;
  EXPECT_FALSE(std::filesystem::exists(db_));  // nothing stored: no archive made
  r = run({"model", "list", "--json"});
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.json()["exit_code"], 2);  // --json: the error is the one document on stdout
  EXPECT_NE(r.err.find("no store"), std::string::npos) << r.err;
  r = run(
      {"model", "import", write("good.csv", "error,position_mm,value\nEXX,0,1\nEXX,100,2\n"), "--machine", machine_});
  ASSERT_EQ(r.code, 0) << r.err;
  // What it holds said: a file cut short shows as the few terms and the short range it has.
  EXPECT_NE(r.err.find("it has 1 of the machine's 21 error terms: EXX over x 0 to 100\n"), std::string::npos) << r.err;
  r = run({"model", "predict", "7", "--grid", "0:1:2,0:1:2,0:1:2"});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("model 7 does not exist"), std::string::npos) << r.err;
  r = run({"model", "import", write("good.csv", "error,position_mm,value\nEXX,0,1\nEXX,100,2\n"), "--machine", machine_,
           "--knot-spacing-mm", "0"});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("--knot-spacing-mm: must be from 0.1 to 100000, got 0"), std::string::npos) << r.err;
  r = run({"model", "identify", "1", "--machine", machine_, "--max-condition", "-1"});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("--max-condition: must be from 1 to"), std::string::npos) << r.err;
}

// The example campaigns of examples/import (exported from the simulated vmc3 by mtcal, the
// direct one with a JSON manifest, the 9-line one with a CSV manifest) identify models as
// docs/import.md shows: the direct campaign all 21 errors with no note, the 9-line one the
// errors its displacement lines see (9 of them with the 6 straightnesses their rotations make,
// the squareness said to be out of reach).
TEST_F(ModelCliTest, ImportedExampleCampaignsIdentifyModels) {
  const std::string examples = std::string(MTCAL_EXAMPLES_DIR) + "/import/";
  auto r = run({"import", "campaign", examples + "direct-21/manifest.json", "--json"});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(r.json()["run_ids"].size(), 18u);
  const auto direct = r.json()["campaign_id"].get<long long>();
  r = run({"model", "identify", "c" + std::to_string(direct), "--machine", machine_, "--json"});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(r.json()["errors"].size(), 21u);
  EXPECT_TRUE(r.json()["notes"].empty()) << r.json()["notes"].dump();

  r = run({"import", "campaign", examples + "9-line/manifest.csv", "--json"});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(r.json()["run_ids"].size(), 9u);
  const auto nine = r.json()["campaign_id"].get<long long>();
  r = run({"model", "identify", "c" + std::to_string(nine), "--machine", machine_, "--method", "9-line", "--json"});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(r.json()["errors"].size(), 15u);
  EXPECT_NE(r.json()["notes"].dump().find("EC0Y not identified"), std::string::npos);

  // The six-error file: one run per error column, with the line and reflector given.
  r = run({"import", "linear", examples + "x_axis_six_errors.csv", "--line-position-mm", "Y=200,Z=150",
           "--reflector-offset-mm", "0,25,45", "--json"});
  ASSERT_EQ(r.code, 0) << r.err;
  ASSERT_EQ(r.json()["run_ids"].size(), 5u);
  EXPECT_EQ(r.json()["measures"], (std::vector<std::string>{"EXX", "EYX", "EZX", "EBX", "ECX"}));
  EXPECT_EQ(r.json()["readings"], (std::vector<int>{102, 102, 102, 102, 102}));  // 17 targets x 3 cycles x 2 directions
  const auto ebx = r.json()["run_ids"][3].get<long long>();
  const auto text = run({"import", "linear", examples + "x_axis_six_errors.csv"});
  EXPECT_NE(text.out.find(fmt::format("imported run {}: 102 readings of EBX\n", ebx + 5)), std::string::npos)
      << text.out;
  r = run({"show", std::to_string(ebx), "--json"});
  EXPECT_EQ(r.json()["plan"]["measures"], "EBX");
  EXPECT_EQ(r.json()["plan"]["line_position_mm"]["Z"], 150.0);
  EXPECT_NEAR(r.json()["target_values"][1]["deviation_urad"].get<double>(), 0.0877 * 4.84813681109536, 1e-9);

  // The German Excel file gives the ISO 230-2 figures of the export it was written from.
  r = run({"import", "linear", examples + "x_axis_excel_de.csv", "--columns",
           "target_mm=Ziel,direction=Richtung,cycle=Zyklus,measured_mm=Position", "--columns",
           "time_s=Zeit,air_temp_c=Lufttemperatur,air_pressure_pa=Luftdruck,humidity_pct=Feuchte,"
           "material_temp_c=Materialtemperatur",
           "--json"});
  ASSERT_EQ(r.code, 0) << r.err;
  const auto excel = r.json()["run_id"].get<long long>();
  r = run({"import", "linear", std::string(MTCAL_EXAMPLES_DIR) + "/import-vendor-csv/x_axis_export.csv", "--json"});
  const auto original = r.json()["run_id"].get<long long>();
  const auto a = run({"analyze", "iso230-2", std::to_string(excel), "--json"}).json();
  const auto b = run({"analyze", "iso230-2", std::to_string(original), "--json"}).json();
  EXPECT_NEAR(a["A_um"].get<double>(), b["A_um"].get<double>(), 1e-9);
  EXPECT_NEAR(a["A_um"].get<double>(), 11.62, 0.005);
  r = run({"show", std::to_string(excel), "--json"});
  EXPECT_NE(r.out.find("Spindel [°C]"), std::string::npos);  // the column left over is a channel
}

}  // namespace
}  // namespace mtcal::app
