#include "mtcal/processing/bspline.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "mtcal/error.h"

namespace mtcal::processing {

BSpline::BSpline(int degree, std::vector<double> knots, Eigen::VectorXd coefficients)
    : degree_(degree), knots_(std::move(knots)), coefficients_(std::move(coefficients)) {
  if (degree_ < 0) throw InputError("B-spline: degree must be >= 0");
  const auto n = static_cast<std::size_t>(coefficients_.size());
  if (n < static_cast<std::size_t>(degree_) + 1 || knots_.size() != n + static_cast<std::size_t>(degree_) + 1) {
    throw InputError("B-spline: " + std::to_string(n) + " coefficients of degree " + std::to_string(degree_) +
                     " need " + std::to_string(n + static_cast<std::size_t>(degree_) + 1) + " knots, got " +
                     std::to_string(knots_.size()));
  }
  if (!std::is_sorted(knots_.begin(), knots_.end())) throw InputError("B-spline: knots must not decrease");
  if (!(upper() > lower())) throw InputError("B-spline: the base interval is empty");
}

std::vector<double> BSpline::clampedKnots(double a, double b, int degree, const std::vector<double>& interior) {
  if (!(b > a)) throw InputError("B-spline knots: the interval must not be empty");
  std::vector<double> t(static_cast<std::size_t>(degree) + 1, a);
  double previous = a;
  for (double k : interior) {
    if (!(k > previous && k < b))
      throw InputError("B-spline knots: interior knots must increase strictly inside (a, b)");
    t.push_back(k);
    previous = k;
  }
  t.insert(t.end(), static_cast<std::size_t>(degree) + 1, b);
  return t;
}

std::vector<double> BSpline::averagedInteriorKnots(const std::vector<double>& sites, int degree, int spans) {
  const int n = static_cast<int>(sites.size());
  if (degree < 0 || spans < 1 || spans > n - degree) {
    throw InputError("B-spline knots: " + std::to_string(spans) + " spans of degree " + std::to_string(degree) +
                     " need at least " + std::to_string(spans + degree) + " data sites, have " + std::to_string(n));
  }
  std::vector<double> interior;
  if (spans == n - degree) {
    // Interpolation: de Boor's averages of `degree` consecutive sites from the second.
    const int width = std::max(degree, 1);
    for (int i = 1; i < spans; ++i) {
      double sum = 0.0;
      for (int j = i; j < i + width; ++j) sum += sites[static_cast<std::size_t>(std::min(j, n - 1))];
      interior.push_back(sum / width);
    }
    return interior;
  }
  // Fewer spans: knots at even fractions of the site index (even sites give even knots).
  for (int i = 1; i < spans; ++i) {
    const double u = static_cast<double>(n - 1) * i / spans;
    const auto k = static_cast<std::size_t>(std::floor(u));
    const double f = u - static_cast<double>(k);
    interior.push_back(sites[k] + f * (sites[std::min<std::size_t>(k + 1, sites.size() - 1)] - sites[k]));
  }
  return interior;
}

int BSpline::span(double x) const {
  const int n = static_cast<int>(coefficients_.size());
  if (x >= upper()) return n - 1;
  if (x <= lower()) return degree_;
  // Largest mu in [k, n-1] with t_mu <= x.
  const auto it = std::upper_bound(knots_.begin() + degree_, knots_.begin() + n, x);
  return static_cast<int>(it - knots_.begin()) - 1;
}

Eigen::VectorXd BSpline::basis(double x) const {
  // Cox-de Boor recursion on the k + 1 functions that are non-zero on the span.
  const int k = degree_;
  const int mu = span(x);
  const auto& t = knots_;
  Eigen::VectorXd local = Eigen::VectorXd::Zero(k + 1);
  local(0) = 1.0;
  for (int d = 1; d <= k; ++d) {
    // local(j) holds N_{mu-d+1+j, d-1}; raise to degree d in place, right to left.
    double saved = 0.0;
    for (int j = 0; j < d; ++j) {
      const int i = mu - d + 1 + j;  // index of N_{i,d-1}
      const double left = t[static_cast<std::size_t>(i + d)] - t[static_cast<std::size_t>(i)];
      const double term = left > 0.0 ? local(j) / left : 0.0;
      local(j) = saved + (t[static_cast<std::size_t>(i + d)] - x) * term;
      saved = (x - t[static_cast<std::size_t>(i)]) * term;
    }
    local(d) = saved;
  }
  Eigen::VectorXd full = Eigen::VectorXd::Zero(coefficients_.size());
  full.segment(mu - k, k + 1) = local;
  return full;
}

double BSpline::operator()(double x) const { return basis(x).dot(coefficients_); }

BSpline BSpline::fit(int degree, std::vector<double> knots, const Eigen::VectorXd& x, const Eigen::VectorXd& y,
                     const Eigen::VectorXd& weights) {
  if (x.size() != y.size() || x.size() != weights.size())
    throw InputError("B-spline fit: x, y and weights differ in size");
  const auto n = static_cast<Eigen::Index>(knots.size()) - degree - 1;
  if (n < 1) throw InputError("B-spline fit: too few knots for the degree");
  if (x.size() < n) {
    throw InputError("B-spline fit: " + std::to_string(x.size()) + " points cannot determine " + std::to_string(n) +
                     " coefficients");
  }
  for (Eigen::Index i = 0; i < weights.size(); ++i) {
    if (!(weights(i) > 0.0) || !std::isfinite(weights(i))) throw InputError("B-spline fit: weights must be positive");
  }
  BSpline shape(degree, std::move(knots), Eigen::VectorXd::Zero(n));
  Eigen::MatrixXd a(x.size(), n);
  Eigen::VectorXd b(x.size());
  for (Eigen::Index i = 0; i < x.size(); ++i) {
    const double sw = std::sqrt(weights(i));
    a.row(i) = sw * shape.basis(x(i)).transpose();
    b(i) = sw * y(i);
  }
  const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(a);
  if (qr.rank() < n) {
    throw InputError("B-spline fit: the data leave " + std::to_string(n - qr.rank()) +
                     " coefficient(s) undetermined (a knot span without enough points)");
  }
  shape.coefficients_ = qr.solve(b);
  return shape;
}

}  // namespace mtcal::processing
