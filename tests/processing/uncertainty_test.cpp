#include "mtcal/processing/uncertainty.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>

#include "mtcal/error.h"

namespace mtcal::processing {
namespace {

ErrorModel model(std::vector<ErrorFunction> functions) {
  std::ifstream in(std::string(MTCAL_EXAMPLES_DIR) + "/machines/vmc3-cn104200063.model.json");
  return ErrorModel(MultibodyModel::fromJson(nlohmann::json::parse(in), "vmc3"), std::move(functions));
}

// Independent components: the band along direction eta is k sqrt(sa^2 cos^2 + sb^2 sin^2).
TEST(PlaneBand, IndependentComponents) {
  const auto m = model({ErrorFunction("EXX", 2.0, 0.6), ErrorFunction("EYY", -1.0, 0.8)});
  const PlaneBand band = planeBand(m, Plane::kXY, Eigen::Vector3d(300, 200, 250));
  EXPECT_NEAR(band.mean_um[0], -2.0, 1e-9);
  EXPECT_NEAR(band.mean_um[1], 1.0, 1e-9);
  EXPECT_NEAR(band.sigmaAt(0.0), 0.6, 1e-9);
  EXPECT_NEAR(band.sigmaAt(M_PI / 2), 0.8, 1e-9);
  EXPECT_NEAR(band.sigmaAt(M_PI / 4), std::sqrt((0.36 + 0.64) / 2.0), 1e-9);
  EXPECT_NEAR(band.covariance[2], 0.0, 1e-15);
  EXPECT_DOUBLE_EQ(band.coverage_k, 3.0);  // constants: no degrees of freedom known
  EXPECT_NEAR(band.widestBandUm(), 3.0 * 0.8, 1e-9);
  EXPECT_NEAR(band.meanAt(M_PI), 2.0, 1e-9);
}

// One roll error of X moves the tool point in Y and Z at once (lever arms z - L and y):
// the two components are fully correlated, and the widest band is k sqrt(var_y + var_z).
TEST(PlaneBand, ASharedErrorTermCorrelatesTheComponents) {
  const auto m = model({ErrorFunction("EAX", 0.0, 10.0)});
  const Eigen::Vector3d q(100, 300, 420);  // z - L = 300 mm, y = 300 mm
  const PlaneBand band = planeBand(m, Plane::kYZ, q);
  const double sy = 10.0 * 300.0 * 1e-3, sz = 10.0 * 300.0 * 1e-3;
  EXPECT_NEAR(band.covariance[0], sy * sy, 1e-9);
  EXPECT_NEAR(band.covariance[1], sz * sz, 1e-9);
  EXPECT_NEAR(std::abs(band.covariance[2]), sy * sz, 1e-9);  // |correlation| = 1
  EXPECT_NEAR(band.widestBandUm(), 3.0 * std::sqrt(sy * sy + sz * sz), 1e-9);
}

// For a linear model with independent inputs the first-order Sobol index of a term equals
// its variance share. E_x at q = (400, 250, 320) by hand: the tool point sits at (0, y, z - L)
// = (0, 250, 200) mm from the X carriage (L = 120 mm tool offset), so a pitch of X (EBX) moves
// it in x by 200 mm x EBX and a yaw (ECX) by 250 mm x ECX; EXX and EXY move it in x one to
// one. With sigmas 0.6 um, 4 urad, 3 urad and 1 um:
//   Var(E_x) = 0.6^2 + (0.004 x 200)^2 + (0.003 x 250)^2 + 1^2 = 0.36 + 0.64 + 0.5625 + 1
//            = 2.5625 um^2, shares 144/1025, 256/1025, 225/1025 and 400/1025.
// The full model is linear to first order (the errors are micro-radians), so both the
// analytic shares and the Monte Carlo indices must give these.
//
// Monte Carlo standard error of the estimator (Saltelli 2010, Table 2 (b), with f(B) centred),
// derived for this linear Gaussian case: with S = c_j b_j', T = c_j a_j' and R the other terms
// of f(B), each product (S + R)(S - T) has mean V_j and variance V_j^2 + 2 V V_j, so
// se(V_j)/V = sqrt((S_j^2 + 2 S_j)/N); the estimated Var(E) (2N samples) adds about
// S_j/sqrt(N) in quadrature: se(S_j) ~ sqrt(2 S_j (1 + S_j) / N), 0.0045 to 0.0082 at
// N = 16000 (an upper bound: the two errors are positively correlated and partly cancel).
// Every estimate must lie within 4 se of the closed form. Measured: within 0.011 (seed 17)
// and 0.014 (seed 18), both for EBX.
TEST(Sobol, MonteCarloAndKeyErrorSharesMatchTheLeverArmClosedForm) {
  const auto m = model({ErrorFunction("EXX", 1.0, 0.6), ErrorFunction("EBX", 5.0, 4.0), ErrorFunction("ECX", -3.0, 3.0),
                        ErrorFunction("EXY", 0.5, 1.0)});
  const Eigen::Vector3d q(400, 250, 320);
  const std::map<std::string, double> closed_form{
      {"EXX", 144.0 / 1025.0}, {"EBX", 256.0 / 1025.0}, {"ECX", 225.0 / 1025.0}, {"EXY", 400.0 / 1025.0}};
  EXPECT_NEAR(m.sigmaUm(q)(0), std::sqrt(2.5625), 1e-6);

  // The analytic shares (first order): exact up to the second order of the micro-radians.
  int shares_found = 0;
  for (const auto& k : m.keyErrors(q)) {
    const auto it = closed_form.find(k.name);
    if (it == closed_form.end()) {
      EXPECT_EQ(k.share[0], 0.0) << k.name;  // terms without a sigma take no share
      continue;
    }
    EXPECT_NEAR(k.share[0], it->second, 1e-6) << k.name;
    ++shares_found;
  }
  EXPECT_EQ(shares_found, 4);

  // Monte Carlo with two seeds: different estimates, each within 4 standard errors.
  constexpr int kSamples = 16000;
  const auto first = sobolFirstOrder(m, q, kSamples, 17);
  const auto second = sobolFirstOrder(m, q, kSamples, 18);
  ASSERT_EQ(first.size(), second.size());
  int compared = 0;
  double largest_seed_difference = 0.0;
  for (std::size_t i = 0; i < first.size(); ++i) {
    ASSERT_EQ(first[i].name, second[i].name);
    const auto it = closed_form.find(first[i].name);
    if (it == closed_form.end()) {
      EXPECT_EQ(first[i].first_order[0], 0.0) << first[i].name;  // zero sigma: not sampled
      continue;
    }
    const double s = it->second;
    const double se = std::sqrt(2.0 * s * (1.0 + s) / kSamples);
    EXPECT_NEAR(first[i].first_order[0], s, 4.0 * se) << first[i].name << " seed 17";
    EXPECT_NEAR(second[i].first_order[0], s, 4.0 * se) << first[i].name << " seed 18";
    // Two independent estimates differ by about sqrt(2) se: not identical, and not by more
    // than the sampling allows.
    const double difference = std::abs(first[i].first_order[0] - second[i].first_order[0]);
    EXPECT_LT(difference, 4.0 * std::sqrt(2.0) * se) << first[i].name;
    largest_seed_difference = std::max(largest_seed_difference, difference);
    ++compared;
  }
  EXPECT_EQ(compared, 4);
  EXPECT_GT(largest_seed_difference, 1e-4);  // the seed is used: another seed, another sample
  EXPECT_THROW(sobolFirstOrder(m, q, 5, 1), InputError);
  EXPECT_THROW(parsePlane("XW"), InputError);
}

}  // namespace
}  // namespace mtcal::processing
