#include "mtcal/processing/spindle_thermal.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "mtcal/error.h"

namespace mtcal::processing {
namespace {

constexpr double kPi = std::numbers::pi;

// Petroff: a concentric film (eps = 0) carries no pressure and its friction number is the
// Couette shear over the whole film, 2 pi L/R.
TEST(Reynolds, ConcentricFilmIsPetroff) {
  const auto s = solveReynolds(0.0, 1.0);
  EXPECT_NEAR(s.load_number, 0.0, 1e-12);
  EXPECT_NEAR(s.friction_number, 2 * kPi * 1.0, 1e-9);
}

// Ocvirk's short-bearing solution (half-Sommerfeld; e.g. Hamrock, Fundamentals of Fluid Film
// Lubrication, ch. 10): W = mu U L^3 / (4 c^2) eps / (1 - eps^2)^2 sqrt(pi^2 (1 - eps^2) + 16 eps^2),
// attitude tan(phi) = pi sqrt(1 - eps^2) / (4 eps). In the dimensionless load number of
// solveReynolds (W c^2 / (mu omega R^4), U = omega R): (L/R)^3 / 4 times the eps factor. For
// L/D = 1/8 the short-bearing approximation is within a few per cent of the finite bearing.
TEST(Reynolds, ShortBearingMatchesOcvirk) {
  const double lambda = 0.25;  // L/R
  for (double eps : {0.3, 0.5, 0.7}) {
    const auto s = solveReynolds(eps, lambda, 96, 21);
    const double ocvirk = lambda * lambda * lambda / 4 * eps / std::pow(1 - eps * eps, 2) *
                          std::sqrt(kPi * kPi * (1 - eps * eps) + 16 * eps * eps);
    EXPECT_NEAR(s.load_number / ocvirk, 1.0, 0.05) << eps;
    EXPECT_NEAR(s.attitude_rad, std::atan(kPi * std::sqrt(1 - eps * eps) / (4 * eps)), 0.05) << eps;
    EXPECT_GT(s.pressure.minCoeff(), -1e-15);  // no tension in the film
  }
  EXPECT_THROW(solveReynolds(1.0, 1.0), InputError);
}

TEST(BearingFriction, PowerGrowsWithSpeedAndFallsWithTemperature) {
  const BearingFriction b(SpindleThermalModel::headstock().front);
  EXPECT_EQ(b.at(0.0, 30.0).friction_power_w, 0.0);
  const auto slow = b.at(500.0, 30.0), fast = b.at(2000.0, 30.0), hot = b.at(2000.0, 45.0);
  // Petroff's P = mu omega^2 R^3 2 pi L / c for the concentric film; at the eccentricity that
  // carries the load the Couette shear alone integrates to 2 pi L / R / sqrt(1 - eps^2), the
  // pressure-driven part adds a little.
  const double omega = 2000 * 2 * kPi / 60, mu = b.viscosityPaS(30.0);
  const double petroff = mu * omega * omega * std::pow(0.025, 3) * 2 * kPi * 0.025 / 50e-6;
  const double couette = 1.0 / std::sqrt(1 - fast.eccentricity * fast.eccentricity);
  EXPECT_GT(fast.friction_power_w / petroff, couette - 0.01);
  EXPECT_LT(fast.friction_power_w / petroff, couette + 0.1);
  EXPECT_GT(fast.eccentricity, 0.1);
  EXPECT_LT(fast.eccentricity, slow.eccentricity);              // the faster film carries the load thicker
  EXPECT_GT(fast.friction_power_w, 8 * slow.friction_power_w);  // ~ omega^2, less the eccentric film's extra shear
  EXPECT_NEAR(hot.viscosity_pa_s / fast.viscosity_pa_s, std::exp(-0.03 * 15), 1e-12);
  EXPECT_LT(hot.friction_power_w, fast.friction_power_w);
}

// The network's steady state solves G T = heat + G_amb T_amb; a step in heat approaches it;
// with no heat and the ambient at the reference the drift stays exactly zero.
TEST(ThermalNetwork, ReachesItsSteadyStateAndDriftsFromIt) {
  SpindleThermalModel m = SpindleThermalModel::headstock();
  ThermalNetwork idle(m, 20.0, 10.0);
  for (int i = 0; i < 100; ++i) idle.step(0.0, 20.0);
  EXPECT_EQ(idle.driftUm(idle.temperatures()).norm(), 0.0);
  ThermalNetwork net(m, 20.0, 60.0);
  for (int i = 0; i < 24 * 60 * 10; ++i) net.step(1800.0, 20.0);  // 10 days: the column's hours are long past
  const auto [front_w, rear_w] = net.lastPowerW();
  const auto n = static_cast<Eigen::Index>(m.nodes.size());
  Eigen::MatrixXd g = Eigen::MatrixXd::Zero(n, n);
  for (Eigen::Index i = 0; i < n; ++i) g(i, i) = m.nodes[static_cast<std::size_t>(i)].to_ambient_w_per_k;
  for (const auto& l : m.links) {
    g(l.a, l.a) += l.conductance_w_per_k;
    g(l.b, l.b) += l.conductance_w_per_k;
    g(l.a, l.b) -= l.conductance_w_per_k;
    g(l.b, l.a) -= l.conductance_w_per_k;
  }
  Eigen::VectorXd heat = Eigen::VectorXd::Zero(n);
  heat(0) = front_w;
  heat(1) = rear_w;
  const Eigen::VectorXd rise = g.partialPivLu().solve(heat);
  EXPECT_NEAR((net.temperatures().array() - 20.0 - rise.array()).abs().maxCoeff(), 0.0, 1e-6);
  EXPECT_GT(rise(0), rise(3));  // the bearing runs hotter than the headstock
  // Energy balance: what leaves to the ambient is what the films make.
  EXPECT_NEAR((Eigen::VectorXd(m.nodes.size()).setZero() + rise)
                  .dot(Eigen::Map<Eigen::VectorXd>(std::vector<double>{0, 0, 2, 10, 35}.data(), 5)),
              front_w + rear_w, 1e-6);
  const Eigen::Vector3d drift = net.driftUm(net.temperatures());
  EXPECT_NEAR(drift(2), m.drift_um_per_k.row(2).dot(rise), 1e-6);
  // Sensor sites are weighted means: the ambient site reads the ambient.
  EXPECT_NEAR(net.sensorsC(net.temperatures(), 21.5)(7), 21.5, 1e-12);
}

}  // namespace
}  // namespace mtcal::processing
