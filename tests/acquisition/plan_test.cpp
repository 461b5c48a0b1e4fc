#include <gtest/gtest.h>

#include <algorithm>
#include <regex>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "mtcal/acquisition/circle_plan.h"
#include "mtcal/acquisition/csv.h"
#include "mtcal/acquisition/gcode.h"
#include "mtcal/acquisition/linear_plan.h"
#include "mtcal/acquisition/thermal_run.h"
#include "mtcal/error.h"

namespace mtcal::acquisition {
namespace {

std::string errorOf(const char* json) {
  try {
    LinearPlan::fromJson(nlohmann::json::parse(json), "plan.json");
  } catch (const InputError& e) {
    return e.what();
  }
  return "no error";
}

TEST(LinearPlan, DemoPlanIsThePatentsNodeGrid) {
  const auto plan = LinearPlan::demo();
  const auto targets = plan.targetPositions();
  // 50, 70, ..., 590 and the end 600: 29 targets.
  ASSERT_EQ(targets.size(), 29u);
  EXPECT_DOUBLE_EQ(targets.front(), 50.0);
  EXPECT_DOUBLE_EQ(targets[27], 590.0);
  EXPECT_DOUBLE_EQ(targets.back(), 600.0);
  EXPECT_EQ(linearTargets(plan).size(), 29u * 2u * 9u);
}

TEST(LinearPlan, TestCycleApproachesEveryTargetFromBothSidesAfterOverruns) {
  LinearPlan plan;
  plan.start_mm = 0;
  plan.end_mm = 40;
  plan.step_mm = 20;
  plan.repeats = 2;
  plan.overrun_mm = 5;
  const auto moves = linearMoves(plan);
  std::vector<double> positions;
  for (const auto& m : moves) positions.push_back(m.position_mm);
  EXPECT_EQ(positions, (std::vector<double>{-5, 0, 20, 40, 45, 40, 20, 0, -5, 0, 20, 40, 45, 40, 20, 0}));
  EXPECT_EQ(moves[1].target.direction, 1);
  EXPECT_EQ(moves[5].target.direction, -1);
  EXPECT_EQ(moves[15].target.cycle, 2);
  EXPECT_EQ(moves[15].target.seq, 11);
  plan.bidirectional = false;
  EXPECT_EQ(linearTargets(plan).size(), 6u);
}

TEST(LinearPlan, RandomOffsetsAreFixedPerTargetAndKeepTheEnds) {
  LinearPlan plan = LinearPlan::demo();
  plan.random_offset_mm = 2.0;
  plan.random_seed = 11;
  const auto a = plan.targetPositions();
  const auto b = plan.targetPositions();
  EXPECT_EQ(a, b);
  EXPECT_DOUBLE_EQ(a.front(), 50.0);
  EXPECT_DOUBLE_EQ(a.back(), 600.0);
  int moved = 0;
  for (std::size_t i = 1; i + 1 < a.size(); ++i) {
    const double nominal = 50.0 + 20.0 * static_cast<double>(i);
    EXPECT_LE(std::abs(a[i] - nominal), 2.0);
    moved += a[i] != nominal;
  }
  EXPECT_GT(moved, 20);
  // The same target position in every cycle and direction.
  const auto targets = linearTargets(plan);
  EXPECT_DOUBLE_EQ(targets[1].target_mm, targets[29 * 2 + 1].target_mm);
}

TEST(LinearPlan, ValidationNamesTheFileTheKeyAndWhy) {
  EXPECT_NE(errorOf(R"({"step_mm": -5})").find("plan.json: key 'step_mm': must be > 0"), std::string::npos);
  EXPECT_NE(errorOf(R"({"repeats": 1})").find("'repeats'"), std::string::npos);
  EXPECT_NE(errorOf(R"({"repeats": "nine"})").find("must be an integer"), std::string::npos);
  EXPECT_NE(errorOf(R"({"axis": "Q"})").find("'axis'"), std::string::npos);
  EXPECT_NE(errorOf(R"({"start_mm": 600, "end_mm": 50})").find("'end_mm'"), std::string::npos);
  EXPECT_NE(errorOf(R"({"sample_rate_hz": 60000})").find("'sample_rate_hz'"), std::string::npos);
  EXPECT_NE(errorOf(R"({"stepp_mm": 20})").find("unknown key"), std::string::npos);
  EXPECT_NE(errorOf(R"({"type": "circle"})").find("'type'"), std::string::npos);
  EXPECT_NE(errorOf(R"({"random_offset_mm": 15})").find("half the step"), std::string::npos);
  EXPECT_NE(errorOf(R"({"air_index_model": "magic"})").find("'air_index_model'"), std::string::npos);
  EXPECT_NE(errorOf(R"([1, 2])").find("JSON object"), std::string::npos);
  EXPECT_THROW(LinearPlan::load("/nonexistent/plan.json"), InputError);
}

TEST(LinearPlan, JsonRoundTrip) {
  LinearPlan plan = LinearPlan::demo();
  plan.random_offset_mm = 1.5;
  plan.axis = "Y";
  const auto back = LinearPlan::fromJson(plan.toJson(), "round trip");
  EXPECT_EQ(back.toJson(), plan.toJson());
  EXPECT_EQ(back.targetPositions(), plan.targetPositions());
}

TEST(LinearGcode, OneDwellPerTargetInTheChosenDialect) {
  LinearPlan plan = LinearPlan::demo();
  const std::string iso = linearGcode(plan);
  const auto count = [](const std::string& text, const std::string& what) {
    std::size_t n = 0;
    for (auto pos = text.find(what); pos != std::string::npos; pos = text.find(what, pos + 1)) ++n;
    return n;
  };
  EXPECT_EQ(count(iso, "\nG4 P"), 522u + 1u);  // every target plus the datum
  EXPECT_EQ(count(iso, "(overrun)"), 18u);     // one below and one above per cycle
  EXPECT_NE(iso.find("G1 X45.0000 F2000 (approach the datum from below)\nG1 X50.0000\nG4 P"), std::string::npos);
  EXPECT_NE(iso.find("G1 X600.0000 (target 29 cycle 1 up)"), std::string::npos);
  EXPECT_NE(iso.find("G1 X45.0000 (overrun)"), std::string::npos);
  EXPECT_NE(iso.find("M30"), std::string::npos);
  // The header says the dwells' unit: a Fanuc-style control reads G4 P in milliseconds.
  EXPECT_NE(iso.find("\n(dwells are G4 P in seconds, as LinuxCNC reads them; a control that reads G4 P in "
                     "milliseconds"),
            std::string::npos);
  plan.gcode_dialect = "fanuc";
  const std::string fanuc = linearGcode(plan);
  EXPECT_EQ(count(fanuc, "\nG04 X"), 523u);
  EXPECT_NE(fanuc.find("\n(dwells are G04 X in seconds)\n"), std::string::npos);
  EXPECT_EQ(fanuc.find("G4 P"), std::string::npos);
}

// A comment ends at its first ')' and may hold no '(' (RS274/NGC, NIST IR 6556, 3.3.4): a plan
// named with parentheses (the thermal example's is) would make a program LinuxCNC refuses.
// Every line's parentheses open and close in turn.
bool commentsWellFormed(const std::string& program, std::string& bad_line) {
  std::istringstream lines(program);
  std::string line;
  while (std::getline(lines, line)) {
    bool open = false;
    for (const char c : line) {
      if (c == '(' && open) break;
      if (c == '(') open = true;
      if (c == ')' && !open) {
        open = true;  // a ')' outside a comment: as wrong
        break;
      }
      if (c == ')') open = false;
    }
    if (open) {
      bad_line = line;
      return false;
    }
  }
  return true;
}

// A key given twice in one object: JSON keeps the last without a word, so a plan's radius of 100
// mm followed by one of 50 ran 50. Refused; the same key in two objects is two keys.
TEST(JsonFiles, AKeyGivenTwiceInOneObjectIsRefused) {
  for (const auto& [text, key] : std::vector<std::pair<std::string, std::string>>{
           {R"({"type": "circle", "radius_mm": 100, "radius_mm": 50})", "radius_mm"},
           {R"({"axes": [{"name": "X", "travel_mm": 1}, {"name": "Y", "name": "Z"}]})", "name"}}) {
    try {
      parseJsonText(text, "plan.json");
      ADD_FAILURE() << text;
    } catch (const InputError& e) {
      EXPECT_EQ(std::string(e.what()),
                "plan.json: key '" + key + "' is given twice in one object (which one is meant?)");
    }
  }
  // No file name at all (a plan given as ''): said so, not ": cannot open file".
  try {
    readJsonFile("");
    ADD_FAILURE() << "an empty file name opened";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), "a file name is needed, got ''");
  }
  const auto j = parseJsonText(R"({"a": {"x": 1}, "b": {"x": 2}, "x": 3})", "ok.json");
  EXPECT_EQ(j["b"]["x"], 2);
  EXPECT_EQ(j["x"], 3);
}

TEST(PartProgram, NamesWithParenthesesStayInsideOneComment) {
  std::string bad;
  LinearPlan linear = LinearPlan::demo();
  linear.name = "X (after repair)";
  const std::string program = linearGcode(linear);
  EXPECT_TRUE(commentsWellFormed(program, bad)) << bad;
  EXPECT_NE(program.find("(mtcal linear positioning plan: X [after repair])"), std::string::npos);
  const auto thermal = ThermalPlan::fromJson(readJsonFile(MTCAL_EXAMPLES_DIR "/plans/thermal/quick-2h.json"), "quick");
  ASSERT_NE(thermal.name.find('('), std::string::npos);  // the example's own name
  EXPECT_TRUE(commentsWellFormed(thermalGcode(thermal), bad)) << bad;
  auto circle = CirclePlan::fromJson(readJsonFile(MTCAL_EXAMPLES_DIR "/plans/ballbar/circle_xy_100.json"), "circle");
  circle.name = "r100 (XY)\nsecond line";
  EXPECT_TRUE(commentsWellFormed(circleGcode(circle), bad)) << bad;
  EXPECT_EQ(gcodeCommentText("a (b)\nc"), "a [b] c");
}

}  // namespace
}  // namespace mtcal::acquisition
