// Compensation tables: hand-worked examples of building a table from an axis' error, of the
// correction a controller applies from it, and of the LinuxCNC and CSV files.
#include "mtcal/processing/compensation.h"

#include <gtest/gtest.h>

#include <string>

#include "compensation_example.h"
#include "mtcal/error.h"
#include "mtcal/processing/compensation_formats.h"

namespace mtcal::processing {
namespace {

using D = Direction;

using testing::messageOf;
using testing::threeEntries;

TEST(CompensationTable, InterpolatesPerDirectionAndHoldsTheEnds) {
  const auto t = threeEntries();
  EXPECT_DOUBLE_EQ(t.correctionUm(5.0, D::kUp), 1.0);     // (0 + 2) / 2
  EXPECT_DOUBLE_EQ(t.correctionUm(15.0, D::kDown), 1.0);  // (3 - 1) / 2
  EXPECT_DOUBLE_EQ(t.correctionUm(17.5, D::kUp), -1.0);   // 2 + (-4) * 0.75
  EXPECT_DOUBLE_EQ(t.correctionUm(10.0, D::kDown), 3.0);
  EXPECT_DOUBLE_EQ(t.correctionUm(-5.0, D::kDown), 1.0);  // the first value held
  EXPECT_DOUBLE_EQ(t.correctionUm(25.0, D::kUp), -2.0);   // the last value held
  EXPECT_TRUE(t.bidirectional());
}

TEST(CompensationTable, StepsAndNoCorrectionBeyondUnderOtherRules) {
  const auto t = threeEntries();
  const TableRules steps{false, false};
  EXPECT_DOUBLE_EQ(t.correctionUm(9.99, D::kUp, steps), 0.0);  // the entry on the negative side
  EXPECT_DOUBLE_EQ(t.correctionUm(10.0, D::kUp, steps), 2.0);
  EXPECT_DOUBLE_EQ(t.correctionUm(15.0, D::kDown, steps), 3.0);
  EXPECT_DOUBLE_EQ(t.correctionUm(25.0, D::kUp, steps), 0.0);
  EXPECT_DOUBLE_EQ(t.correctionUm(-1.0, D::kDown, steps), 0.0);
}

TEST(CompensationTable, AModuloTableWrapsRoundTheCircle) {
  CompensationTable t;
  t.position = {0.0, 90.0, 180.0, 270.0};
  t.up_um = t.down_um = {0.0, 4.0, 8.0, 4.0};
  t.modulo = 360.0;
  EXPECT_DOUBLE_EQ(t.correctionUm(315.0, D::kUp), 2.0);  // from 4 at 270 to 0 at 360
  EXPECT_DOUBLE_EQ(t.correctionUm(-45.0, D::kUp), 2.0);
  EXPECT_DOUBLE_EQ(t.correctionUm(720.0 + 45.0, D::kUp), 2.0);
  EXPECT_DOUBLE_EQ(t.correctionUm(135.0, D::kDown), 6.0);
  EXPECT_FALSE(t.bidirectional());
}

AxisError measuredError() {
  AxisError e;
  e.position = {0.0, 20.0, 40.0};
  e.up_um = {1.0, 2.0, 3.0};
  e.down_um = {-1.0, 0.0, 1.0};
  return e;
}

TEST(CompensationTableFromError, CancelsTheErrorOnItsGridAndAtTheReference) {
  TableOptions o;
  o.interval = 10.0;
  auto t = compensationTable(measuredError(), o);
  ASSERT_EQ(t.position, (std::vector<double>{0, 10, 20, 30, 40}));
  EXPECT_EQ(t.up_um, (std::vector<double>{-1.0, -1.5, -2.0, -2.5, -3.0}));
  EXPECT_EQ(t.down_um, (std::vector<double>{1.0, 0.5, 0.0, -0.5, -1.0}));
  // Zero at 20 mm: the mean of -2 and 0 comes off both directions; the reversal stays 2 um.
  o.reference = 20.0;
  t = compensationTable(measuredError(), o);
  EXPECT_EQ(t.up_um, (std::vector<double>{0.0, -0.5, -1.0, -1.5, -2.0}));
  EXPECT_EQ(t.down_um, (std::vector<double>{2.0, 1.5, 1.0, 0.5, 0.0}));
  // The mean of both directions, rounded to 1 um.
  o.reference.reset();
  o.bidirectional = false;
  o.resolution_um = 1.0;
  t = compensationTable(measuredError(), o);
  EXPECT_EQ(t.up_um, (std::vector<double>{0.0, -1.0, -1.0, -2.0, -2.0}));  // 0, -0.5, -1, -1.5, -2 rounded
  EXPECT_EQ(t.down_um, t.up_um);
}

TEST(CompensationTableFromError, ASecondIterationAddsWhatTheFirstLeft) {
  // The machine ran the first table while it was measured again: 0.2 um left everywhere going up.
  TableOptions o;
  const auto first = compensationTable(measuredError(), o);
  AxisError left;
  left.position = {0.0, 20.0, 40.0};
  left.up_um = {0.2, 0.2, 0.2};
  left.down_um = {0.0, 0.0, 0.0};
  const auto second = compensationTable(left, o, &first);
  EXPECT_EQ(second.up_um, (std::vector<double>{-1.2, -2.2, -3.2}));
  EXPECT_EQ(second.down_um, first.down_um);
}

TEST(CompensationTableFromError, RefusesWhatCannotBeATable) {
  TableOptions o;
  o.interval = 15.0;
  EXPECT_NE(messageOf([&] { compensationTable(measuredError(), o); }).find("does not divide the range"),
            std::string::npos);
  o.interval = 10.0;
  o.end = 50.0;
  EXPECT_NE(messageOf([&] { compensationTable(measuredError(), o); }).find("outside the measured range [0, 40]"),
            std::string::npos);
  o.end.reset();
  o.max_points = 4;
  EXPECT_NE(messageOf([&] { compensationTable(measuredError(), o); }).find("5 entries, the controller takes at most 4"),
            std::string::npos);
  o.max_points = 0;
  o.reference = 45.0;
  EXPECT_NE(messageOf([&] { compensationTable(measuredError(), o); }).find("reference point 45 is outside"),
            std::string::npos);
  auto t = threeEntries();
  t.position[2] = 10.0;
  EXPECT_NE(messageOf([&] { checkTable(t, "t"); }).find("entry 3: position 10 does not increase"), std::string::npos);
}

TEST(CompensationTableFromError, TakesTheMeanDeviationsOfAnIso230Evaluation) {
  Iso230Result r;
  r.positions.resize(2);
  r.positions[0].target_mm = 0.0;
  r.positions[0].mean_up_um = 1.5;
  r.positions[0].mean_down_um = -0.5;
  r.positions[1].target_mm = 20.0;
  r.positions[1].mean_up_um = 2.5;  // measured going up only
  const auto e = axisErrorOf(r);
  EXPECT_EQ(e.up_um, (std::vector<double>{1.5, 2.5}));
  EXPECT_EQ(e.down_um, (std::vector<double>{-0.5, 2.5}));
  EXPECT_DOUBLE_EQ(e.at(5.0, D::kDown), -0.5 + 3.0 * 0.25);
}

TEST(LinuxCncCompFile, Type0HoldsWhereTheAxisIsAndType1TheTrims) {
  // Correction +2 um at 10 mm going up: the axis stands at 9.998 mm when told 10 (trim =
  // nominal - actual = +0.002 mm, LinuxCNC's src/emc/motion/usrmotintf.cc).
  const auto& type0 = controllerFormat("linuxcnc");
  const auto file = type0.write(threeEntries(), {"X", 0, ""});
  EXPECT_EQ(file.text,
            "0.000000 0.000000 -0.001000\n"
            "10.000000 9.998000 9.997000\n"
            "20.000000 20.002000 20.001000\n");
  EXPECT_NE(file.setup.find("[JOINT_0]\n"), std::string::npos);
  EXPECT_NE(file.setup.find("COMP_FILE = X.comp\nCOMP_FILE_TYPE = 0\n"), std::string::npos);
  const auto trims = controllerFormat("linuxcnc-trim").write(threeEntries(), {"Y", 1, ""});
  EXPECT_EQ(trims.text,
            "0.000000 0.000000 0.001000\n"
            "10.000000 0.002000 0.003000\n"
            "20.000000 -0.002000 -0.001000\n");
  EXPECT_NE(trims.setup.find("[JOINT_1]"), std::string::npos);
  EXPECT_NE(trims.setup.find("COMP_FILE_TYPE = 1"), std::string::npos);
  for (const auto* f : {&type0, &controllerFormat("linuxcnc-trim")}) {
    const auto back = f->read(f->write(threeEntries(), {"X", 0, ""}).text, "x.comp");
    ASSERT_EQ(back.position, threeEntries().position);
    for (std::size_t i = 0; i < 3; ++i) {
      EXPECT_NEAR(back.up_um[i], threeEntries().up_um[i], 1e-9);
      EXPECT_NEAR(back.down_um[i], threeEntries().down_um[i], 1e-9);
    }
  }
}

TEST(LinuxCncCompFile, RefusesWhatLinuxCncWouldDropSilently) {
  const auto& f = controllerFormat("linuxcnc-trim");
  EXPECT_NE(messageOf([&] { f.read("nominal forward reverse\n0 0 0\n10 0 0\n", "t.comp"); })
                .find("t.comp: line 1: 'nominal forward reverse' is not three numbers: LinuxCNC ends the table "
                      "there without a word and would load 0 entries"),
            std::string::npos);
  EXPECT_NE(messageOf([&] { f.read("0 0 0\n# comment\n10 0 0\n", "t.comp"); }).find("line 2"), std::string::npos);
  EXPECT_NE(messageOf([&] {
              f.read("0 0 0\n10 0 0\n10 0 0\n", "t.comp");
            }).find("line 3: nominal 10 does not increase: LinuxCNC rejects the entry"),
            std::string::npos);
  std::string many;
  for (int i = 0; i < 257; ++i) many += std::to_string(i) + " 0 0\n";
  EXPECT_NE(messageOf([&] { f.read(many, "t.comp"); }).find("257 entries: LinuxCNC takes at most 256"),
            std::string::npos);
  EXPECT_EQ(f.read("0 0 0\r\n10 0.001 0\r\n\n\n", "t.comp").up_um[1], 1.0);  // CR LF and blank lines at the end
  CompensationTable rotary = threeEntries();
  rotary.modulo = 360.0;
  EXPECT_NE(messageOf([&] { f.write(rotary, {"A", 3, ""}); }).find("no modulo"), std::string::npos);
}

TEST(CompensationCsv, HoldsErrorAndCorrectionAndReadsBack) {
  const auto& f = controllerFormat("csv");
  const auto file = f.write(threeEntries(), {"X", 0, ""});
  EXPECT_EQ(file.text,
            "position,error_up_um,error_down_um,correction_up_um,correction_down_um\n"
            "0,0.0000,-1.0000,0.0000,1.0000\n"
            "10,-2.0000,-3.0000,2.0000,3.0000\n"
            "20,2.0000,1.0000,-2.0000,-1.0000\n");
  EXPECT_EQ(f.read(file.text, "t.csv").down_um, threeEntries().down_um);
  EXPECT_NE(messageOf([] { controllerFormat("haas"); }).find("unknown controller 'haas' (one of: csv, linuxcnc"),
            std::string::npos);
  EXPECT_NE(
      messageOf([] { controllerFormat("haas"); }).find("; of a model, also isg-volumetric: its volumetric table)"),
      std::string::npos);
  EXPECT_NE(messageOf([] {
              controllerFormat(kIsgVolumetric);
            }).find("isg-volumetric is a model's volumetric table (every axis in one file), not one axis' table"),
            std::string::npos);
}

}  // namespace
}  // namespace mtcal::processing
