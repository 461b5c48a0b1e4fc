// The controllers' table files, each against a hand-worked example of a small table (the
// correction, um: up 0 / +2 / -2 and down +1 / +3 / -1 at 0 / 10 / 20 mm), read back as the
// controller reads it, and refused where the controller cannot take the table. The formats'
// sources: docs/compensation.md.
#include "mtcal/processing/compensation_formats.h"

#include <gtest/gtest.h>

#include <functional>
#include <map>
#include <string>

#include "compensation_example.h"
#include "mtcal/error.h"

namespace mtcal::processing {
namespace {

/// The hand-worked table of compensation_example.h.
CompensationTable bidirectional() { return testing::threeEntries(); }

CompensationTable mean() {
  auto t = bidirectional();
  t.up_um = t.down_um = {0.5, 2.5, -1.5};
  return t;
}

/// A rotary axis every 90 deg, 360 deg period.
CompensationTable rotary() {
  CompensationTable t;
  t.position = {0.0, 90.0, 180.0, 270.0};
  t.up_um = t.down_um = {0.0, 4.0, 8.0, 4.0};
  t.modulo = 360.0;
  return t;
}

using testing::messageOf;

void expectSameTable(const CompensationTable& read, const CompensationTable& written, double tolerance_um) {
  ASSERT_EQ(read.position.size(), written.position.size());
  for (std::size_t i = 0; i < read.position.size(); ++i) {
    EXPECT_NEAR(read.position[i], written.position[i], 1e-9) << i;
    EXPECT_NEAR(read.up_um[i], written.up_um[i], tolerance_um) << i;
    EXPECT_NEAR(read.down_um[i], written.down_um[i], tolerance_um) << i;
  }
  EXPECT_EQ(read.modulo.has_value(), written.modulo.has_value());
  if (read.modulo && written.modulo) {
    EXPECT_DOUBLE_EQ(*read.modulo, *written.modulo);
  }
}

void expectRoundTrip(const char* controller, const CompensationTable& t, double tolerance_um = 1e-9) {
  const auto& f = controllerFormat(controller);
  expectSameTable(f.read(f.write(t, {"X", 0, ""}).text, "t"), t, tolerance_um);
}

// The axis a file is written for, as its reading names it: where the format names one (a
// controller's axis number), another axis' file is told apart from this one's.
TEST(ControllerFormats, AFileNamesTheAxisItWasWrittenFor) {
  const std::map<std::string, std::pair<std::string, std::string>> named = {
      {"siemens-eec", {"AX1", "AX2"}}, {"siemens-cec", {"AX1", "AX2"}}, {"fanuc", {"A1", "A2"}}};
  for (const auto& controller : controllerNames()) {
    const auto& f = controllerFormat(controller);
    const auto table = controller == "siemens-eec" ? mean() : bidirectional();
    const auto first = f.read(f.write(table, {"X", 0, ""}).text, "x"),
               second = f.read(f.write(table, {"Y", 1, ""}).text, "y");
    const auto it = named.find(controller);
    EXPECT_EQ(first.axis_in_file, it == named.end() ? "" : it->second.first) << controller;
    EXPECT_EQ(second.axis_in_file, it == named.end() ? "" : it->second.second) << controller;
  }
}

TEST(SiemensEec, HoldsTheErrorInMmOnAnEquidistantGrid) {
  // SINUMERIK's example (Extended Functions K3): the value is the error, "a positive compensation
  // value causes the machine axis to move in the negative direction"; correction +0.5 um -> -0.0005.
  const auto file = controllerFormat("siemens-eec").write(mean(), {"X", 0, ""});
  EXPECT_EQ(file.text,
            "%_N_AX_EEC_INI\n"
            "; axis X (AX1): the measured error (actual - nominal position), mm; a positive value moves the axis "
            "negative\n"
            "CHANDATA(1)\n"
            "$AA_ENC_COMP[0,0,AX1]=-0.000500\n"
            "$AA_ENC_COMP[0,1,AX1]=-0.002500\n"
            "$AA_ENC_COMP[0,2,AX1]=0.001500\n"
            "$AA_ENC_COMP_STEP[0,AX1]=10.000000\n"
            "$AA_ENC_COMP_MIN[0,AX1]=0.000000\n"
            "$AA_ENC_COMP_MAX[0,AX1]=20.000000\n"
            "$AA_ENC_COMP_IS_MODULO[0,AX1]=0\n"
            "M17\n");
  EXPECT_NE(file.setup.find("MD38000 $MA_MM_ENC_COMP_MAX_POINTS[0,AX1] >= 3"), std::string::npos);
  expectRoundTrip("siemens-eec", mean());
  // A rotary axis: the period closed by a last point equal to the first (MAX - MIN = 360).
  const auto closed = controllerFormat("siemens-eec").write(rotary(), {"A", 3, ""}).text;
  EXPECT_NE(closed.find("$AA_ENC_COMP[0,4,AX4]=0.000000\n"), std::string::npos);
  EXPECT_NE(closed.find("$AA_ENC_COMP_MAX[0,AX4]=360.000000\n$AA_ENC_COMP_IS_MODULO[0,AX4]=1\n"), std::string::npos);
  expectRoundTrip("siemens-eec", rotary());
}

TEST(SiemensEec, RefusesWhatItCannotHoldOrRead) {
  const auto& f = controllerFormat("siemens-eec");
  EXPECT_NE(messageOf([&] {
              f.write(bidirectional(), {"X", 0, ""});
            }).find("applies one table to both directions: give --mean, or --controller siemens-cec"),
            std::string::npos);
  auto uneven = mean();
  uneven.position[2] = 25.0;
  EXPECT_NE(messageOf([&] {
              f.write(uneven, {"X", 0, ""});
            }).find("takes entries at equal intervals: entry 3 is at 25, not 20; give --interval"),
            std::string::npos);
  const std::string good = f.write(mean(), {"X", 0, ""}).text;
  auto without = [&](const std::string& line) {
    std::string s = good;
    s.erase(s.find(line), line.size());
    return s;
  };
  EXPECT_NE(messageOf([&] {
              f.read(without("$AA_ENC_COMP_MAX[0,AX1]=20.000000\n"), "x.ini");
            }).find("x.ini: the table: _STEP, _MIN and _MAX are all needed"),
            std::string::npos);
  EXPECT_NE(messageOf([&] {
              f.read(without("$AA_ENC_COMP[0,1,AX1]=-0.002500\n"), "x.ini");
            }).find("x.ini: the table: _MIN 0 to _MAX 20 in steps of 10 needs 3 points, the table gives 2"),
            std::string::npos);
  EXPECT_NE(messageOf([&] {
              f.read(good + "G1 X10\n", "x.ini");
            }).find("line 12: 'G1 X10' is not an assignment the controller reads"),
            std::string::npos);
  EXPECT_NE(messageOf([&] { f.read("CHANDATA(1)\n", "x.ini"); }).find("line 1: a %_N_AX_EEC_INI file starts with"),
            std::string::npos);
}

TEST(SiemensCec, ATablePerDirectionOfTheAxisOnItself) {
  const auto file = controllerFormat("siemens-cec").write(bidirectional(), {"Y", 1, ""});
  EXPECT_EQ(file.text,
            "%_N_NC_CEC_INI\n"
            "; axis Y (AX2) on itself: the correction added to its position, mm; table 2 moving positive, table 3 "
            "moving negative\n"
            "CHANDATA(1)\n"
            "$AN_CEC[2,0]=0.000000\n$AN_CEC[2,1]=0.002000\n$AN_CEC[2,2]=-0.002000\n"
            "$AN_CEC_INPUT_AXIS[2]=(AX2)\n$AN_CEC_OUTPUT_AXIS[2]=(AX2)\n$AN_CEC_STEP[2]=10.000000\n"
            "$AN_CEC_MIN[2]=0.000000\n$AN_CEC_MAX[2]=20.000000\n$AN_CEC_DIRECTION[2]=1\n"
            "$AN_CEC_MULT_BY_TABLE[2]=0\n$AN_CEC_IS_MODULO[2]=0\n"
            "$AN_CEC[3,0]=0.001000\n$AN_CEC[3,1]=0.003000\n$AN_CEC[3,2]=-0.001000\n"
            "$AN_CEC_INPUT_AXIS[3]=(AX2)\n$AN_CEC_OUTPUT_AXIS[3]=(AX2)\n$AN_CEC_STEP[3]=10.000000\n"
            "$AN_CEC_MIN[3]=0.000000\n$AN_CEC_MAX[3]=20.000000\n$AN_CEC_DIRECTION[3]=-1\n"
            "$AN_CEC_MULT_BY_TABLE[3]=0\n$AN_CEC_IS_MODULO[3]=0\n"
            "M17\n");
  EXPECT_NE(file.setup.find("SD41300 $SN_CEC_TABLE_ENABLE[3] = 1"), std::string::npos);
  expectRoundTrip("siemens-cec", bidirectional());
  expectRoundTrip("siemens-cec", mean());  // one table, DIRECTION 0
  EXPECT_NE(controllerFormat("siemens-cec").write(mean(), {"X", 0, ""}).text.find("$AN_CEC_DIRECTION[0]=0\n"),
            std::string::npos);
  std::string positive_only = file.text.substr(0, file.text.find("$AN_CEC[3,0]")) + "M17\n";
  EXPECT_NE(messageOf([&] {
              controllerFormat("siemens-cec").read(positive_only, "c.ini");
            }).find("c.ini: no table for the negative direction"),
            std::string::npos);
}

TEST(Heidenhain, ComTableOfTheErrorWithItsBacklashColumnAndTheCma) {
  const auto file = controllerFormat("heidenhain").write(bidirectional(), {"X", 0, ""});
  EXPECT_EQ(file.text,
            "BEGIN X.COM MM\n"
            "NR    AXISPOS       X             BACKLASH\n"
            "0     +0.00000      +0.00000      -0.00100\n"
            "1     +10.00000     -0.00200      -0.00300\n"
            "2     +20.00000     +0.00200      +0.00100\n"
            "[END]\n");
  EXPECT_NE(file.setup.find("BEGIN CONFIG.CMA\nNR    X             ACTIVE\n0     X.COM         *\n[END]\n"),
            std::string::npos);
  expectRoundTrip("heidenhain", bidirectional());
  // A correction that rounds to zero at the file's 10 nm is written as zero, not "-0.00000".
  auto tiny = bidirectional();
  tiny.up_um[0] = 0.0037;
  EXPECT_NE(controllerFormat("heidenhain").write(tiny, {"X", 0, ""}).text.find("0     +0.00000      +0.00000"),
            std::string::npos);
  // Saved under another name: the table and the assignment name it.
  const auto named = controllerFormat("heidenhain").write(bidirectional(), {"X", 0, "XAXIS1.COM"});
  EXPECT_EQ(named.text.rfind("BEGIN XAXIS1.COM MM\n", 0), 0u);
  EXPECT_NE(named.setup.find("0     XAXIS1.COM    *"), std::string::npos);
  EXPECT_NE(controllerFormat("linuxcnc")
                .write(bidirectional(), {"X", 0, "x-2026.comp"})
                .setup.find("COMP_FILE = x-2026.comp\n"),
            std::string::npos);
  const auto& f = controllerFormat("heidenhain");
  EXPECT_NE(messageOf([&] {
              f.read(file.text.substr(0, file.text.find("[END]")), "X.COM");
            }).find("X.COM: no [END] line: the table is cut short"),
            std::string::npos);
  EXPECT_NE(
      messageOf([&] { f.read("BEGIN X.COM INCH\nNR AXISPOS X\n[END]\n", "X.COM"); }).find("mtcal reads tables in MM"),
      std::string::npos);
  CompensationTable many;
  for (int i = 0; i < 257; ++i) many.position.push_back(i), many.up_um.push_back(0), many.down_um.push_back(0);
  EXPECT_NE(messageOf([&] {
              f.write(many, {"X", 0, ""});
            }).find("257 entries, a table takes at most 256"),
            std::string::npos);
}

TEST(Fanuc, IncrementalValuesPerIntervalCountedFromTheReferencePoint) {
  // Point 0 is the reference (0 mm): its correction moving positive is Fanuc's zero. Moving up
  // the corrections 0, +2, -2 um are the increments 0, +2, -4 (the value at a point is the change
  // over the interval below it); moving down +1, +3, -1 um: 3627 = +1 um at the reference, then
  // the same increments, in points 3 to 5 (3626).
  const auto file = controllerFormat("fanuc").write(bidirectional(), {"X", 0, ""});
  EXPECT_EQ(file.text,
            "%\n"
            "N03620A1P0\nN03621A1P0\nN03622A1P2\nN03623A1P1\nN03624A1P10000\n"
            "N03626A1P3\nN03627A1P1\n"
            "N10000P0\nN10001P2\nN10002P-4\n"
            "N10003P0\nN10004P2\nN10005P-4\n"
            "%\n");
  EXPECT_NE(file.setup.find("set parameter 3605#0 (BDP) of axis A1 to 1"), std::string::npos);
  expectRoundTrip("fanuc", bidirectional());
  // A jump of 10 um over one interval does not fit in +-7: magnification 2, values in 2 um.
  CompensationTable steep = mean();
  steep.up_um = steep.down_um = {0.0, 10.0, 6.0};
  const auto magnified = controllerFormat("fanuc").write(steep, {"Y", 1, ""}).text;
  EXPECT_NE(magnified.find("N03623A2P2\n"), std::string::npos);
  EXPECT_NE(magnified.find("N10128P0\nN10129P5\nN10130P-2\n%\n"), std::string::npos);  // Y's numbers from 128
  expectRoundTrip("fanuc", steep);
  // A rotary axis: the reference is the first point, 3625 the travel per rotation, and the first
  // point's value is the last one's (the same interval, a rotation on): increments sum to zero.
  const auto turn = controllerFormat("fanuc").write(rotary(), {"A", 3, ""}).text;
  EXPECT_NE(turn.find("N03620A4P384\nN03621A4P384\nN03622A4P388\nN03623A4P1\nN03624A4P90000\nN03625A4P360000\n"),
            std::string::npos);
  EXPECT_NE(turn.find("N10384P-4\nN10385P4\nN10386P4\nN10387P-4\nN10388P-4\n"), std::string::npos);
  expectRoundTrip("fanuc", rotary());
}

TEST(Fanuc, TheTableIsShiftedToZeroAtTheReferenceAndRefusedWithoutOne) {
  auto shifted = bidirectional();
  for (auto* v : {&shifted.up_um, &shifted.down_um})
    for (auto& x : *v) x += 5.0;
  const auto& f = controllerFormat("fanuc");
  const auto file = f.write(shifted, {"X", 0, ""});
  EXPECT_NE(file.setup.find("the table is shifted by -5.000 um"), std::string::npos);
  expectSameTable(f.read(file.text, "x.prm"), bidirectional(), 1e-9);
  auto away = mean();
  away.position = {10.0, 20.0, 30.0};
  EXPECT_NE(messageOf([&] { f.write(away, {"X", 0, ""}); }).find("the table needs an entry at 0"), std::string::npos);
  CompensationTable many;
  for (int i = 0; i < 65; ++i) many.position.push_back(i), many.up_um.push_back(0), many.down_um.push_back(i % 2);
  EXPECT_NE(messageOf([&] {
              f.write(many, {"X", 0, ""});
            }).find("65 points per direction do not fit in the 128 compensation numbers of axis X (0 to 127)"),
            std::string::npos);
  EXPECT_NE(messageOf([&] {
              f.read("%\nN03620A1P0\nN03621A1P0\nN03622A1P2\nN03623A1P1\n%\n", "x.prm");
            }).find("x.prm: parameter 3624 is missing"),
            std::string::npos);
  EXPECT_NE(messageOf([&] {
              f.read(
                  "%\nN03620A1P0\nN03621A1P0\nN03622A1P1\nN03623A1P1\nN03624A1P1000\n"
                  "N10000P0\nN10001PX\n%\n",
                  "x.prm");
            }).find("x.prm: line 8: 'N10001PX' is not a record"),
            std::string::npos);
  // A point's value is -7 to +7 and the magnification at most 100: the controller takes no more.
  EXPECT_NE(messageOf([&] {
              f.read("%\nN03620A1P0\nN03621A1P0\nN03622A1P1\nN03623A1P1\nN03624A1P1000\nN10000P0\nN10001P-9\n%\n",
                     "x.prm");
            }).find("x.prm: compensation point 1: -9 is beyond FANUC's -7 to +7"),
            std::string::npos);
  EXPECT_NE(messageOf([&] {
              f.read("%\nN03620A1P0\nN03621A1P0\nN03622A1P1\nN03623A1P101\nN03624A1P1000\nN10000P0\nN10001P1\n%\n",
                     "x.prm");
            }).find("x.prm: parameter 3623: magnification 101 is beyond FANUC's 100"),
            std::string::npos);
}

TEST(TwinCatPtp, AdditiveCompensationElementsPerDirection) {
  const auto file = controllerFormat("twincat-ptp").write(bidirectional(), {"X", 0, ""});
  EXPECT_NE(file.text.find("\taCompensationXPositive : ARRAY[1..3] OF ST_PositionCompensationTableElement := [\n"
                           "\t\t(Position := 0.000000, Compensation := 0.000000),\n"
                           "\t\t(Position := 10.000000, Compensation := 0.002000),\n"
                           "\t\t(Position := 20.000000, Compensation := -0.002000)\n\t];\n"
                           "\tstCompensationXPositiveParameter : ST_PositionCompensationTableParameter := "
                           "(MinPosition := 0.000000, MaxPosition := 20.000000, NoOfTableElements := 3, Direction := "
                           "WorkDirectionPositive, Modulo := FALSE);\n"),
            std::string::npos);
  EXPECT_NE(file.text.find("(Position := 10.000000, Compensation := 0.003000),"), std::string::npos);
  expectRoundTrip("twincat-ptp", bidirectional());
  expectRoundTrip("twincat-ptp", mean());
  expectRoundTrip("twincat-ptp", rotary());
  std::string cut = file.text;
  const std::string element = "\t\t(Position := 10.000000, Compensation := 0.002000),\n";
  cut.erase(cut.find(element), element.size());
  EXPECT_NE(messageOf([&] {
              controllerFormat("twincat-ptp").read(cut, "x.st");
            }).find("x.st: an array of 3 elements holds 2"),
            std::string::npos);
}

TEST(TwinCatCnc, TheErrorInTenthsOfAMicrometrePerDirection) {
  // Beckhoff's example list (TF5200 axis compensation): "absolute position errors" in 0.1 um.
  const auto file = controllerFormat("twincat-cnc").write(bidirectional(), {"X", 0, ""});
  EXPECT_EQ(file.text,
            "kopf.log_achs_nr 1\nkopf.log_achs_name X\nkw.ssfk.interval 100000\nkw.ssfk.kw_startpos 0\n"
            "kw.ssfk.kw_nr_max 3\nkw.ssfk.unit 1\nkw.ssfk.bilateral 1\n"
            "kw.ssfk.table[0].pos 0\nkw.ssfk.table[1].pos -20\nkw.ssfk.table[2].pos 20\n"
            "kw.ssfk.table[0].neg -10\nkw.ssfk.table[1].neg -30\nkw.ssfk.table[2].neg 10\n");
  expectRoundTrip("twincat-cnc", bidirectional());
  expectRoundTrip("twincat-cnc", mean());
  std::string unit0 = file.text;
  unit0.replace(unit0.find("unit 1"), 6, "unit 0");
  EXPECT_NE(messageOf([&] {
              controllerFormat("twincat-cnc").read(unit0, "x.lis");
            }).find("kw.ssfk.unit 0: mtcal reads lists in 0.1 um"),
            std::string::npos);
  EXPECT_NE(messageOf([&] {
              controllerFormat("twincat-cnc").write(rotary(), {"A", 3, ""});
            }).find("no modulo"),
            std::string::npos);
}

}  // namespace
}  // namespace mtcal::processing
