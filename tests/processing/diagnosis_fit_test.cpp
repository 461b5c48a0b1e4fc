// The diagnosis' orthonormal basis of a design's columns (processing/src/diagnosis_fit.cpp),
// against the Householder QR's Q of the same columns.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <random>
#include <vector>

#include "diagnosis_internal.h"

namespace mtcal::processing::detail {
namespace {

std::vector<Eigen::Index> allColumns(const Eigen::MatrixXd& x) {
  std::vector<Eigen::Index> columns;
  for (Eigen::Index j = 0; j < x.cols(); ++j) columns.push_back(j);
  return columns;
}

/// How far x's columns are from the span of q: |x - q q'x| / |x|.
double outsideSpan(const Eigen::MatrixXd& q, const Eigen::MatrixXd& x) {
  return (x - q * (q.transpose() * x)).norm() / x.norm();
}

double offOrthonormal(const Eigen::MatrixXd& q) {
  return (q.transpose() * q - Eigen::MatrixXd::Identity(q.cols(), q.cols())).cwiseAbs().maxCoeff();
}

Eigen::MatrixXd householderQ(const Eigen::MatrixXd& x) {
  const Eigen::HouseholderQR<Eigen::MatrixXd> qr(x);
  return qr.householderQ() * Eigen::MatrixXd::Identity(x.rows(), x.cols());
}

TEST(OrthonormalBasis, SpansTheColumnsAsTheHouseholderQDoes) {
  // A run's design at 5000 readings (a tall matrix, reduced in blocks): a level, powers of the
  // position up to the 13th over 0..600 mm, a sine of 37 mm and a column of another scale (the
  // time in hours, a reading every 0.36 s): a condition of 2.6e9 at unit norms (numpy), near
  // what a fit still calls independent.
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> position(0.0, 600.0);
  const Eigen::Index n = 5000;
  Eigen::MatrixXd x(n, 16);
  for (Eigen::Index i = 0; i < n; ++i) {
    const double p = position(rng);
    for (int k = 0; k <= 13; ++k) x(i, k) = std::pow(p / 600.0, k);
    x(i, 14) = std::sin(2.0 * 3.141592653589793 * p / 37.0);
    x(i, 15) = 1e-4 * static_cast<double>(i);
  }
  const auto columns = allColumns(x);
  const Eigen::MatrixXd q = orthonormalBasis(x, columns);
  ASSERT_EQ(q.rows(), n);
  ASSERT_EQ(q.cols(), 16);
  const Eigen::MatrixXd reference = householderQ(x);
  EXPECT_LT(offOrthonormal(q), 1e-13);
  EXPECT_LT(offOrthonormal(q), 10.0 * offOrthonormal(reference) + 1e-14);
  EXPECT_LT(outsideSpan(q, x), 10.0 * outsideSpan(reference, x) + 1e-14);
  // The same space: each basis spans the other's columns, to the rounding times the condition
  // (1.3e-7 here: the span is that uncertain along its smallest singular value).
  EXPECT_LT(outsideSpan(q, reference), 1e-6);
  EXPECT_LT(outsideSpan(reference, q), 1e-6);
  // A selection of the columns, in the order given: their span only.
  const Eigen::MatrixXd q2 = orthonormalBasis(x, {15, 0, 3});
  ASSERT_EQ(q2.cols(), 3);
  EXPECT_LT(offOrthonormal(q2), 1e-13);
  EXPECT_LT(outsideSpan(q2, x(Eigen::all, std::vector<Eigen::Index>{15, 0, 3})), 1e-13);
  EXPECT_GT(outsideSpan(q2, x.col(1)), 0.01);  // the position itself is not in it
}

TEST(OrthonormalBasis, NoColumnsAndColumnsTooNearDependenceForTheTriangle) {
  Eigen::MatrixXd x = Eigen::MatrixXd::Random(300, 3);
  EXPECT_EQ(orthonormalBasis(x, {}).cols(), 0);
  EXPECT_EQ(orthonormalBasis(x, {}).rows(), 300);
  // A column given twice (a caller's mistake): the triangle is singular, and the basis is the
  // Householder Q's, still orthonormal and spanning the column.
  x.col(1) = x.col(0);
  const Eigen::MatrixXd q = orthonormalBasis(x, {0, 1});
  ASSERT_EQ(q.cols(), 2);
  EXPECT_TRUE(q.allFinite());
  EXPECT_EQ(q, householderQ(x.leftCols(2)));
  EXPECT_LT(offOrthonormal(q), 1e-13);
  EXPECT_LT(outsideSpan(q, x.col(0)), 1e-13);
  // Independent columns are not given the Householder Q (the triangle's way differs in rounding).
  x.col(1) = Eigen::VectorXd::Random(300);
  EXPECT_NE(orthonormalBasis(x, {0, 1}), householderQ(x.leftCols(2)));
}

}  // namespace
}  // namespace mtcal::processing::detail
