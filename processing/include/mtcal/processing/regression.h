#pragma once
// Linear regression for thermal error models (seed 002): ordinary least squares
// with the statistics a model choice needs (residual sum of squares, Gaussian
// log-likelihood, AIC, BIC, Durbin-Watson), and the same regression with AR(1) residuals
// (eps_i = phi eps_{i-1} + a_i) estimated by Prais-Winsten iterations.
//
// Conventions as statsmodels' OLS: k counts the coefficients (intercept included), not the
// variance; log L = -n/2 (ln 2 pi + ln(RSS/n) + 1); AIC = -2 log L + 2k; BIC = -2 log L + k ln n.

#include <Eigen/Core>
#include <vector>

namespace mtcal::processing {

struct LinearFit {
  Eigen::VectorXd coefficients;  ///< intercept first (when fitted), then one per column of x
  Eigen::VectorXd residuals;     ///< y - fitted
  int n = 0, k = 0;              ///< observations, coefficients
  double rss = 0.0;              ///< residual sum of squares
  double log_likelihood = 0.0, aic = 0.0, bic = 0.0;
  double durbin_watson = 0.0;  ///< sum (e_i - e_{i-1})^2 / RSS: 2 for independent residuals
};

/// Gaussian log-likelihood of n residuals with this RSS, and AIC and BIC for k parameters
/// (the conventions above).
struct InformationCriteria {
  double log_likelihood = 0.0, aic = 0.0, bic = 0.0;
};
InformationCriteria informationCriteria(double rss, int n, int k);

/// Least squares of y on the columns of x (n x p) and an intercept, by column-pivoting
/// Householder QR on columns scaled to unit norm (Longley's data stay exact to ~1e-9).
/// @throws InputError when n <= k or the columns are linearly dependent.
LinearFit fitLinear(const Eigen::MatrixXd& x, const Eigen::VectorXd& y, bool intercept = true);

/// The residual sum of squares `rss` of a least-squares fit less what columns F added to its
/// model take of it, from their Gram matrix beside the model, G = F'F - (Q'F)'(Q'F) (Q: an
/// orthonormal basis of the model's columns), and their products with its residual, b = F'r
/// (r orthogonal to Q): rss - b'G^-1 b, without a fit of every reading (a search's trials).
/// Columns scaled to a unit diagonal; a column the model already has (a diagonal of G below
/// 1e-10 of its largest) is left out, and dependent ones count once.
double rssWithAddedColumns(double rss, Eigen::MatrixXd gram, const Eigen::VectorXd& cross);

/// Durbin-Watson statistic of residuals in time order.
double durbinWatson(const Eigen::VectorXd& residuals);

/// Ljung-Box portmanteau statistic Q = n (n + 2) sum_{k=1..lags} r_k^2 / (n - k) of residuals
/// in time order (r_k the lag-k autocorrelation of the de-meaned series). Under independence
/// Q ~ chi^2(lags - fitted ARMA parameters). @throws InputError when lags < 1 or lags >= n
double ljungBox(const Eigen::VectorXd& residuals, int lags);

/// P(X > x) for X ~ chi^2 with `dof` degrees of freedom: the regularised upper incomplete
/// gamma function Q(dof/2, x/2) (series below a + 1, Lentz's continued fraction above).
double chiSquareSurvival(double x, double dof);

struct Ar1Fit {
  LinearFit fit;                ///< coefficients of the original model; residuals eps = y - x b (not whitened)
  double phi = 0.0;             ///< AR(1) coefficient of eps
  Eigen::VectorXd innovations;  ///< a_i = eps_i - phi eps_{i-1} (i >= 1; a_0 = eps_0 sqrt(1 - phi^2))
  int iterations = 0;
};

/// Regression with AR(1) residuals by Prais-Winsten (the first observation kept, scaled by
/// sqrt(1 - phi^2)), iterated until phi changes by less than 1e-10 (at most 100 times).
/// `starts` (empty: one series) marks the rows that begin a series of their own (after a
/// gap in the data): treated like the first observation, never differenced with the row
/// before them.
/// @throws InputError as fitLinear, or when |phi| reaches 1 (a non-stationary residual).
Ar1Fit fitLinearAr1(const Eigen::MatrixXd& x, const Eigen::VectorXd& y, const std::vector<bool>& starts = {});

}  // namespace mtcal::processing
