#include "mtcal/processing/evidence.h"

#include <cmath>
#include <numbers>

#include <Eigen/Dense>
#include <fmt/format.h>

#include "mtcal/error.h"

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

double regularizedIncompleteBeta(double x, double a, double b) {
  if (!(a > 0.0 && b > 0.0) || x < 0.0 || x > 1.0) throw InputError(fmt::format("incomplete beta: x {} a {} b {}", x, a, b));
  if (x == 0.0 || x == 1.0) return x;
  const double front = std::exp(std::lgamma(a + b) - std::lgamma(a) - std::lgamma(b) + a * std::log(x) + b * std::log1p(-x));
  if (x < (a + 1.0) / (a + b + 2.0)) return front * betaFraction(x, a, b) / a;
  return 1.0 - front * betaFraction(1.0 - x, b, a) / b;  // the symmetry I_x(a, b) = 1 - I_{1-x}(b, a)
}

double studentTSurvival(double t, double dof) {
  if (!(dof > 0.0)) throw InputError(fmt::format("Student's t: {} degrees of freedom", dof));
  const double tail = 0.5 * regularizedIncompleteBeta(dof / (dof + t * t), dof / 2.0, 0.5);
  return t >= 0.0 ? tail : 1.0 - tail;
}

Periodogram lombScargle(const Eigen::VectorXd& t, const Eigen::VectorXd& y, const Eigen::VectorXd& frequencies) {
  const Eigen::Index n = t.size();
  if (y.size() != n || n < 4) throw InputError(fmt::format("Lomb-Scargle: {} positions and {} values (need 4 or more)", n, y.size()));
  const double chi2_0 = (y.array() - y.mean()).matrix().squaredNorm();
  if (!(chi2_0 > 0.0)) throw InputError("Lomb-Scargle: the values are constant");
  Periodogram p;
  p.frequency = frequencies;
  p.power.resize(frequencies.size());
  p.amplitude.resize(frequencies.size());
  Eigen::MatrixXd a(n, 3);
  a.col(2).setOnes();
  for (Eigen::Index k = 0; k < frequencies.size(); ++k) {
    const Eigen::ArrayXd phase = 2.0 * std::numbers::pi * frequencies(k) * t.array();
    a.col(0) = phase.cos().matrix();
    a.col(1) = phase.sin().matrix();
    const Eigen::Vector3d coef = a.colPivHouseholderQr().solve(y);
    const double chi2 = (y - a * coef).squaredNorm();
    p.power(k) = std::max(0.0, 1.0 - chi2 / chi2_0);
    p.amplitude(k) = std::hypot(coef(0), coef(1));
  }
  return p;
}

double lombScargleFalseAlarm(double power, int n, int independent_frequencies) {
  if (n < 4 || independent_frequencies < 1) throw InputError("Lomb-Scargle false alarm: n >= 4 and at least one frequency");
  const double single = std::pow(std::max(0.0, 1.0 - power), (n - 3) / 2.0);
  return -std::expm1(independent_frequencies * std::log1p(-std::min(single, 1.0 - 1e-16)));
}

}  // namespace mtcal::processing
