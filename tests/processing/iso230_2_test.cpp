#include "mtcal/processing/iso230_2.h"

#include <gtest/gtest.h>

#include <cmath>

#include "mtcal/error.h"

namespace mtcal::processing {
namespace {

// A hand-computed set (4 targets, 3 cycles each way) built so that every max/min of
// ISO 230-2:2014 clause 3 is taken at a different target or direction:
//   up:   P1 {1,2,3}  P2 {5,5,5}  P3 {-1,0,4}  P4 {0,0,6}
//   down: P1 {0,0,3}  P2 {2,4,6}  P3 {-4,-3,-2} P4 {2,2,2}
// means up 2, 5, 1, 2; down 1, 4, -3, 2; s up 1, 0, sqrt 7, sqrt 12; s down sqrt 3, 2, 1, 0.
std::vector<PositionDeviation> handSet() {
  const double targets[] = {0.0, 100.0, 200.0, 300.0};
  const double up[4][3] = {{1, 2, 3}, {5, 5, 5}, {-1, 0, 4}, {0, 0, 6}};
  const double down[4][3] = {{0, 0, 3}, {2, 4, 6}, {-4, -3, -2}, {2, 2, 2}};
  std::vector<PositionDeviation> d;
  for (int i = 0; i < 4; ++i) {
    for (int j = 0; j < 3; ++j) {
      d.push_back({targets[i], Direction::kUp, j + 1, up[i][j]});
      d.push_back({targets[i], Direction::kDown, j + 1, down[i][j]});
    }
  }
  return d;
}

TEST(Iso230_2, PerPositionValuesAreMeansOverCyclesAndSampleDeviations) {
  const auto r = evaluateIso230_2(handSet());
  ASSERT_EQ(r.positions.size(), 4u);
  const auto& p3 = r.positions[2];
  EXPECT_DOUBLE_EQ(*p3.mean_up_um, 1.0);  // divided by the 3 cycles, not by the 4 targets
  EXPECT_DOUBLE_EQ(*p3.mean_down_um, -3.0);
  EXPECT_NEAR(*p3.s_up_um, std::sqrt(7.0), 1e-12);  // n - 1 in the denominator
  EXPECT_NEAR(*p3.s_down_um, 1.0, 1e-12);
  EXPECT_DOUBLE_EQ(*p3.reversal_um, 4.0);  // B_i = up - down, not down - up
  EXPECT_DOUBLE_EQ(*p3.mean_um, -1.0);
  EXPECT_EQ(p3.cycles_up, 3);
}

TEST(Iso230_2, BidirectionalRepeatabilityTakesEachBranchOfItsMax) {
  const auto r = evaluateIso230_2(handSet());
  // P1: R_down (4 sqrt 3 = 6.928) beats 2 s_up + 2 s_down + |B| = 6.464.
  EXPECT_NEAR(*r.positions[0].repeatability_um, 4.0 * std::sqrt(3.0), 1e-12);
  // P3: the sum 2 sqrt 7 + 2 + 4 = 11.29 beats R_up 10.58 and R_down 4.
  EXPECT_NEAR(*r.positions[2].repeatability_um, 2.0 * std::sqrt(7.0) + 2.0 + 4.0, 1e-12);
  // P4: R_up (4 sqrt 12 = 13.86) beats the sum 6.93.
  EXPECT_NEAR(*r.positions[3].repeatability_um, 4.0 * std::sqrt(12.0), 1e-12);
}

TEST(Iso230_2, AxisValuesMatchHandComputation) {
  const auto r = evaluateIso230_2(handSet());
  EXPECT_DOUBLE_EQ(*r.B_um, 4.0);                                 // max |B_i|, at P3
  EXPECT_DOUBLE_EQ(*r.B_mean_um, (1.0 + 1.0 + 4.0 + 0.0) / 4.0);  // over the 4 targets
  EXPECT_NEAR(*r.R_up_um, 4.0 * std::sqrt(12.0), 1e-12);          // max R_i up (P4), not R up of one target
  EXPECT_NEAR(*r.R_down_um, 8.0, 1e-12);                          // P2
  EXPECT_NEAR(*r.R_um, 4.0 * std::sqrt(12.0), 1e-12);
  EXPECT_DOUBLE_EQ(*r.E_up_um, 5.0 - 1.0);
  EXPECT_DOUBLE_EQ(*r.E_down_um, 4.0 - (-3.0));
  EXPECT_DOUBLE_EQ(*r.E_um, 5.0 - (-3.0));  // max from the up means, min from the down means
  EXPECT_DOUBLE_EQ(*r.M_um, 4.5 - (-1.0));
  // A up: max(x + 2s) = 2 + 2 sqrt 12 (P4), min(x - 2s) = 2 - 2 sqrt 12 (P4).
  EXPECT_NEAR(*r.A_up_um, 4.0 * std::sqrt(12.0), 1e-12);
  // A down: max 4 + 4 = 8 (P2), min -3 - 2 = -5 (P3).
  EXPECT_NEAR(*r.A_down_um, 13.0, 1e-12);
  // A: max over both directions 2 + 2 sqrt 12 (up, P4), min -5 (down, P3).
  EXPECT_NEAR(*r.A_um, 2.0 + 2.0 * std::sqrt(12.0) + 5.0, 1e-12);
  EXPECT_EQ(r.min_cycles, 3);
}

TEST(Iso230_2, UnidirectionalRunHasNoBidirectionalValues) {
  std::vector<PositionDeviation> d;
  for (const auto& x : handSet()) {
    if (x.direction == Direction::kUp) d.push_back(x);
  }
  const auto r = evaluateIso230_2(d);
  EXPECT_TRUE(r.E_up_um.has_value());
  EXPECT_FALSE(r.E_down_um.has_value());
  EXPECT_FALSE(r.B_um.has_value());
  EXPECT_FALSE(r.E_um.has_value());
  EXPECT_FALSE(r.A_um.has_value());
  EXPECT_FALSE(r.positions[0].repeatability_um.has_value());
}

TEST(Iso230_2, RejectsDataThatCannotBeEvaluated) {
  // One cycle only: no s.
  EXPECT_THROW(
      evaluateIso230_2(std::vector<PositionDeviation>{{0, Direction::kUp, 1, 1.0}, {10, Direction::kUp, 1, 2.0}}),
      InputError);
  // A cycle given twice.
  auto dup = handSet();
  dup.push_back({0.0, Direction::kUp, 2, 9.0});
  EXPECT_THROW(evaluateIso230_2(dup), InputError);
  // One target lacks the down direction the others have.
  auto missing = handSet();
  std::erase_if(missing, [](const auto& x) { return x.target_mm == 300.0 && x.direction == Direction::kDown; });
  try {
    evaluateIso230_2(missing);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("300"), std::string::npos) << e.what();
  }
  EXPECT_THROW(evaluateIso230_2(std::vector<PositionDeviation>{}), InputError);
}

}  // namespace
}  // namespace mtcal::processing
