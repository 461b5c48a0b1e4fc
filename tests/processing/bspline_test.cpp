#include "mtcal/processing/bspline.h"

#include <gtest/gtest.h>

#include <cmath>

#include "mtcal/error.h"

namespace mtcal::processing {
namespace {

// scipy.interpolate.BSpline documentation example: k = 2, t = [0, 1, 2, 3, 4, 5, 6],
// c = [-1, 2, 0, -1] gives S(2.5) = 1.375.
TEST(BSpline, MatchesTheScipyDocumentationExample) {
  Eigen::VectorXd c(4);
  c << -1, 2, 0, -1;
  const BSpline s(2, {0, 1, 2, 3, 4, 5, 6}, c);
  EXPECT_NEAR(s(2.5), 1.375, 1e-15);
  EXPECT_DOUBLE_EQ(s.lower(), 2.0);
  EXPECT_DOUBLE_EQ(s.upper(), 4.0);
}

TEST(BSpline, ClampedBasisIsAPartitionOfUnity) {
  const auto knots = BSpline::clampedKnots(50.0, 600.0, 3, {150.0, 250.0, 350.0, 450.0, 550.0});
  const BSpline s(3, knots, Eigen::VectorXd::Zero(static_cast<Eigen::Index>(knots.size()) - 4));
  for (double x = 50.0; x <= 600.0; x += 7.3) {
    const auto b = s.basis(x);
    EXPECT_NEAR(b.sum(), 1.0, 1e-13) << x;
    EXPECT_GE(b.minCoeff(), 0.0);
  }
  EXPECT_NEAR(s.basis(600.0).sum(), 1.0, 1e-13);  // the closed right end
}

// de Boor, A Practical Guide to Splines (ch. XIII, knots for interpolation): t_{i+k} is the
// mean of the k-1 sites x_{i+1} .. x_{i+k-1}. Even sites give even knots.
TEST(BSpline, AveragedInteriorKnotsAreDeBoorsForInterpolation) {
  const std::vector<double> sites{0, 1, 2, 4, 7, 11, 16};
  const auto k = BSpline::averagedInteriorKnots(sites, 3, 4);  // 7 sites - degree 3: interpolation
  ASSERT_EQ(k.size(), 3u);
  EXPECT_DOUBLE_EQ(k[0], (1.0 + 2.0 + 4.0) / 3.0);
  EXPECT_DOUBLE_EQ(k[1], (2.0 + 4.0 + 7.0) / 3.0);
  EXPECT_DOUBLE_EQ(k[2], (4.0 + 7.0 + 11.0) / 3.0);
  std::vector<double> even;
  for (int i = 0; i <= 27; ++i) even.push_back(50.0 + 20.0 * i);
  const auto e = BSpline::averagedInteriorKnots(even, 3, 9);
  ASSERT_EQ(e.size(), 8u);
  for (std::size_t i = 0; i < e.size(); ++i) EXPECT_NEAR(e[i], 50.0 + 60.0 * (i + 1), 1e-9);
  EXPECT_THROW(BSpline::averagedInteriorKnots(sites, 3, 5), InputError);  // more coefficients than sites
}

// The spline space of degree k contains every polynomial of degree <= k: the least-squares
// fit of exact cubic data must return the cubic.
TEST(BSpline, FitReproducesAPolynomialOfItsDegree) {
  auto cubic = [](double x) { return 1.5 - 0.02 * x + 3e-5 * x * x - 2e-8 * x * x * x; };
  Eigen::VectorXd x(28), y(28), w(28);
  for (int i = 0; i < 28; ++i) {
    x(i) = 50.0 + 20.0 * i;
    y(i) = cubic(x(i));
    w(i) = 1.0 + i % 3;
  }
  std::vector<double> sites(x.data(), x.data() + x.size());
  const auto knots = BSpline::clampedKnots(50.0, 590.0, 3, BSpline::averagedInteriorKnots(sites, 3, 9));
  const BSpline s = BSpline::fit(3, knots, x, y, w);
  for (double v = 50.0; v <= 590.0; v += 3.0) EXPECT_NEAR(s(v), cubic(v), 1e-10) << v;
}

// Degree 0 on one span is a constant: the weighted least-squares constant is the weighted
// mean sum(w y) / sum(w) (closed form). Weights 1/s^2 make a noisy node count less.
TEST(BSpline, WeightedFitOfAConstantIsTheWeightedMean) {
  Eigen::VectorXd x(3), y(3), w(3);
  x << 1, 2, 3;
  y << 1.0, 2.0, 10.0;
  w << 1.0 / (0.5 * 0.5), 1.0 / (0.5 * 0.5), 1.0 / (5.0 * 5.0);
  const BSpline s = BSpline::fit(0, {0.0, 10.0}, x, y, w);
  EXPECT_NEAR(s(5.0), (4.0 * 1.0 + 4.0 * 2.0 + 0.04 * 10.0) / (4.0 + 4.0 + 0.04), 1e-13);
}

TEST(BSpline, RefusesDataThatCannotDetermineTheSpline) {
  Eigen::VectorXd x(6), y = Eigen::VectorXd::Zero(6), w = Eigen::VectorXd::Ones(6);
  x << 0, 1, 2, 3, 4, 5;  // nothing in (6, 10)
  const auto knots = BSpline::clampedKnots(0.0, 10.0, 1, {2.0, 4.0, 6.0, 8.0});
  try {
    BSpline::fit(1, knots, x, y, w);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("undetermined"), std::string::npos) << e.what();
  }
  EXPECT_THROW(BSpline::fit(1, knots, x.head(3), y.head(3), w.head(3)), InputError);  // 3 points, 6 coefficients
  w(2) = 0.0;
  EXPECT_THROW(BSpline::fit(0, {0.0, 10.0}, x, y, w), InputError);
  EXPECT_THROW(BSpline(2, {0, 1, 2}, Eigen::VectorXd::Zero(4)), InputError);
  EXPECT_THROW(BSpline::clampedKnots(0.0, 10.0, 3, {5.0, 4.0}), InputError);
}

}  // namespace
}  // namespace mtcal::processing
