#include "mtcal/processing/regression.h"

#include <fmt/format.h>

#include <Eigen/QR>
#include <algorithm>
#include <cmath>
#include <numbers>

#include "mtcal/error.h"
#include "mtcal/processing/evidence.h"

namespace mtcal::processing {
namespace {

Eigen::MatrixXd design(const Eigen::MatrixXd& x, bool intercept) {
  if (!intercept) return x;
  Eigen::MatrixXd a(x.rows(), x.cols() + 1);
  a.col(0).setOnes();
  a.rightCols(x.cols()) = x;
  return a;
}

/// Least squares on a design matrix (columns scaled to unit norm for the solve).
Eigen::VectorXd solve(const Eigen::MatrixXd& a, const Eigen::VectorXd& y) {
  if (a.rows() <= a.cols()) {
    throw InputError(fmt::format("regression: {} observations for {} coefficients", a.rows(), a.cols()));
  }
  const Eigen::VectorXd norms = a.colwise().norm().transpose();
  for (Eigen::Index j = 0; j < norms.size(); ++j) {
    if (!(norms(j) > 0.0)) throw InputError(fmt::format("regression: column {} is zero", j));
  }
  const Eigen::MatrixXd scaled = a * norms.cwiseInverse().asDiagonal();
  Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(scaled);
  qr.setThreshold(1e-12);
  if (qr.rank() < a.cols()) {
    throw InputError(fmt::format("regression: the {} columns are linearly dependent (rank {})", a.cols(), qr.rank()));
  }
  return qr.solve(y).cwiseQuotient(norms);
}

LinearFit statistics(Eigen::VectorXd coefficients, Eigen::VectorXd residuals, int k) {
  LinearFit f;
  f.coefficients = std::move(coefficients);
  f.residuals = std::move(residuals);
  f.n = static_cast<int>(f.residuals.size());
  f.k = k;
  f.rss = f.residuals.squaredNorm();
  const auto ic = informationCriteria(f.rss, f.n, k);
  f.log_likelihood = ic.log_likelihood;
  f.aic = ic.aic;
  f.bic = ic.bic;
  f.durbin_watson = durbinWatson(f.residuals);
  return f;
}

}  // namespace

InformationCriteria informationCriteria(double rss, int n, int k) {
  const double nd = n;
  InformationCriteria ic;
  ic.log_likelihood = -nd / 2.0 * (std::log(2.0 * std::numbers::pi) + std::log(rss / nd) + 1.0);
  ic.aic = -2.0 * ic.log_likelihood + 2.0 * k;
  ic.bic = -2.0 * ic.log_likelihood + k * std::log(nd);
  return ic;
}

double rssWithAddedColumns(double rss, Eigen::MatrixXd gram, const Eigen::VectorXd& cross) {
  if (gram.size() == 0) return rss;
  Eigen::VectorXd scale(gram.rows());
  const double largest = gram.diagonal().cwiseAbs().maxCoeff();
  for (Eigen::Index j = 0; j < gram.rows(); ++j)
    scale(j) = gram(j, j) > 1e-10 * largest ? 1.0 / std::sqrt(gram(j, j)) : 0.0;
  gram = scale.asDiagonal() * gram * scale.asDiagonal();
  Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd> cod(gram.rows(), gram.cols());
  cod.setThreshold(1e-10);
  cod.compute(gram);
  const Eigen::VectorXd scaled = scale.cwiseProduct(cross);
  return rss - scaled.dot(cod.solve(scaled));
}

double durbinWatson(const Eigen::VectorXd& e) {
  if (e.size() < 2) return 0.0;
  const double rss = e.squaredNorm();
  if (!(rss > 0.0)) return 0.0;
  return (e.tail(e.size() - 1) - e.head(e.size() - 1)).squaredNorm() / rss;
}

double ljungBox(const Eigen::VectorXd& residuals, int lags) {
  const Eigen::Index n = residuals.size();
  if (lags < 1 || lags >= n) throw InputError(fmt::format("Ljung-Box: {} lags for {} residuals", lags, n));
  const Eigen::VectorXd e = residuals.array() - residuals.mean();
  const double c0 = e.squaredNorm();
  if (!(c0 > 0.0)) return 0.0;
  double q = 0.0;
  for (int k = 1; k <= lags; ++k) {
    const double r = e.tail(n - k).dot(e.head(n - k)) / c0;
    q += r * r / static_cast<double>(n - k);
  }
  return static_cast<double>(n) * static_cast<double>(n + 2) * q;
}

double chiSquareSurvival(double x, double dof) {
  if (!(dof > 0.0)) throw InputError(fmt::format("chi-square: {} degrees of freedom", dof));
  if (x <= 0.0) return 1.0;
  const double a = dof / 2.0, z = x / 2.0;
  const double log_prefactor = a * std::log(z) - z - logGamma(a);
  if (z < a + 1.0) {  // P(a, z) by its series, Q = 1 - P
    double term = 1.0 / a, sum = term;
    for (int k = 1; k < 1000 && std::abs(term) > std::abs(sum) * 1e-16; ++k) {
      term *= z / (a + k);
      sum += term;
    }
    return std::max(0.0, 1.0 - std::exp(log_prefactor) * sum);
  }
  // Q(a, z) by the continued fraction 1/(z+1-a- 1(1-a)/(z+3-a- 2(2-a)/(z+5-a- ...))), modified Lentz.
  constexpr double kTiny = 1e-300;
  double b = z + 1.0 - a, c = 1.0 / kTiny, d = 1.0 / b, h = d;
  for (int i = 1; i < 1000; ++i) {
    const double an = -i * (i - a);
    b += 2.0;
    d = an * d + b;
    if (std::abs(d) < kTiny) d = kTiny;
    c = b + an / c;
    if (std::abs(c) < kTiny) c = kTiny;
    d = 1.0 / d;
    const double delta = d * c;
    h *= delta;
    if (std::abs(delta - 1.0) < 1e-16) break;
  }
  return std::exp(log_prefactor) * h;
}

LinearFit fitLinear(const Eigen::MatrixXd& x, const Eigen::VectorXd& y, bool intercept) {
  if (x.rows() != y.size())
    throw InputError(fmt::format("regression: {} rows of x but {} values of y", x.rows(), y.size()));
  const Eigen::MatrixXd a = design(x, intercept);
  Eigen::VectorXd b = solve(a, y);
  Eigen::VectorXd r = y - a * b;
  return statistics(std::move(b), std::move(r), static_cast<int>(a.cols()));
}

Ar1Fit fitLinearAr1(const Eigen::MatrixXd& x, const Eigen::VectorXd& y, const std::vector<bool>& starts) {
  const Eigen::MatrixXd a = design(x, true);
  const Eigen::Index n = a.rows();
  if (!starts.empty() && static_cast<Eigen::Index>(starts.size()) != n)
    throw InputError("regression: the series starts do not match the rows");
  // Row i continues the series of row i - 1.
  const auto continues = [&](Eigen::Index i) {
    return i > 0 && (starts.empty() || !starts[static_cast<std::size_t>(i)]);
  };
  Ar1Fit out;
  Eigen::VectorXd b = solve(a, y);
  double phi = 0.0;
  // Prais-Winsten transform: a series' first row scaled, the others differenced.
  const auto transform = [&](const Eigen::MatrixXd& m, double f) {
    Eigen::MatrixXd t(m.rows(), m.cols());
    const double first = std::sqrt(1.0 - f * f);
    for (Eigen::Index i = 0; i < m.rows(); ++i)
      t.row(i) = continues(i) ? Eigen::MatrixXd(m.row(i) - f * m.row(i - 1)) : Eigen::MatrixXd(first * m.row(i));
    return t;
  };
  for (out.iterations = 1; out.iterations <= 100; ++out.iterations) {
    const Eigen::VectorXd e = y - a * b;
    double lagged = 0.0, previous = 0.0;
    for (Eigen::Index i = 1; i < n; ++i) {
      if (!continues(i)) continue;
      lagged += e(i) * e(i - 1);
      previous += e(i - 1) * e(i - 1);
    }
    const double next = lagged / previous;
    if (!(std::abs(next) < 1.0)) {
      throw InputError(
          fmt::format("regression: the residuals' AR(1) coefficient reached {:.4f}: not stationary", next));
    }
    const bool converged = std::abs(next - phi) < 1e-10;
    phi = next;
    b = solve(transform(a, phi), transform(y, phi).col(0));
    if (converged) break;
  }
  Eigen::VectorXd e = y - a * b;
  out.phi = phi;
  out.innovations = transform(e, phi).col(0);
  out.fit = statistics(std::move(b), std::move(e), static_cast<int>(a.cols()));
  return out;
}

}  // namespace mtcal::processing
