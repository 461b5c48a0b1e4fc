#include "mtcal/mocks/gcode_player.h"

#include <gtest/gtest.h>

#include "mtcal/error.h"

namespace mtcal::mocks {
namespace {

TEST(GcodePlayer, ParsesTheSubsetMtcalWrites) {
  const auto blocks = parseGcode(
      "%\n(header comment)\nG21 G90 G94\nG1 X45.0000 F2000 (overrun)\nG1 Y12.5\nG4 P1.200\nG04 X0.5 ; fanuc\n"
      "G0 Z-3\nM30\n%\n");
  ASSERT_EQ(blocks.size(), 6u);
  EXPECT_EQ(blocks[0].kind, GcodeBlock::Kind::kMove);
  EXPECT_EQ(blocks[0].axis, Axis::kX);
  EXPECT_DOUBLE_EQ(blocks[0].value, 45.0);
  EXPECT_EQ(blocks[1].axis, Axis::kY);
  EXPECT_EQ(blocks[2].kind, GcodeBlock::Kind::kDwell);
  EXPECT_DOUBLE_EQ(blocks[2].value, 1.2);
  EXPECT_DOUBLE_EQ(blocks[3].value, 0.5);
  EXPECT_DOUBLE_EQ(blocks[4].value, -3.0);
  EXPECT_EQ(blocks[5].kind, GcodeBlock::Kind::kEnd);
  EXPECT_EQ(blocks[5].line, 9);
}

TEST(GcodePlayer, RejectsWhatItCannotRunWithTheLine) {
  auto error = [](const char* program) {
    try {
      parseGcode(program);
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(error("G1 X10\nG91\n").find("line 2: G91 is not supported"), std::string::npos);
  EXPECT_NE(error("G1 X1 A5\n").find("line 1: word A"), std::string::npos);
  EXPECT_NE(error("G4\n").find("line 1: a dwell"), std::string::npos);
  EXPECT_NE(error("G1 X1..2\n").find("line 1"), std::string::npos);
  EXPECT_NE(error("G1 #1\n").find("line 1: unexpected '#'"), std::string::npos);
}

TEST(GcodePlayer, RunsMovesAndDwellsOnTheWorldClock) {
  VirtualMachineConfig config;
  config.feed_mm_per_min = 6000.0;  // 100 mm/s
  WorldClock clock(500.0);
  VirtualMachine machine(config, clock);
  const double t0 = clock.nowS();
  runGcode(machine, parseGcode("G1 X100\nG4 P2\nG1 X50\nM30\nG1 X300\n"));
  EXPECT_EQ(machine.moveCount(), 2u);  // nothing after M30
  EXPECT_DOUBLE_EQ(machine.commanded()[0], 50.0);
  EXPECT_GE(clock.nowS() - t0, 1.0 + 2.0 + 0.5);  // 100 mm, the dwell, 50 mm
}

}  // namespace
}  // namespace mtcal::mocks
