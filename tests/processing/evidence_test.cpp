#include "mtcal/processing/evidence.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>

#include "mtcal/error.h"

namespace mtcal::processing {
namespace {

constexpr double kPi = std::numbers::pi;

// Closed forms of Student's t: dof 1 is Cauchy, P(T > t) = 1/2 - atan(t)/pi; dof 2:
// P(T > t) = (1 - t / sqrt(2 + t^2)) / 2; and the table value t_0.975(10) = 2.228 (e.g.
// NIST/SEMATECH e-Handbook, table 1.3.6.7.2).
TEST(Evidence, StudentTMatchesClosedFormsAndTheTable) {
  for (double t : {-3.0, -0.5, 0.0, 0.7, 2.0, 12.0}) {
    EXPECT_NEAR(studentTSurvival(t, 1), 0.5 - std::atan(t) / kPi, 1e-13) << t;
    EXPECT_NEAR(studentTSurvival(t, 2), 0.5 * (1 - t / std::sqrt(2 + t * t)), 1e-13) << t;
  }
  EXPECT_NEAR(studentTSurvival(2.228, 10), 0.025, 1e-4);
  // I_x(a, 1) = x^a and I_x(1, b) = 1 - (1 - x)^b.
  EXPECT_NEAR(regularizedIncompleteBeta(0.3, 2.5, 1.0), std::pow(0.3, 2.5), 1e-14);
  EXPECT_NEAR(regularizedIncompleteBeta(0.8, 1.0, 3.5), 1 - std::pow(0.2, 3.5), 1e-14);
  EXPECT_THROW(regularizedIncompleteBeta(1.5, 1, 1), InputError);
}

// log |Gamma|: Gamma(1/2) = sqrt(pi), Gamma(10) = 9!, Gamma(-1/2) = -2 sqrt(pi) (its magnitude).
TEST(Evidence, LogGammaMatchesClosedForms) {
  EXPECT_NEAR(logGamma(0.5), 0.5 * std::log(kPi), 1e-14);
  EXPECT_NEAR(logGamma(10.0), std::log(362880.0), 1e-13);
  EXPECT_NEAR(logGamma(-0.5), std::log(2.0 * std::sqrt(kPi)), 1e-14);
}

// A noise-free sinusoid on uneven positions explains all the variance at its frequency:
// power exactly 1 and its amplitude; white noise stays below the false-alarm level; a
// sinusoid of a third of the noise's sigma in 300 points is found at its frequency.
TEST(Evidence, LombScargleFindsASinusoidOnUnevenPositions) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> position(0.0, 400.0);
  std::normal_distribution<double> normal;
  const int n = 300;
  Eigen::VectorXd t(n), pure(n), noise(n), weak(n);
  for (int i = 0; i < n; ++i) {
    t(i) = position(rng);
    pure(i) = 3.0 + 1.5 * std::sin(2 * kPi * t(i) / 10.0 + 0.4);
    noise(i) = normal(rng);
    weak(i) = noise(i) + 0.35 * std::cos(2 * kPi * t(i) / 37.0);
  }
  Eigen::VectorXd f(400);
  for (int k = 0; k < 400; ++k) f(k) = (k + 1) / 800.0;  // periods 800 mm .. 2 mm
  const auto p = lombScargle(t, pure, f);
  Eigen::Index best = 0;
  p.power.maxCoeff(&best);
  EXPECT_NEAR(f(best), 0.1, 1e-12);
  EXPECT_NEAR(p.power(best), 1.0, 1e-12);
  EXPECT_NEAR(p.amplitude(best), 1.5, 1e-12);
  const int independent = 400;
  const auto q = lombScargle(t, noise, f);
  EXPECT_GT(lombScargleFalseAlarm(q.power.maxCoeff(), n, independent), 0.01);
  const auto w = lombScargle(t, weak, f);
  w.power.maxCoeff(&best);
  EXPECT_NEAR(1.0 / f(best), 37.0, 1.0);
  EXPECT_LT(lombScargleFalseAlarm(w.power(best), n, independent), 1e-3);
  EXPECT_THROW(lombScargle(t.head(3), pure.head(3), f), InputError);
}

// A residual with nothing in it shows nothing (seeded white noise: every p above 1 %); each
// effect hidden in it alone is found with its size: a trend of 0.01 per unit, a step of 0.5
// between directions, a period of 7 with amplitude 0.4 on uneven positions.
TEST(Evidence, ResidualEvidenceFindsATrendAStepAndAPeriod) {
  std::mt19937_64 rng(8);
  std::normal_distribution<double> normal;
  std::uniform_real_distribution<double> position(0.0, 200.0);
  const int n = 200;
  Eigen::VectorXd x(n), noise(n);
  Eigen::VectorXi direction(n);
  for (int i = 0; i < n; ++i) {
    x(i) = position(rng);
    noise(i) = 0.3 * normal(rng);
    direction(i) = i % 2;
  }
  const auto none = residualEvidence(noise, x, direction, 2.0, 100.0, 400);
  EXPECT_GT(none.trend_p, 0.01);
  EXPECT_GT(none.step_p, 0.01);
  EXPECT_GT(none.period_false_alarm, 0.01);
  EXPECT_GT(none.ljung_box_p, 0.01);

  const auto trend = residualEvidence(noise.array() + 0.01 * x.array(), x, direction, 2.0, 100.0, 400);
  EXPECT_LT(trend.trend_p, 1e-10);
  EXPECT_NEAR(trend.slope, 0.01, 0.002);  // se of the slope: 0.3 / sqrt(n var x) ~ 0.0004
  EXPECT_LT(trend.ljung_box_p, 1e-6);     // sorted by position the trend is correlated

  Eigen::VectorXd stepped = noise;
  for (int i = 0; i < n; ++i) stepped(i) += direction(i) ? 0.25 : -0.25;
  const auto step = residualEvidence(stepped, x, direction, 2.0, 100.0, 400);
  EXPECT_LT(step.step_p, 1e-10);
  EXPECT_NEAR(step.step, 0.5, 0.1);  // se of the step: 0.3 sqrt(2 / 100) = 0.042
  EXPECT_GT(step.trend_p, 0.01);

  Eigen::VectorXd cyclic = noise;
  for (int i = 0; i < n; ++i) cyclic(i) += 0.4 * std::sin(2 * kPi * x(i) / 7.0);
  const auto period = residualEvidence(cyclic, x, Eigen::VectorXi(), 2.0, 100.0, 400);
  EXPECT_NEAR(period.period, 7.0, 0.1);
  EXPECT_NEAR(period.period_amplitude, 0.4, 0.08);
  EXPECT_LT(period.period_false_alarm, 1e-6);
  EXPECT_TRUE(std::isnan(period.step_p));  // no groups: no step test
  EXPECT_THROW(residualEvidence(noise.head(5), x.head(5), Eigen::VectorXi(), 2.0, 100.0, 10), InputError);
}

// The correlation along a variable is taken between its values: a residual whose repeats at each
// of 21 positions sum to zero (a baseline through every position's mean) has nothing between
// the positions and is not tested (it read as a correlation between neighbours, Ljung-Box p
// 0.0019, on effect-free data); white repeats are not correlated; a smooth curve between the
// positions is.
TEST(Evidence, CorrelationAlongAVariableIsBetweenItsValues) {
  std::mt19937_64 rng(9);
  std::normal_distribution<double> normal;
  const int positions = 21, repeats = 10, n = positions * repeats;
  Eigen::VectorXd x(n), noise(n), centred(n);
  for (int i = 0; i < n; ++i) {
    x(i) = 20.0 * (i % positions);
    noise(i) = 0.5 * normal(rng);
  }
  for (int p = 0; p < positions; ++p) {
    double mean = 0.0;
    for (int r = 0; r < repeats; ++r) mean += noise(r * positions + p) / repeats;
    for (int r = 0; r < repeats; ++r) centred(r * positions + p) = noise(r * positions + p) - mean;
  }
  const auto through_means = residualEvidence(centred, x, Eigen::VectorXi(), 0.0, 0.0, 0);
  EXPECT_TRUE(std::isnan(through_means.ljung_box_p));
  EXPECT_TRUE(std::isnan(through_means.durbin_watson));
  const auto white = residualEvidence(noise, x, Eigen::VectorXi(), 0.0, 0.0, 0);
  EXPECT_GT(white.ljung_box_p, 0.01);
  EXPECT_NEAR(white.durbin_watson, 2.0, 0.9);  // 21 means: sd of DW about 2 / sqrt(21) = 0.44
  // A bow of 1.5 um between the positions (0.16 um of noise on a position's mean).
  const Eigen::VectorXd bow = noise.array() + 1.5 * (kPi * x.array() / 400.0).sin();
  const auto curved = residualEvidence(bow, x, Eigen::VectorXi(), 0.0, 0.0, 0);
  EXPECT_LT(curved.ljung_box_p, 0.01);  // 0.0022: 21 values, 5 lags
  EXPECT_LT(curved.durbin_watson, 1.0);
  // Fewer than 6 values (a run's 5 cycles): not tested.
  const Eigen::VectorXd cycle = (Eigen::VectorXd::LinSpaced(n, 0, n - 1).array() / 42.0).floor();
  EXPECT_TRUE(std::isnan(residualEvidence(noise, cycle, Eigen::VectorXi(), 0.0, 0.0, 0).ljung_box_p));
}

}  // namespace
}  // namespace mtcal::processing
