// mtcal against the independent numpy implementations in bench/ on the same inputs
// (bench/reference/numpy_reference.h, shared with the benchmarks): the volumetric map, the
// identification from measured lines and the gantry evaluation. Every value each side
// computes is compared; a name, a point or a hole that only one side has fails the test.

#include <gtest/gtest.h>

#include <iostream>

#include "numpy_reference.h"

namespace mtcal::reference {
namespace {

void expectAgreement(const Agreement& a, std::size_t expected_values, double tolerance) {
  for (const auto& m : a.mismatches) ADD_FAILURE() << m;
  EXPECT_EQ(a.compared, expected_values);
  EXPECT_LE(a.max_abs_difference, tolerance) << "largest difference at " << a.worst;
  ::testing::Test::RecordProperty("max_abs_difference", std::to_string(a.max_abs_difference));
  std::cout << "largest difference " << a.max_abs_difference << " (" << a.worst << ")\n";
}

// E = P_ideal - P, the difference of two positions of up to ~1e3 mm chained through 4 x 4
// transforms, times 1000: one rounding of such a position is 1e3 mm x 1.1e-16 = 1.1e-13 mm =
// 1.1e-10 um, and each side's chain of joint matrices takes of the order of a hundred
// roundings (the splines' values, a few um, round off far less). The tolerance is that bound,
// 1e-8 um; measured 3.4e-10 um (three roundings). A real difference (a term, a sign, a frame)
// is of the order of the errors, 0.1 to 10 um.
constexpr double kMapToleranceUm = 1e-8;

TEST(NumpyReference, VolumetricMapEqualsNumpysEverywhereOnTheGrid) {
  // Unequal counts per axis, so that axes taken in the wrong order or a grid run the wrong
  // way round do not line up by chance.
  const auto c = vmc3Model();
  const auto axes = mapGrid({17, 19, 23});
  const auto mtcal = c.model.predictGridUm(axes);
  ASSERT_EQ(mtcal.size(), 17u * 19u * 23u);
  const auto numpy = runNumpy("model_map_numpy.py", mapInput(c, axes), mapArgs(1, 0));
  ASSERT_EQ(numpy["points"], mtcal.size());
  expectAgreement(compareMap(mtcal, numpy), 3 * mtcal.size(), kMapToleranceUm);
}

// numpy's reading rows are central differences of the full model with 1 um / 1 urad steps:
// exact for the linear part, the quadratic part cancels and the cubic one (angles of 1e-6 rad
// cubed) is far below round-off. What is left is the round-off of readings that are positions
// of ~1e3 mm in um (1.1e-10 um each) over the 2 um of the step: ~1e-10 on a matrix whose
// largest entries are of order 1 (1 um per um; lever arms of 0.1 to 0.6 um per urad). The
// per-node solves amplify that relative error by at most their condition number, which the
// choice of unknowns keeps below 1000 (LineIdentificationOptions): 1e-7 of the values, up to
// 13 um / urad here: ~1e-6. The tolerance is that bound; measured 8.3e-10.
constexpr double kIdentificationToleranceUmOrUrad = 1e-6;

TEST(NumpyReference, IdentificationGivesNumpysCurvesNodeByNode) {
  const auto c = vmc3Model();
  const auto lines = directMethodLines(c.model);
  const auto mtcal = processing::identifyFromLines(c.model.kinematics(), lines, {});
  ASSERT_EQ(mtcal.curves.size(), 21u);  // 18 motion error functions and 3 squareness constants
  std::size_t values = 0;
  for (const auto& curve : mtcal.curves) values += curve.mean.size();
  const auto numpy = runNumpy("model_identify_numpy.py", identificationInput(c.machine, lines), {"1"});
  expectAgreement(compareIdentification(mtcal, numpy), values, kIdentificationToleranceUmOrUrad);
}

// dP is a difference of positions of up to 4000 mm in the tracker's frame (one rounding:
// 4.4e-13 mm = 4.4e-10 um) through planes, lines and circles fitted by SVD and Gauss-Newton
// (numpy's circle fit stops at a step of 1e-13 of the radius, mtcal's by its own rule) and the
// 300 mm tool length along the C axis' fitted direction. Measured 1.1e-8 um, some 25 roundings.
// The tolerance is the agreement the evaluation is held to against the model's truth in
// tests/processing/gantry_accuracy_test.cpp, 1e-6 um: two correct implementations stay well
// within it, a wrong step (a frame, a sign, a point kept or dropped) moves dP far more.
constexpr double kGantryToleranceUm = 1e-6;

TEST(NumpyReference, GantryEvaluationGivesNumpysDPOfEveryHole) {
  const auto evaluation = processing::evaluateGantry(gantryMeasurements());
  ASSERT_EQ(evaluation.holes.size(), 12u);
  const auto numpy = runNumpy("gantry_numpy.py", gantryExport(), {"1"});
  expectAgreement(compareGantry(evaluation, numpy), 3 * evaluation.holes.size(), kGantryToleranceUm);
}

}  // namespace
}  // namespace mtcal::reference
