#pragma once
// B-spline functions of one variable and their weighted least-squares fit: the error
// functions of position of the multi-body model (patent CN104200063 fits the node means of
// the 20 mm x 9-repeat measurements with B-splines). Pure numerics, thread-safe.

#include <Eigen/Dense>
#include <vector>

namespace mtcal::processing {

class BSpline {
 public:
  /// @param degree k >= 0
  /// @param knots non-decreasing, size n + k + 1 for n coefficients
  /// @throws InputError when the sizes or the knot order are wrong
  BSpline(int degree, std::vector<double> knots, Eigen::VectorXd coefficients);

  /// Clamped knot vector on [a, b]: degree + 1 copies of each end and the interior knots.
  /// @throws InputError when an interior knot is not strictly inside (a, b) or not increasing
  static std::vector<double> clampedKnots(double a, double b, int degree, const std::vector<double>& interior);

  /// Interior knots for `spans` spans over sorted, distinct data sites, placed by de Boor's
  /// averaging (A Practical Guide to Splines, ch. XIII: t_{i+k} = mean of k-1 consecutive
  /// sites): with spans = sites - degree (interpolation) exactly his knots, which keep the
  /// Schoenberg-Whitney condition and the system well conditioned; with fewer spans, knots at
  /// even fractions of the site index (even sites give even knots).
  /// @throws InputError when spans is not in [1, sites - degree]
  static std::vector<double> averagedInteriorKnots(const std::vector<double>& sites, int degree, int spans);

  /// Weighted least-squares fit: minimises sum w_i (y_i - S(x_i))^2 over the coefficients.
  /// @throws InputError when the data cannot determine the coefficients (too few points, or
  ///         a knot span without data: Schoenberg-Whitney), naming how many are missing
  static BSpline fit(int degree, std::vector<double> knots, const Eigen::VectorXd& x, const Eigen::VectorXd& y,
                     const Eigen::VectorXd& weights);

  /// Value at x. Defined on [t_k, t_n] (the base interval); outside it the end polynomial
  /// pieces are extended.
  double operator()(double x) const;
  /// Values of the n basis functions at x (the row of the collocation matrix).
  Eigen::VectorXd basis(double x) const;

  int degree() const { return degree_; }
  const std::vector<double>& knots() const { return knots_; }
  const Eigen::VectorXd& coefficients() const { return coefficients_; }
  double lower() const { return knots_[static_cast<std::size_t>(degree_)]; }
  double upper() const { return knots_[knots_.size() - 1 - static_cast<std::size_t>(degree_)]; }

 private:
  /// Index mu with t_mu <= x < t_{mu+1} inside the base interval (the last span closed).
  int span(double x) const;

  int degree_;
  std::vector<double> knots_;
  Eigen::VectorXd coefficients_;
};

}  // namespace mtcal::processing
