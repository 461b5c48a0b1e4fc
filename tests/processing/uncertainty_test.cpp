#include "mtcal/processing/uncertainty.h"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
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
// its variance share; the full model is linear to first order, so Monte Carlo on it must
// agree with keyErrors() within the sampling error (N = 4000: about 0.02).
TEST(Sobol, MonteCarloOnTheFullModelConfirmsTheKeyErrorShares) {
  const auto m = model({ErrorFunction("EXX", 1.0, 0.6), ErrorFunction("EBX", 5.0, 4.0),
                        ErrorFunction("ECX", -3.0, 3.0), ErrorFunction("EXY", 0.5, 1.0)});
  const Eigen::Vector3d q(400, 250, 320);
  const auto sobol = sobolFirstOrder(m, q, 4000, 17);
  const auto keys = m.keyErrors(q);
  int compared = 0;
  for (const auto& k : keys) {
    if (k.share[0] <= 0.0) continue;
    const auto it = std::find_if(sobol.begin(), sobol.end(), [&](const SobolIndex& s) { return s.name == k.name; });
    ASSERT_NE(it, sobol.end());
    EXPECT_NEAR(it->first_order[0], k.share[0], 0.04) << k.name;
    ++compared;
  }
  EXPECT_EQ(compared, 4);
  EXPECT_EQ(sobolFirstOrder(m, q, 100, 5)[0].first_order, sobolFirstOrder(m, q, 100, 5)[0].first_order);  // seeded
  EXPECT_THROW(sobolFirstOrder(m, q, 5, 1), InputError);
  EXPECT_THROW(parsePlane("XW"), InputError);
}

}  // namespace
}  // namespace mtcal::processing
