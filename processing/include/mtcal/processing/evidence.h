#pragma once
// Statistics that decide whether a residual has structure (groundwork of the diagnosis): the
// generalised Lomb-Scargle periodogram for unevenly spaced positions or times, its false-alarm
// probability, and Student's t distribution for trend and step tests.
//
// Generalised Lomb-Scargle (Zechmeister & Kürster 2009, A&A 496, 577): at each frequency f the
// least-squares fit y ~ a cos(2 pi f t) + b sin(2 pi f t) + c with a floating mean; the power
// p(f) = 1 - chi2(f) / chi2_0 (chi2_0 about the mean) is the fraction of the variance the
// sinusoid explains, 0..1; a noise-free sinusoid gives exactly 1 at its frequency.

#include <Eigen/Core>
#include <limits>

namespace mtcal::processing {

struct Periodogram {
  Eigen::VectorXd frequency;  ///< cycles per unit of t (1/mm for positions)
  Eigen::VectorXd power;      ///< 0..1
  Eigen::VectorXd amplitude;  ///< of the fitted sinusoid, sqrt(a^2 + b^2), units of y
};

/// @throws InputError when t and y differ in size, fewer than 4 points, or y is constant
Periodogram lombScargle(const Eigen::VectorXd& t, const Eigen::VectorXd& y, const Eigen::VectorXd& frequencies);

/// The chance that noise alone reaches `power` at one frequency ((1 - p)^((n - 3) / 2), Zechmeister &
/// Kürster eq. 24) and anywhere among `independent_frequencies` (1 - (1 - prob)^M).
double lombScargleFalseAlarm(double power, int n, int independent_frequencies);

/// P(T > t) for Student's t with `dof` degrees of freedom, by the regularised incomplete beta
/// function: 0.5 I_{dof / (dof + t^2)}(dof / 2, 1 / 2) for t >= 0.
double studentTSurvival(double t, double dof);

/// P(F > f) for Fisher's F with (d1, d2) degrees of freedom: I_{d2 / (d2 + d1 f)}(d2 / 2, d1 / 2);
/// 1 for f <= 0. The test of nested least-squares models: F = (delta RSS / d1) / (RSS / d2).
double fisherFSurvival(double f, double d1, double d2);

/// The chance that any of `tests` independent tests reaches what one reaches with chance `p`:
/// 1 - (1 - p)^tests (Sidak), computed without losing a small p.
double anyOfIndependentTests(double p, double tests);

/// The regularised incomplete beta function I_x(a, b) (Lentz's continued fraction).
double regularizedIncompleteBeta(double x, double a, double b);

/// log |Gamma(x)|, as std::lgamma, safe on several threads at once (std::lgamma also writes the
/// sign to the global `signgam`).
double logGamma(double x);

/// What a residual shows against one explaining variable (a position, a time, a temperature):
/// each a statistic and the probability that noise alone shows that much.
struct ResidualEvidence {
  double slope = 0.0, trend_p = 1.0;  ///< least-squares slope (residual units per variable unit), two-sided t test
  /// mean(group 1) - mean(group 0), Welch's two-sided t test (NaN: no groups given, not tested)
  double step = 0.0, step_p = std::numeric_limits<double>::quiet_NaN();
  double period = 0.0, period_amplitude = 0.0;  ///< the periodogram's strongest period (variable units) and amplitude
  double period_false_alarm = 1.0;
  /// Along the variable, of the residual's mean at each of its values (NaN: fewer than 6
  /// values, or nothing left between them)
  double durbin_watson = 2.0, ljung_box_p = 1.0;
};

/// Evidence in `residual` against `variable`; `group` (0/1 per point, e.g. the approach
/// direction; empty: no step test) and the periods searched (`min_period`..`max_period`,
/// `periods` of them, evenly in frequency; 0: no periodogram). Autocorrelation is taken between
/// the variable's values, of the residual's mean at each. @throws InputError for mismatched sizes or fewer than 6
/// points
ResidualEvidence residualEvidence(const Eigen::VectorXd& residual, const Eigen::VectorXd& variable,
                                  const Eigen::VectorXi& group, double min_period, double max_period, int periods);

}  // namespace mtcal::processing
