#include "mtcal/processing/error_model.h"

#include <gtest/gtest.h>

#include <fstream>
#include <nlohmann/json.hpp>

#include "mtcal/error.h"

namespace mtcal::processing {
namespace {

MultibodyModel patentMachine() {
  std::ifstream in(std::string(MTCAL_EXAMPLES_DIR) + "/machines/vmc3-cn104200063.model.json");
  return MultibodyModel::fromJson(nlohmann::json::parse(in), "vmc3-cn104200063.model.json");
}

// Student t quantiles from the standard table (NIST/SEMATECH e-Handbook 1.3.6.7.2):
// t(0.975, 10) = 2.228, t(0.995, 8) = 3.355; the factor equals the normal k as dof grows.
// The demo's grid: nodes every 20 mm from 50 to 590 and one at 600 (29 nodes), knots at the
// 20 mm limit: one coefficient per node. Evenly spaced knots made that interpolation swing by
// 30 um between the first nodes of a 2 um curve; de Boor's averaged knots follow the curve.
TEST(ErrorFunction, InterpolatingFitOfTheDemoGridFollowsTheCurve) {
  auto curve = [](double x) { return 9e-3 * x - 7e-6 * x * x + 1.2 * std::sin(2 * M_PI * x / 180.0 + 0.4); };
  ErrorCurveData d;
  d.name = "EXX";
  for (double x = 50.0; x <= 590.0; x += 20.0) d.position_mm.push_back(x);
  d.position_mm.push_back(600.0);
  for (double x : d.position_mm) {
    d.mean.push_back(curve(x));
    d.s.push_back(0.5);
    d.repeats.push_back(9);
  }
  const auto f = ErrorFunction::fit(d, {});
  EXPECT_EQ(f.spline()->coefficients().size(), 29);
  for (double x = 50.0; x <= 600.0; x += 1.7) EXPECT_NEAR(f.value(x), curve(x), 0.03) << x;
}

TEST(CoverageFactor, MatchesTheStudentTTable) {
  EXPECT_NEAR(coverageFactor(1.959964, 10), 2.228, 0.001);
  EXPECT_NEAR(coverageFactor(2.575829, 8), 3.355, 0.001);
  EXPECT_NEAR(coverageFactor(3.0, 1000000), 3.0, 1e-3);
  EXPECT_DOUBLE_EQ(coverageFactor(3.0, 0), 3.0);
  // The patent's 9 repeats: +-3 s covers less than 99.73 % unless widened to 4.2766 s
  // (t quantile at 0.998650 with 8 degrees of freedom, checked by integrating the t density).
  EXPECT_NEAR(coverageFactor(3.0, 8), 4.2766, 1e-4);
}

ErrorCurveData curve(const std::string& name, double slope_um_per_mm, double s, int repeats) {
  ErrorCurveData d;
  d.name = name;
  for (double p = 50.0; p <= 600.0; p += 50.0) {
    d.position_mm.push_back(p);
    d.mean.push_back(slope_um_per_mm * p);
    d.s.push_back(s);
    d.repeats.push_back(repeats);
  }
  return d;
}

TEST(ErrorFunction, FitsNodeMeansAndCarriesTheirScatter) {
  ErrorCurveData d = curve("EXX", 0.01, 0.5, 9);
  d.s[3] = 1.5;  // one noisier node
  const auto f = ErrorFunction::fit(d, {});
  EXPECT_FALSE(f.constant());
  for (double p = 50.0; p <= 600.0; p += 10.0)
    EXPECT_NEAR(f.value(p), 0.01 * p, 1e-9) << p;  // a line is in the spline space
  EXPECT_DOUBLE_EQ(f.sigma(50.0), 0.5);
  EXPECT_DOUBLE_EQ(f.sigma(200.0), 1.5);
  EXPECT_DOUBLE_EQ(f.sigma(175.0), 1.0);  // halfway between 0.5 at 150 and 1.5 at 200
  EXPECT_EQ(f.degreesOfFreedom(), 12 * 8);
  // Nodes 50 mm apart with a 20 mm minimum knot spacing: capped at as many coefficients as nodes.
  EXPECT_LE(f.spline()->coefficients().size(), 12);
}

TEST(ErrorFunction, WithoutRepeatsTheResidualIsTheScatter) {
  ErrorCurveData d = curve("EXX", 0.0, 0.0, 1);
  for (std::size_t i = 0; i < d.mean.size(); ++i) {
    d.mean[i] = (i % 2 ? 1.0 : -1.0);  // alternating: no smooth curve fits it
    d.s[i] = std::nullopt;
  }
  ErrorFitOptions wide;
  wide.min_knot_spacing_mm = 200.0;
  const auto f = ErrorFunction::fit(d, wide);
  EXPECT_GT(f.sigma(300.0), 0.8);
  EXPECT_GT(f.degreesOfFreedom(), 0);
}

// The fit's own error: each node's mean of variance s^2 / repeats (s pooled over the nodes)
// through the weighted fit. Closed forms: a straight line fitted to N equally weighted nodes has
// Var(y(x)) = s^2 / n (1 / N + (x - mean)^2 / Sxx) and Cov(y(a), y(b)) = s^2 / n (1 / N + (a -
// mean)(b - mean) / Sxx); an interpolating broken line has each node's mean's own variance there
// and, halfway between two, half of it.
TEST(ErrorFunction, ItsFitErrorIsItsNodesPooledScatterThroughTheFit) {
  ErrorCurveData d{
      "EXX", {0.0, 10.0, 20.0, 30.0, 40.0}, {0.1, -0.2, 0.3, 0.0, 0.4}, {0.3, 0.3, 0.3, 0.3, 0.3}, {4, 4, 4, 4, 4}};
  const auto line = ErrorFunction::fit(d, {1, 1000.0});  // one span: a straight line
  ASSERT_EQ(line.spline()->coefficients().size(), 2);
  const Eigen::MatrixXd f = line.fitErrorFactor(Eigen::Vector3d(0.0, 20.0, 40.0));
  ASSERT_EQ(f.rows(), 3);
  ASSERT_EQ(f.cols(), 5);
  const Eigen::MatrixXd covariance = f * f.transpose();
  const double unit = 0.09 / 4.0;  // s^2 / n; N 5, mean 20, Sxx 1000
  EXPECT_NEAR(covariance(0, 0), unit * (0.2 + 400.0 / 1000.0), 1e-12);
  EXPECT_NEAR(covariance(1, 1), unit * 0.2, 1e-12);
  EXPECT_NEAR(covariance(0, 2), unit * (0.2 - 400.0 / 1000.0), 1e-12);

  // Unequal scatter: the weights are the nodes' own, the means' variances the pooled s's.
  d.s = {0.2, 0.4, 0.2, 0.4, 0.2};
  const double pooled_variance = (3 * 0.04 + 2 * 0.16) / 5.0;
  const auto broken = ErrorFunction::fit(d, {1, 10.0});  // four spans: through every node
  ASSERT_EQ(broken.spline()->coefficients().size(), 5);
  const Eigen::MatrixXd g = broken.fitErrorFactor(Eigen::Vector3d(10.0, 15.0, 30.0));
  const Eigen::MatrixXd c = g * g.transpose();
  EXPECT_NEAR(c(0, 0), pooled_variance / 4.0, 1e-12);
  EXPECT_NEAR(c(1, 1), 0.5 * pooled_variance / 4.0, 1e-12);
  EXPECT_NEAR(c(0, 2), 0.0, 1e-12);
  EXPECT_NEAR(c(0, 1), 0.5 * pooled_variance / 4.0, 1e-12);

  // Stored and read back, the repeats and so the statement stay; a function stored without them
  // (before they were kept) states nothing.
  const auto j = broken.toJson();
  EXPECT_EQ(j.at("node_repeats"), nlohmann::json({4, 4, 4, 4, 4}));
  EXPECT_TRUE(ErrorFunction::fromJson("EXX", j).fitErrorFactor(Eigen::Vector3d(10.0, 15.0, 30.0)).isApprox(g));
  auto old = j;
  old.erase("node_repeats");
  EXPECT_EQ(ErrorFunction::fromJson("EXX", old).fitErrorFactor(Eigen::Vector3d(10.0, 15.0, 30.0)).size(), 0);
  auto wrong = j;
  wrong["node_repeats"] = {4, 4, 0, 4, 4};
  EXPECT_THROW(ErrorFunction::fromJson("EXX", wrong), InputError);
  wrong["node_repeats"] = {4, 4};
  EXPECT_THROW(ErrorFunction::fromJson("EXX", wrong), InputError);
}

// Where the scatter is not known, nothing is stated (not a zero error): a constant measured once,
// a curve through nodes read once each. A model states nothing to readings that see a function
// which states nothing, and through each reading's sensitivity otherwise.
TEST(ErrorFunction, WhatIsNotKnownIsNotStatedAsExact) {
  EXPECT_EQ(ErrorFunction::fit({"EC0Y", {}, {12.0}, {std::nullopt}, {1}}, {})
                .fitErrorFactor(Eigen::Vector2d(0.0, 1.0))
                .size(),
            0);
  const ErrorCurveData once{
      "EXX", {0.0, 10.0, 20.0}, {0.1, -0.2, 0.3}, {std::nullopt, std::nullopt, std::nullopt}, {1, 1, 1}};
  const auto through = ErrorFunction::fit(once, {2, 10.0});
  ASSERT_EQ(through.degreesOfFreedom(), 0);
  EXPECT_EQ(through.fitErrorFactor(Eigen::Vector2d(5.0, 15.0)).size(), 0);

  const ErrorCurveData measured{"EXX", {0.0, 200.0, 400.0}, {0.1, -0.2, 0.3}, {0.3, 0.3, 0.3}, {5, 5, 5}};
  const auto exx = ErrorFunction::fit(measured, {2, 200.0});
  const ErrorModel model(patentMachine(), {exx, ErrorFunction("EBX", 20.0, 4.0)});
  const auto& terms = model.kinematics().terms();
  std::vector<Eigen::VectorXd> q(
      2, Eigen::VectorXd::Zero(static_cast<Eigen::Index>(model.kinematics().coordinates().size())));
  q[1](0) = 100.0;
  Eigen::MatrixXd sensitivity = Eigen::MatrixXd::Zero(2, static_cast<Eigen::Index>(terms.size()));
  sensitivity.col(model.kinematics().termIndex("EXX")).setConstant(-1.0);
  const Eigen::MatrixXd f = model.readingFitErrorFactor(q, sensitivity);
  EXPECT_TRUE(f.isApprox(-exx.fitErrorFactor(Eigen::Vector2d(0.0, 100.0))));
  sensitivity(1, model.kinematics().termIndex("EBX")) = 0.05;  // an Abbe arm: the pitch's error is not stated
  EXPECT_EQ(model.readingFitErrorFactor(q, sensitivity).size(), 0);
}

TEST(ErrorModel, SpatialErrorAndItsSigmaFollowTheLeverArms) {
  std::vector<ErrorFunction> functions;
  functions.push_back(ErrorFunction::fit(curve("EXX", 0.01, 0.6, 9), {}));  // 10 um per metre
  functions.push_back(ErrorFunction("EBX", 20.0, 4.0));                     // pitch 20 urad +- 4
  const ErrorModel model(patentMachine(), functions);
  const Eigen::Vector3d q(500.0, 100.0, 320.0);
  // E_x = -(EXX + EBX (z - 120) 1e-3) = -(5 + 20 * 200e-3) = -9 um.
  EXPECT_NEAR(model.predictUm(q)(0), -9.0, 1e-6);
  EXPECT_NEAR(model.predictUm(q)(1), 0.0, 1e-9);
  // Var(E_x) = 0.6^2 + (4 * 0.2)^2.
  const Eigen::Vector3d s = model.sigmaUm(q);
  EXPECT_NEAR(s(0), std::sqrt(0.36 + 0.64), 1e-9);
  EXPECT_NEAR(s(1), 0.0, 1e-12);
  const auto keys = model.keyErrors(q);
  EXPECT_EQ(keys[0].name, "EBX");
  EXPECT_NEAR(keys[0].share[0], 0.64, 1e-9);
  EXPECT_NEAR(keys[1].share[0], 0.36, 1e-9);
  double sum = 0.0;
  for (const auto& k : keys) sum += k.share[0];
  EXPECT_NEAR(sum, 1.0, 1e-12);
  EXPECT_THROW(ErrorModel(patentMachine(), {ErrorFunction("EQQ", 1.0, 0.0)}), InputError);
}

// The grid evaluator computes the same values as the point-by-point full model.
TEST(ErrorModel, GridPredictionEqualsPointPrediction) {
  std::vector<ErrorFunction> functions;
  functions.push_back(ErrorFunction::fit(curve("EXX", 0.01, 0.6, 9), {}));
  functions.push_back(ErrorFunction::fit(curve("EBX", 0.03, 1.0, 9), {}));
  functions.push_back(ErrorFunction::fit(curve("EAY", -0.02, 1.0, 9), {}));
  functions.push_back(ErrorFunction::fit(curve("ECZ", 0.05, 1.0, 9), {}));
  functions.push_back(ErrorFunction("EC0Y", 15.0, 1.0));
  const ErrorModel model(patentMachine(), functions);
  const std::vector<std::vector<double>> axes = {{50.0, 300.0, 600.0}, {60.0, 410.0}, {100.0, 250.0, 333.0, 590.0}};
  const auto grid = model.predictGridUm(axes);
  ASSERT_EQ(grid.size(), 24u);
  std::size_t n = 0;
  for (double x : axes[0]) {
    for (double y : axes[1]) {
      for (double z : axes[2]) {
        EXPECT_TRUE(grid[n].isApprox(model.predictUm(Eigen::Vector3d(x, y, z)), 1e-9)) << x << " " << y << " " << z;
        ++n;
      }
    }
  }
}

}  // namespace
}  // namespace mtcal::processing
