#pragma once
// Stochastic description of the spatial error (patent CN104200063, step 3): the plane
// random process of the error on a machined plane and a variance-based (Sobol) check of the
// key-error ranking. Pure numerics; Monte Carlo is seeded and reproducible.

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "mtcal/processing/error_model.h"
#include "mtcal/processing/plane.h"

namespace mtcal::processing {

/// The error in a machined plane at one point: the two in-plane components are jointly
/// Gaussian (mean, covariance from the error model; shared error terms correlate them).
/// Along a direction eta in the plane, E(eta) = E_a cos(eta) + E_b sin(eta) (the patent's
/// plane random process with omega eta the direction angle).
struct PlaneBand {
  std::array<double, 3> point_mm{};
  std::array<double, 2> mean_um{};     ///< E_a, E_b
  std::array<double, 3> covariance{};  ///< var a, var b, cov ab (um^2)
  double coverage_k = 3.0;             ///< band half-width in sigmas (t-corrected)
  /// Mean and band half-width of E(eta).
  double meanAt(double eta_rad) const;
  double sigmaAt(double eta_rad) const;
  /// The widest half-width over all directions: k sqrt(largest eigenvalue).
  double widestBandUm() const;
};

/// Band at q (coordinates of the model) for `plane`, with a +-3 sigma coverage corrected by
/// the t factor of the smallest degrees of freedom among the contributing error terms.
PlaneBand planeBand(const ErrorModel& model, Plane plane, const Eigen::VectorXd& q);

/// First-order Sobol indices of every error term for E_x, E_y, E_z at q, by Monte Carlo
/// with the full (nonlinear) model: error terms independent N(mean, sigma^2). Saltelli's
/// estimator (2010) on N base samples, (terms + 2) N model evaluations.
struct SobolIndex {
  std::string name;
  std::array<double, 3> first_order{};
};
std::vector<SobolIndex> sobolFirstOrder(const ErrorModel& model, const Eigen::VectorXd& q, int samples,
                                        std::uint64_t seed);

}  // namespace mtcal::processing
