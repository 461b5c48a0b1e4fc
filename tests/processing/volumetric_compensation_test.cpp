// Volumetric compensation (ISG's CSV): a hand-worked file, the controller's reading of it, the
// correction through the patent's VMC kinematics in closed form, and the refusals.
#include "mtcal/processing/volumetric_compensation.h"

#include <gtest/gtest.h>

#include <fstream>
#include <nlohmann/json.hpp>

#include "compensation_example.h"

namespace mtcal::processing {
namespace {

using testing::messageOf;

MultibodyModel vmc() {
  std::ifstream in(std::string(MTCAL_EXAMPLES_DIR) + "/machines/vmc3-cn104200063.model.json");
  return MultibodyModel::fromJson(nlohmann::json::parse(in), "vmc3-cn104200063.model.json");
}

/// X at 0 and 100 mm: EXX +2 / -1 um, EBX 5 / 0 urad; EC0Y 10 urad.
VolumetricTable handTable() {
  VolumetricTable t;
  t.axes.push_back({"x", {0.0, 100.0}, {{"EXX", {2.0, -1.0}}, {"EBX", {5.0, 0.0}}}});
  t.constants["EC0Y"] = 10.0;
  return t;
}

// ISG's CSV (Beckhoff Information System, TF5280 "ISG CSV format" and "Units of measure"): a
// header per block naming the argument and the errors, '#' before the next block, "//"
// comments, offsets in mm and angles in rad.
constexpr const char* kHandFile =
    "// hand example\n"
    "// ISO 230-1 component errors per axis and position errors; mm and rad, arguments mm (deg)\n"
    "X EBX EXX\n"
    "0.0000 0.0000050000 0.0020000\n"
    "100.0000 0.0000000000 -0.0010000\n"
    "#\n"
    "C0Y\n"
    "0.0000100000\n";

TEST(IsgVolumetricCsv, WritesTheHandWorkedFileAndReadsItBack) {
  EXPECT_EQ(writeIsgVolumetricCsv(handTable(), "hand example"), kHandFile);
  const auto read = readIsgVolumetricCsv(kHandFile, "hand.csv");
  ASSERT_EQ(read.axes.size(), 1u);
  EXPECT_EQ(read.axes[0].coordinate, "x");
  EXPECT_EQ(read.axes[0].position, (std::vector<double>{0.0, 100.0}));
  EXPECT_NEAR(read.axes[0].values.at("EXX")[0], 2.0, 1e-12);
  EXPECT_NEAR(read.axes[0].values.at("EXX")[1], -1.0, 1e-12);
  EXPECT_NEAR(read.axes[0].values.at("EBX")[0], 5.0, 1e-9);
  EXPECT_NEAR(read.constants.at("EC0Y"), 10.0, 1e-9);
  EXPECT_EQ(read.records(), 3u);
  const auto setup = isgVolumetricSetup(read, "vc.csv");
  EXPECT_NE(setup.find("X 1\n"), std::string::npos);
  EXPECT_NE(setup.find("file[0] vc.csv\nfile_format[0] ISG_CSV\n"), std::string::npos);
  EXPECT_NE(setup.find("vol_comp[0].max_records 3\n"), std::string::npos);
}

TEST(IsgVolumetricCsv, InterpolatesBetweenRowsAndHoldsBeyondTheEnds) {
  const auto kinematics = vmc();
  const auto t = handTable();
  const auto exx = kinematics.termIndex("EXX"), ebx = kinematics.termIndex("EBX");
  const auto ec0y = kinematics.termIndex("EC0Y"), eyy = kinematics.termIndex("EYY");
  const auto at = [&](double x) { return t.errorsAt(kinematics, Eigen::Vector3d(x, 200.0, 0.0)); };
  EXPECT_NEAR(at(50.0)(exx), 0.5, 1e-12);
  EXPECT_NEAR(at(50.0)(ebx), 2.5, 1e-12);
  EXPECT_NEAR(at(150.0)(exx), -1.0, 1e-12);
  EXPECT_NEAR(at(-10.0)(exx), 2.0, 1e-12);
  EXPECT_NEAR(at(50.0)(ec0y), 10.0, 1e-12);
  EXPECT_EQ(at(50.0)(eyy), 0.0);  // not in the table
}

TEST(IsgVolumetricCsv, TheCorrectionCancelsTheToolPointsErrorInClosedForm) {
  // The patent's VMC (docs/conventions.md): EXX moves the tool +X; EBX moves the tool point,
  // 120 mm under the Z carriage at z = 0, by EBX (z - 120) along X; EC0Y by -EC0Y y. At
  // (0, 200, 0): 2 um - 0.6 um - 2 um = -0.6 um along X, nothing along Y and Z, so the X
  // command gains +0.6 um. The full transform product adds second-order terms (rotation x
  // rotation x arm: below 1e-4 um here).
  const auto kinematics = vmc();
  std::array<int, 3> positioning{kinematics.termIndex("EXX"), kinematics.termIndex("EYY"), kinematics.termIndex("EZZ")};
  const auto d = volumetricCorrectionUm(kinematics, handTable(), Eigen::Vector3d(0.0, 200.0, 0.0), positioning);
  EXPECT_NEAR(d[0], 0.6, 1e-4);
  EXPECT_NEAR(d[1], 0.0, 1e-4);
  EXPECT_NEAR(d[2], 0.0, 1e-4);
  // At x = 100 mm EXX is -1 um and EBX zero: -1 - 2 = -3 um, the command +3 um.
  const auto d100 = volumetricCorrectionUm(kinematics, handTable(), Eigen::Vector3d(100.0, 200.0, 0.0), positioning);
  EXPECT_NEAR(d100[0], 3.0, 1e-4);
}

TEST(IsgVolumetricCsv, RefusesWhatTheControllerRefusesAndWhatMtcalCannotRead) {
  const auto refusal = [](const std::string& text) { return messageOf([&] { readIsgVolumetricCsv(text, "vc.csv"); }); };
  EXPECT_EQ(refusal("X EQX\n0 0\n"), "vc.csv: line 1: unknown identifier 'EQX'");
  EXPECT_EQ(refusal("X EXX\n0 0\n#\nX EXX\n1 0\n"), "vc.csv: line 4: 'EXX' is given twice");
  EXPECT_EQ(refusal("X EXX EYX\n0 0\n"), "vc.csv: line 2: 2 values for the 3 columns of line 1");
  EXPECT_EQ(refusal("Z X EXX\n0 0 0\n"), "vc.csv: line 1: a second argument 'X': mtcal reads blocks of one argument");
  EXPECT_EQ(refusal("X EYY\n0 0\n"), "vc.csv: line 1: 'EYY' depends on Y, not on the block's argument 'X'");
  EXPECT_EQ(refusal("X EXX\n10 0\n10 1\n"), "vc.csv: line 3: X = 10 does not increase (previous 10)");
  EXPECT_EQ(refusal("C0Y\n0\n1\n"), "vc.csv: line 3: position errors are constants: one record, not 2");
  EXPECT_EQ(refusal("X EXX\n#\n"), "vc.csv: line 1: a header without records");
  EXPECT_EQ(refusal("// nothing\n"), "vc.csv: no records (a header line, then rows of numbers)");
  EXPECT_EQ(refusal("X EXX\n0 0,002\n"), "vc.csv: line 2: '0,002' is not a number");
  const auto kinematics = vmc();
  VolumetricTable rotary;
  rotary.axes.push_back({"c", {0.0, 90.0}, {{"ECC", {0.0, 1.0}}}});
  EXPECT_EQ(messageOf([&] { rotary.errorsAt(kinematics, Eigen::Vector3d::Zero()); }),
            "the machine '3-axis vertical machining centre (patent CN104200063)' has no axis C (the compensation has)");
  EXPECT_EQ(messageOf([] {
              writeIsgVolumetricCsv({{}, {{"EXX1", 0.0}}}, "");
            }),
            "the error term 'EXX1' has no column in ISG's volumetric compensation");
}

}  // namespace
}  // namespace mtcal::processing
