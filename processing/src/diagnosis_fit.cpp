// The least-squares fit and its held-out cross-validation, shared by the candidate search
// (diagnosis.cpp) and the validation of stored extensions on other runs (diagnosis_extension.cpp).
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <vector>

#include "diagnosis_internal.h"

namespace mtcal::processing::detail {

LeastSquares leastSquares(const Eigen::MatrixXd& x, const Eigen::VectorXd& y, bool standard_errors) {
  LeastSquares f;
  if (x.cols() == 0) {
    f.residual = y;
    f.rss = y.squaredNorm();
    return f;
  }
  // Columns scaled to unit norm; a column that is numerically zero (a sinusoid sampled at its
  // zeros) stays zero rather than being blown up to a unit column of rounding errors.
  const double negligible = 1e-9 * std::sqrt(static_cast<double>(x.rows()));
  Eigen::VectorXd norms = x.colwise().norm().transpose();
  Eigen::MatrixXd xs = x;
  for (Eigen::Index j = 0; j < norms.size(); ++j) {
    if (norms(j) > negligible) {
      xs.col(j) /= norms(j);
    } else {
      xs.col(j).setZero();
      norms(j) = 1.0;
    }
  }
  // The complete orthogonal decomposition gives the least-squares solution of least norm even
  // when columns are dependent (column-pivoting QR's basic solution then misses the minimum).
  // The threshold is set before the decomposition: compute() builds Z for the rank it sees
  // then, and a threshold set afterwards changes rank() alone, so that solve() would apply
  // Householder coefficients of Z that were never computed (uninitialised memory).
  Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd> cod(xs.rows(), xs.cols());
  cod.setThreshold(1e-10);
  cod.compute(xs);
  f.rank = static_cast<int>(cod.rank());
  f.coefficients = cod.solve(y).cwiseQuotient(norms);
  f.residual = y - x * f.coefficients;
  f.rss = f.residual.squaredNorm();
  f.standard_error = Eigen::VectorXd::Zero(x.cols());
  const Eigen::Index dof = x.rows() - f.rank;
  if (standard_errors && dof > 0 && f.rank == x.cols()) {
    // At full rank the decomposition's T is the column-pivoting QR's R (no Z is applied).
    const Eigen::MatrixXd r = cod.matrixT().topLeftCorner(f.rank, f.rank).triangularView<Eigen::Upper>();
    const Eigen::MatrixXd rinv = r.triangularView<Eigen::Upper>().solve(Eigen::MatrixXd::Identity(f.rank, f.rank));
    const Eigen::VectorXd var_scaled = (rinv * rinv.transpose()).diagonal();
    const double s2 = f.rss / static_cast<double>(dof);
    for (Eigen::Index k = 0; k < f.rank; ++k) {
      const Eigen::Index j = cod.colsPermutation().indices()(k);
      f.standard_error(j) = std::sqrt(s2 * var_scaled(k)) / norms(j);
    }
  }
  return f;
}

HeldOut crossValidate(const Eigen::MatrixXd& x, const Eigen::VectorXd& y, const Eigen::VectorXi& fold) {
  HeldOut h;
  h.residual = Eigen::VectorXd::Zero(y.size());
  const int folds = fold.size() ? fold.maxCoeff() + 1 : 0;
  for (int f = 0; f < folds; ++f) {
    std::vector<Eigen::Index> train, test;
    for (Eigen::Index i = 0; i < y.size(); ++i) (fold(i) == f ? test : train).push_back(i);
    if (test.empty()) continue;
    const Eigen::MatrixXd xt = x(train, Eigen::all);
    const auto fit = leastSquares(xt, y(train), false);
    for (Eigen::Index i : test) h.residual(i) = y(i) - (x.cols() ? x.row(i).dot(fit.coefficients) : 0.0);
  }
  h.rms = std::sqrt(h.residual.squaredNorm() / static_cast<double>(std::max<Eigen::Index>(1, y.size())));
  h.peak = h.residual.cwiseAbs().maxCoeff();
  return h;
}

double rmsOf(const Eigen::VectorXd& r) {
  return r.size() ? std::sqrt(r.squaredNorm() / static_cast<double>(r.size())) : 0.0;
}

std::vector<double> distinct(const Eigen::VectorXd& v) {
  std::vector<double> s(v.data(), v.data() + v.size());
  std::sort(s.begin(), s.end());
  s.erase(std::unique(s.begin(), s.end(), [](double a, double b) { return std::abs(a - b) < 1e-9; }), s.end());
  return s;
}

}  // namespace mtcal::processing::detail
