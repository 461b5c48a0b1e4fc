#include "mtcal/processing/evidence.h"

#include <fmt/format.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <numeric>
#include <vector>

#include "mtcal/error.h"
#include "mtcal/processing/regression.h"

namespace mtcal::processing {
namespace {

/// The continued fraction of I_x(a, b) (modified Lentz), valid for x < (a + 1) / (a + b + 2).
double betaFraction(double x, double a, double b) {
  constexpr double kTiny = 1e-300;
  double c = 1.0, d = 1.0 - (a + b) * x / (a + 1.0);
  if (std::abs(d) < kTiny) d = kTiny;
  d = 1.0 / d;
  double h = d;
  for (int m = 1; m < 1000; ++m) {
    const double m2 = 2.0 * m;
    double an = m * (b - m) * x / ((a + m2 - 1.0) * (a + m2));
    d = 1.0 + an * d;
    if (std::abs(d) < kTiny) d = kTiny;
    c = 1.0 + an / c;
    if (std::abs(c) < kTiny) c = kTiny;
    d = 1.0 / d;
    h *= d * c;
    an = -(a + m) * (a + b + m) * x / ((a + m2) * (a + m2 + 1.0));
    d = 1.0 + an * d;
    if (std::abs(d) < kTiny) d = kTiny;
    c = 1.0 + an / c;
    if (std::abs(c) < kTiny) c = kTiny;
    d = 1.0 / d;
    const double delta = d * c;
    h *= delta;
    if (std::abs(delta - 1.0) < 1e-16) break;
  }
  return h;
}

}  // namespace

double logGamma(double x) {
  int sign = 0;
  return lgamma_r(x, &sign);  // the reentrant form of glibc and the BSDs: the sign in a local
}

double regularizedIncompleteBeta(double x, double a, double b) {
  if (!(a > 0.0 && b > 0.0) || x < 0.0 || x > 1.0)
    throw InputError(fmt::format("incomplete beta: x {} a {} b {}", x, a, b));
  if (x == 0.0 || x == 1.0) return x;
  const double front = std::exp(logGamma(a + b) - logGamma(a) - logGamma(b) + a * std::log(x) + b * std::log1p(-x));
  if (x < (a + 1.0) / (a + b + 2.0)) return front * betaFraction(x, a, b) / a;
  return 1.0 - front * betaFraction(1.0 - x, b, a) / b;  // the symmetry I_x(a, b) = 1 - I_{1-x}(b, a)
}

double studentTSurvival(double t, double dof) {
  if (!(dof > 0.0)) throw InputError(fmt::format("Student's t: {} degrees of freedom", dof));
  const double tail = 0.5 * regularizedIncompleteBeta(dof / (dof + t * t), dof / 2.0, 0.5);
  return t >= 0.0 ? tail : 1.0 - tail;
}

double fisherFSurvival(double f, double d1, double d2) {
  if (!(d1 > 0.0 && d2 > 0.0)) throw InputError(fmt::format("F distribution: degrees of freedom {} and {}", d1, d2));
  if (!(f > 0.0)) return 1.0;
  return regularizedIncompleteBeta(d2 / (d2 + d1 * f), d2 / 2.0, d1 / 2.0);
}

Periodogram lombScargle(const Eigen::VectorXd& t, const Eigen::VectorXd& y, const Eigen::VectorXd& frequencies) {
  const Eigen::Index n = t.size();
  if (y.size() != n || n < 4)
    throw InputError(fmt::format("Lomb-Scargle: {} positions and {} values (need 4 or more)", n, y.size()));
  const double chi2_0 = (y.array() - y.mean()).matrix().squaredNorm();
  if (!(chi2_0 > 0.0)) throw InputError("Lomb-Scargle: the values are constant");
  Periodogram p;
  p.frequency = frequencies;
  p.power.resize(frequencies.size());
  p.amplitude.resize(frequencies.size());
  // Per frequency, the least squares of y on (cos, sin, 1) from their sums (Zechmeister &
  // Kuerster 2009, the generalised periodogram): one pass over the readings per frequency. On
  // an even grid of frequencies each reading's cos and sin step from one frequency to the next
  // by a rotation (its angle 2 pi df t), recomputed exactly every 64 steps so that rounding
  // does not accumulate.
  const bool even = frequencies.size() > 2 &&
                    ((frequencies.tail(frequencies.size() - 1) - frequencies.head(frequencies.size() - 1)).array() -
                     (frequencies(1) - frequencies(0)))
                            .abs()
                            .maxCoeff() <= 1e-12 * frequencies.cwiseAbs().maxCoeff();
  const Eigen::ArrayXd step_phase = 2.0 * std::numbers::pi * (even ? frequencies(1) - frequencies(0) : 0.0) * t.array();
  const Eigen::ArrayXd step_cos = step_phase.cos(), step_sin = step_phase.sin();
  Eigen::ArrayXd c(n), s(n);
  const Eigen::ArrayXd ya = y.array();
  const double sum_y = ya.sum(), sum_yy = ya.square().sum();
  for (Eigen::Index k = 0; k < frequencies.size(); ++k) {
    if (!even || k % 64 == 0) {
      const Eigen::ArrayXd phase = 2.0 * std::numbers::pi * frequencies(k) * t.array();
      c = phase.cos();
      s = phase.sin();
    } else {
      const Eigen::ArrayXd c_next = c * step_cos - s * step_sin;
      s = s * step_cos + c * step_sin;
      c = c_next;
    }
    Eigen::Matrix3d g;
    g(0, 0) = c.square().sum();
    g(1, 1) = s.square().sum();
    g(0, 1) = g(1, 0) = (c * s).sum();
    g(0, 2) = g(2, 0) = c.sum();
    g(1, 2) = g(2, 1) = s.sum();
    g(2, 2) = static_cast<double>(n);
    const Eigen::Vector3d b((c * ya).sum(), (s * ya).sum(), sum_y);
    const Eigen::Vector3d coef = g.completeOrthogonalDecomposition().solve(b);
    // The residual's sum of squares from the sums: y'y - coef' b at the solution.
    const double chi2 = std::max(0.0, sum_yy - coef.dot(b));
    p.power(k) = std::max(0.0, 1.0 - chi2 / chi2_0);
    p.amplitude(k) = std::hypot(coef(0), coef(1));
  }
  return p;
}

double lombScargleFalseAlarm(double power, int n, int independent_frequencies) {
  if (n < 4 || independent_frequencies < 1)
    throw InputError("Lomb-Scargle false alarm: n >= 4 and at least one frequency");
  return anyOfIndependentTests(std::pow(std::max(0.0, 1.0 - power), (n - 3) / 2.0), independent_frequencies);
}

double anyOfIndependentTests(double p, double tests) {
  return -std::expm1(tests * std::log1p(-std::min(p, 1.0 - 1e-16)));
}

ResidualEvidence residualEvidence(const Eigen::VectorXd& residual, const Eigen::VectorXd& variable,
                                  const Eigen::VectorXi& group, double min_period, double max_period, int periods) {
  const Eigen::Index n = residual.size();
  if (variable.size() != n || (group.size() != 0 && group.size() != n) || n < 6) {
    throw InputError(
        fmt::format("residual evidence: {} residuals, {} variable values, {} groups (need 6 or more, equal)", n,
                    variable.size(), group.size()));
  }
  ResidualEvidence e;
  // Trend: the slope of the residual on the variable and its t statistic.
  const double mx = variable.mean(), my = residual.mean();
  const Eigen::VectorXd dx = variable.array() - mx, dy = residual.array() - my;
  const double sxx = dx.squaredNorm();
  if (sxx > 0.0) {
    e.slope = dx.dot(dy) / sxx;
    const double rss = (dy - e.slope * dx).squaredNorm();
    const double se = std::sqrt(rss / static_cast<double>(n - 2) / sxx);
    e.trend_p = se > 0.0 ? 2.0 * studentTSurvival(std::abs(e.slope / se), static_cast<double>(n - 2)) : 0.0;
  }
  // Step between the groups: Welch's t with the Welch-Satterthwaite degrees of freedom.
  if (group.size() == n) {
    std::vector<double> a, b;
    for (Eigen::Index i = 0; i < n; ++i) (group(i) ? b : a).push_back(residual(i));
    if (a.size() >= 2 && b.size() >= 2) {
      auto moments = [](const std::vector<double>& v) {
        const double m = std::accumulate(v.begin(), v.end(), 0.0) / static_cast<double>(v.size());
        double ss = 0.0;
        for (double x : v) ss += (x - m) * (x - m);
        return std::pair(
            m, ss / static_cast<double>(v.size() - 1) / static_cast<double>(v.size()));  // mean, variance of the mean
      };
      const auto [ma, va] = moments(a);
      const auto [mb, vb] = moments(b);
      e.step = mb - ma;
      const double se2 = va + vb;
      if (se2 > 0.0) {
        const double dof =
            se2 * se2 / (va * va / static_cast<double>(a.size() - 1) + vb * vb / static_cast<double>(b.size() - 1));
        e.step_p = 2.0 * studentTSurvival(std::abs(e.step) / std::sqrt(se2), dof);
      }
    }
  }
  // Periodicity: the generalised Lomb-Scargle periodogram, evenly in frequency.
  if (periods > 1 && min_period > 0.0 && max_period > min_period && (dy.array() != 0.0).any()) {
    Eigen::VectorXd f(periods);
    for (int k = 0; k < periods; ++k)
      f(k) = 1.0 / max_period + (1.0 / min_period - 1.0 / max_period) * k / (periods - 1);
    const auto p = lombScargle(variable, residual, f);
    Eigen::Index best = 0;
    p.power.maxCoeff(&best);
    e.period = 1.0 / f(best);
    e.period_amplitude = p.amplitude(best);
    // Independent frequencies: the span times the frequency range, at most the frequencies searched.
    const double span = variable.maxCoeff() - variable.minCoeff();
    const int independent =
        std::clamp(static_cast<int>(std::ceil(span * (1.0 / min_period - 1.0 / max_period))), 1, periods);
    e.period_false_alarm = lombScargleFalseAlarm(p.power(best), static_cast<int>(n), independent);
  }
  // Autocorrelation along the variable: between its values, so of the residual's mean at each
  // value where it repeats (the order of a value's repeats is not along it, and a baseline
  // through every position's mean makes its repeats' residuals sum to zero, which read as a
  // correlation between neighbours that the data do not have). Not made on fewer than
  // kFewestValues values, nor where the means are all zero (nothing between the values is left).
  std::vector<Eigen::Index> order(static_cast<std::size_t>(n));
  std::iota(order.begin(), order.end(), Eigen::Index{0});
  std::stable_sort(order.begin(), order.end(),
                   [&](Eigen::Index i, Eigen::Index j) { return variable(i) < variable(j); });
  std::vector<double> means;
  for (std::size_t k = 0; k < order.size();) {
    std::size_t end = k;
    double sum = 0.0;
    for (; end < order.size() && variable(order[end]) == variable(order[k]); ++end) sum += residual(order[end]);
    means.push_back(sum / static_cast<double>(end - k));
    k = end;
  }
  constexpr std::size_t kFewestValues = 6;
  const Eigen::Map<const Eigen::VectorXd> along(means.data(), static_cast<Eigen::Index>(means.size()));
  const double scale = residual.cwiseAbs().maxCoeff();
  e.durbin_watson = e.ljung_box_p = std::numeric_limits<double>::quiet_NaN();
  if (means.size() >= kFewestValues && (along.array() - along.mean()).abs().maxCoeff() > 1e-12 * scale) {
    e.durbin_watson = durbinWatson(along.array() - along.mean());
    const int lags = std::max(1, std::min(10, static_cast<int>(means.size()) / 4));
    e.ljung_box_p = chiSquareSurvival(ljungBox(along, lags), lags);
  }
  return e;
}

}  // namespace mtcal::processing
