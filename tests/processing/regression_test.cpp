#include "mtcal/processing/regression.h"

#include <gtest/gtest.h>

#include <Eigen/QR>
#include <cmath>
#include <numbers>
#include <random>

#include "mtcal/error.h"
#include "mtcal/processing/minimum.h"

namespace mtcal::processing {
namespace {

// NIST Statistical Reference Datasets, Longley (1967), "higher difficulty": the certified
// coefficients and residual sum of squares (https://www.itl.nist.gov/div898/strd/lls/data/Longley.shtml);
// from the certified RSS, the Gaussian log-likelihood -n/2 (1 + ln(2 pi RSS / n)) = -109.6174
// (n = 16), AIC = -2 llf + 2 k = 233.2349 and BIC = -2 llf + k ln n = 238.643 with k = 7
// (statsmodels' convention: sigma not counted), and the Durbin-Watson statistic 2.559 as
// statsmodels' OLS summary of these data prints it (statsmodels documentation, "Model
// Comparison" example on sm.datasets.longley).
TEST(Regression, LongleyMatchesTheCertifiedValues) {
  const double y[] = {60323, 61122, 60171, 61187, 63221, 63639, 64989, 63761,
                      66019, 67857, 68169, 66513, 68655, 69564, 69331, 70551};
  const double x[6][16] = {
      {83, 88.5, 88.2, 89.5, 96.2, 98.1, 99, 100, 101.2, 104.6, 108.4, 110.8, 112.6, 114.2, 115.7, 116.9},
      {234289, 259426, 258054, 284599, 328975, 346999, 365385, 363112, 397469, 419180, 442769, 444546, 482704, 502601,
       518173, 554894},
      {2356, 2325, 3682, 3351, 2099, 1932, 1870, 3578, 2904, 2822, 2936, 4681, 3813, 3931, 4806, 4007},
      {1590, 1456, 1616, 1650, 3099, 3594, 3547, 3350, 3048, 2857, 2798, 2637, 2552, 2514, 2572, 2827},
      {107608, 108632, 109773, 110929, 112075, 113270, 115094, 116219, 117388, 118734, 120445, 121950, 123366, 125368,
       127852, 130081},
      {1947, 1948, 1949, 1950, 1951, 1952, 1953, 1954, 1955, 1956, 1957, 1958, 1959, 1960, 1961, 1962}};
  Eigen::MatrixXd xm(16, 6);
  Eigen::VectorXd ym(16);
  for (int i = 0; i < 16; ++i) {
    ym(i) = y[i];
    for (int j = 0; j < 6; ++j) xm(i, j) = x[j][i];
  }
  const LinearFit f = fitLinear(xm, ym);
  const double certified[] = {-3482258.63459582, 15.0618722713733,       -0.358191792925910e-01, -2.02022980381683,
                              -1.03322686717359, -0.511041056535807e-01, 1829.15146461355};
  for (int j = 0; j < 7; ++j) EXPECT_NEAR(f.coefficients(j) / certified[j], 1.0, 1e-8) << j;
  EXPECT_NEAR(f.rss, 836424.055505915, 1e-4);
  EXPECT_EQ(f.k, 7);
  EXPECT_NEAR(f.log_likelihood, -109.6174, 5e-5);
  EXPECT_NEAR(f.aic, 233.2349, 5e-5);
  EXPECT_NEAR(f.bic, 238.643, 5e-4);
  EXPECT_NEAR(f.durbin_watson, 2.559, 5e-4);
}

TEST(Regression, RefusesTooFewObservationsAndDependentColumns) {
  Eigen::MatrixXd x(3, 2);
  x << 1, 2, 2, 4, 3, 6;  // the second column twice the first
  EXPECT_THROW(fitLinear(x, Eigen::Vector3d(1, 2, 3)), InputError);
  EXPECT_THROW(fitLinear(Eigen::MatrixXd::Ones(2, 2), Eigen::Vector2d(1, 2)), InputError);
  EXPECT_THROW(fitLinear(Eigen::MatrixXd::Zero(5, 1), Eigen::VectorXd::Ones(5)), InputError);
}

TEST(Regression, PraisWinstenRecoversTheCoefficientsAndTheResidualsAr1) {
  // y = 2 + 3 x1 - 1.5 x2 + eps, eps_i = 0.7 eps_{i-1} + a_i, a ~ N(0, 0.5^2), n = 4000
  // (seeded). Standard errors: phi ~ sqrt((1 - phi^2) / n) = 0.011, the slopes ~0.011: the
  // tolerances below are about 4.5 of them.
  std::mt19937_64 rng(4);
  std::normal_distribution<double> normal;
  const int n = 4000;
  Eigen::MatrixXd x(n, 2);
  Eigen::VectorXd y(n);
  double eps = 0.0;
  for (int i = 0; i < n; ++i) {
    x(i, 0) = normal(rng);
    x(i, 1) = normal(rng);
    eps = 0.7 * eps + 0.5 * normal(rng);
    y(i) = 2.0 + 3.0 * x(i, 0) - 1.5 * x(i, 1) + eps;
  }
  const Ar1Fit ar = fitLinearAr1(x, y);
  EXPECT_NEAR(ar.phi, 0.7, 0.05);
  EXPECT_NEAR(ar.fit.coefficients(1), 3.0, 0.05);
  EXPECT_NEAR(ar.fit.coefficients(2), -1.5, 0.05);
  EXPECT_NEAR(ar.fit.coefficients(0), 2.0, 0.2);  // the level: sigma_eps / sqrt(n (1 - phi)^2) = 0.04
  // OLS residuals keep the correlation (DW ~ 2 (1 - phi) = 0.6), the innovations do not.
  EXPECT_NEAR(fitLinear(x, y).durbin_watson, 0.6, 0.1);
  EXPECT_NEAR(durbinWatson(ar.innovations), 2.0, 0.15);
  EXPECT_NEAR(std::sqrt(ar.innovations.squaredNorm() / n), 0.5, 0.03);
}

/// The residual sum of squares of y on the columns of x, by column-pivoting QR.
double directRss(const Eigen::MatrixXd& x, const Eigen::VectorXd& y) {
  if (x.cols() == 0) return y.squaredNorm();
  const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(x);
  return (y - x * qr.solve(y)).squaredNorm();
}

// Columns added to a model: the sum of squares from their Gram matrix beside the model's
// orthonormal basis equals the fit of every reading with them, with a model, with none, and
// with a column the model already has (which adds nothing).
TEST(Regression, ColumnsAddedToAModelFromTheirGramMatrix) {
  std::mt19937_64 rng(7);
  std::normal_distribution<double> normal;
  const Eigen::Index n = 60;
  Eigen::MatrixXd model(n, 4), added(n, 2);
  Eigen::VectorXd y(n);
  for (Eigen::Index i = 0; i < n; ++i) {
    const double t = static_cast<double>(i) / n;
    model.row(i) << 1.0, t, t * t, std::sin(6.0 * t);
    added.row(i) << std::exp(-t / 0.3), t * std::exp(-t / 0.3);
    y(i) = 2.0 - t + 0.7 * added(i, 1) + 0.1 * normal(rng);
  }
  const auto rssWith = [&](const Eigen::MatrixXd& m, const Eigen::MatrixXd& f) {
    Eigen::MatrixXd q(n, 0);
    if (m.cols()) q = Eigen::HouseholderQR<Eigen::MatrixXd>(m).householderQ() * Eigen::MatrixXd::Identity(n, m.cols());
    const Eigen::VectorXd r = y - q * (q.transpose() * y);
    const Eigen::MatrixXd qf = q.transpose() * f;
    return rssWithAddedColumns(r.squaredNorm(), f.transpose() * f - qf.transpose() * qf, f.transpose() * r);
  };
  Eigen::MatrixXd both(n, 6);
  both << model, added;
  EXPECT_NEAR(rssWith(model, added), directRss(both, y), 1e-9 * directRss(both, y));
  EXPECT_NEAR(rssWith(Eigen::MatrixXd(n, 0), added), directRss(added, y), 1e-9 * directRss(added, y));
  Eigen::MatrixXd again(n, 2);
  again << model.col(1), added.col(1);
  Eigen::MatrixXd model_and_one(n, 5);
  model_and_one << model, added.col(1);
  EXPECT_NEAR(rssWith(model, again), directRss(model_and_one, y), 1e-9 * directRss(model_and_one, y));
  EXPECT_EQ(rssWithAddedColumns(3.5, Eigen::MatrixXd(0, 0), Eigen::VectorXd(0)), 3.5);
}

// Brent's method: a parabola's minimum in a few evaluations, a kink's and a cosine's to the
// tolerance, and a function rising from the interval's lower end in two evaluations.
TEST(Minimum, BrentFindsTheMinimumToItsTolerance) {
  int evaluations = 0;
  const auto parabola = [&](double x) {
    ++evaluations;
    return (x - 1.3) * (x - 1.3) + 0.5;
  };
  const auto [x, fx] = brentMinimum(parabola, -5.0, 5.0, 1e-6);
  EXPECT_NEAR(x, 1.3, 2e-6);
  EXPECT_NEAR(fx, 0.5, 1e-11);
  EXPECT_LE(evaluations, 12);  // golden sections alone: about 35 to 1e-6 of 10
  const auto kink = brentMinimum([](double v) { return std::abs(v - 0.7); }, -2.0, 3.0, 1e-5);
  EXPECT_NEAR(kink.first, 0.7, 2e-5);
  const auto cosine = brentMinimum([](double v) { return std::cos(v); }, 0.0, 2.0 * std::numbers::pi, 1e-7);
  EXPECT_NEAR(cosine.first, std::numbers::pi, 2e-7);
  EXPECT_NEAR(cosine.second, -1.0, 1e-12);
  evaluations = 0;
  const auto rising = brentMinimum(
      [&](double v) {
        ++evaluations;
        return std::exp(v);
      },
      -1.0, 4.0, 1e-3);
  EXPECT_EQ(rising.first, -1.0);
  EXPECT_EQ(evaluations, 2);
}

}  // namespace
}  // namespace mtcal::processing
