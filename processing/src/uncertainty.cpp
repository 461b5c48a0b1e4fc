#include "mtcal/processing/uncertainty.h"

#include <algorithm>
#include <cmath>
#include <random>

#include "mtcal/error.h"

namespace mtcal::processing {
namespace {

// The band's two components in coordinate order (X before Y before Z).
std::array<int, 2> axesOf(Plane plane) {
  const PlaneAxes a = planeAxes(plane);
  return {std::min(a.first, a.second), std::max(a.first, a.second)};
}

}  // namespace

double PlaneBand::meanAt(double eta_rad) const {
  return mean_um[0] * std::cos(eta_rad) + mean_um[1] * std::sin(eta_rad);
}

double PlaneBand::sigmaAt(double eta_rad) const {
  const double c = std::cos(eta_rad), s = std::sin(eta_rad);
  return std::sqrt(std::max(0.0, covariance[0] * c * c + covariance[1] * s * s + 2.0 * covariance[2] * c * s));
}

double PlaneBand::widestBandUm() const {
  const double mean = (covariance[0] + covariance[1]) / 2.0;
  const double diff = (covariance[0] - covariance[1]) / 2.0;
  return coverage_k * std::sqrt(std::max(0.0, mean + std::sqrt(diff * diff + covariance[2] * covariance[2])));
}

PlaneBand planeBand(const ErrorModel& model, Plane plane, const Eigen::VectorXd& q) {
  const auto [a, b] = axesOf(plane);
  const Eigen::Vector3d mean = model.predictUm(q);
  const Eigen::Matrix3Xd jac = model.kinematics().jacobian(q);
  const Eigen::VectorXd s2 = model.sigmasAt(q).array().square();
  PlaneBand band;
  for (int i = 0; i < 3; ++i) band.point_mm[static_cast<std::size_t>(i)] = i < q.size() ? q(i) : 0.0;
  band.mean_um = {mean(a), mean(b)};
  band.covariance = {(jac.row(a).array().square() * s2.transpose().array()).sum(),
                     (jac.row(b).array().square() * s2.transpose().array()).sum(),
                     (jac.row(a).array() * jac.row(b).array() * s2.transpose().array()).sum()};
  // The least certain contributing sigma sets the coverage factor.
  int dof = 0;
  for (const auto& f : model.functions()) {
    if (f.degreesOfFreedom() > 0) dof = dof == 0 ? f.degreesOfFreedom() : std::min(dof, f.degreesOfFreedom());
  }
  band.coverage_k = coverageFactor(3.0, dof);
  return band;
}

std::vector<SobolIndex> sobolFirstOrder(const ErrorModel& model, const Eigen::VectorXd& q, int samples,
                                        std::uint64_t seed) {
  if (samples < 10) throw InputError("Sobol: at least 10 samples are needed");
  const Eigen::VectorXd mean = model.errorsAt(q);
  const Eigen::VectorXd sigma = model.sigmasAt(q);
  const auto d = mean.size();
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal;
  auto draw = [&] {
    Eigen::MatrixXd m(samples, d);
    for (Eigen::Index i = 0; i < samples; ++i) {
      for (Eigen::Index j = 0; j < d; ++j) m(i, j) = mean(j) + sigma(j) * normal(rng);
    }
    return m;
  };
  const Eigen::MatrixXd a = draw(), b = draw();
  const auto& kin = model.kinematics();
  auto evaluate = [&](const Eigen::MatrixXd& m) {
    Eigen::Matrix3Xd out(3, samples);
    for (Eigen::Index i = 0; i < samples; ++i) out.col(i) = kin.spatialErrorUm(q, m.row(i).transpose());
    return out;
  };
  const Eigen::Matrix3Xd fa = evaluate(a), fb = evaluate(b);
  Eigen::Vector3d variance, output_mean;
  for (int k = 0; k < 3; ++k) {
    Eigen::VectorXd all(2 * samples);
    all << fa.row(k).transpose(), fb.row(k).transpose();
    output_mean(k) = all.mean();
    variance(k) = (all.array() - all.mean()).square().sum() / static_cast<double>(all.size() - 1);
  }
  std::vector<SobolIndex> out;
  for (Eigen::Index j = 0; j < d; ++j) {
    SobolIndex index;
    index.name = kin.terms()[static_cast<std::size_t>(j)].name;
    if (sigma(j) > 0.0) {
      Eigen::MatrixXd ab = a;
      ab.col(j) = b.col(j);
      const Eigen::Matrix3Xd fab = evaluate(ab);
      for (int k = 0; k < 3; ++k) {
        // Saltelli et al. 2010, Table 2 (b): V_j = mean(f(B) (f(A_B^j) - f(A))), with f(B) centred
        // on the sample mean: still unbiased, and its variance no longer grows with the mean
        // error squared (the spatial error is far from zero-mean).
        const double vj = ((fb.row(k).array() - output_mean(k)) * (fab.row(k).array() - fa.row(k).array())).mean();
        index.first_order[static_cast<std::size_t>(k)] = variance(k) > 0.0 ? vj / variance(k) : 0.0;
      }
    }
    out.push_back(index);
  }
  return out;
}

}  // namespace mtcal::processing
