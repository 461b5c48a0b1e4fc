#include "mtcal/processing/spindle_thermal.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <numbers>

#include "mtcal/error.h"

namespace mtcal::processing {
namespace {
constexpr double kPi = std::numbers::pi;
constexpr double kMaxEccentricity = 0.95;
}  // namespace

ReynoldsSolution solveReynolds(double eccentricity, double length_over_radius, int n_theta, int n_axial) {
  if (!(eccentricity >= 0.0 && eccentricity < 1.0))
    throw InputError(fmt::format("Reynolds: eccentricity {} is not in [0, 1)", eccentricity));
  if (!(length_over_radius > 0.0) || n_theta < 8 || n_axial < 3) {
    throw InputError(fmt::format("Reynolds: L/R {} on a {} x {} grid", length_over_radius, n_theta, n_axial));
  }
  const double dt = 2.0 * kPi / n_theta, dz = length_over_radius / (n_axial - 1);
  auto h = [&](double theta) { return 1.0 + eccentricity * std::cos(theta); };
  Eigen::VectorXd a_east(n_theta), a_west(n_theta), a_axial(n_theta), rhs(n_theta), h_node(n_theta);
  for (int i = 0; i < n_theta; ++i) {
    const double theta = i * dt;
    const double he = h(theta + dt / 2), hw = h(theta - dt / 2);
    h_node(i) = h(theta);
    a_east(i) = he * he * he / (dt * dt);
    a_west(i) = hw * hw * hw / (dt * dt);
    a_axial(i) = h_node(i) * h_node(i) * h_node(i) / (dz * dz);
    rhs(i) = 6.0 * (he - hw) / dt;
  }
  ReynoldsSolution s;
  Eigen::MatrixXd& p = s.pressure;
  p = Eigen::MatrixXd::Zero(n_theta, n_axial);
  constexpr double kOmega = 1.8;  // over-relaxation
  for (s.iterations = 1; s.iterations <= 50000; ++s.iterations) {
    double change = 0.0, largest = 0.0;
    for (int j = 1; j < n_axial - 1; ++j) {
      for (int i = 0; i < n_theta; ++i) {
        const int e = (i + 1) % n_theta, w = (i + n_theta - 1) % n_theta;
        const double sum = a_east(i) + a_west(i) + 2.0 * a_axial(i);
        const double gs =
            (a_east(i) * p(e, j) + a_west(i) * p(w, j) + a_axial(i) * (p(i, j + 1) + p(i, j - 1)) - rhs(i)) / sum;
        const double next = std::max(0.0, p(i, j) + kOmega * (gs - p(i, j)));  // Reynolds condition: no tension
        change = std::max(change, std::abs(next - p(i, j)));
        largest = std::max(largest, next);
        p(i, j) = next;
      }
    }
    if (eccentricity == 0.0 || change <= 1e-10 * std::max(largest, 1e-12)) break;
  }
  if (s.iterations > 50000) throw InputError(fmt::format("Reynolds: no convergence at eccentricity {}", eccentricity));
  // Trapezoid rule (the ends' pressure is zero; periodic in theta).
  double wx = 0.0, wy = 0.0, friction = 0.0;
  for (int j = 0; j < n_axial; ++j) {
    const double wz = (j == 0 || j == n_axial - 1) ? 0.5 * dz : dz;
    for (int i = 0; i < n_theta; ++i) {
      const double theta = i * dt;
      wx += p(i, j) * std::cos(theta) * dt * wz;
      wy += p(i, j) * std::sin(theta) * dt * wz;
      const double dpdt = (p((i + 1) % n_theta, j) - p((i + n_theta - 1) % n_theta, j)) / (2.0 * dt);
      friction += (1.0 / h_node(i) + 0.5 * h_node(i) * dpdt) * dt * wz;
    }
  }
  s.load_number = std::hypot(wx, wy);
  s.attitude_rad = s.load_number > 0.0 ? std::atan2(wy, -wx) : kPi / 2;
  s.friction_number = friction;
  return s;
}

BearingFriction::BearingFriction(JournalBearing bearing, int curve_points) : bearing_(bearing) {
  if (!(bearing_.radius_mm > 0.0 && bearing_.length_mm > 0.0 && bearing_.clearance_um > 0.0 && bearing_.load_n >= 0.0 &&
        bearing_.viscosity_pa_s > 0.0)) {
    throw InputError("journal bearing: radius, length, clearance and viscosity must be > 0, the load >= 0");
  }
  for (int k = 0; k < curve_points; ++k) {
    // Points closer together towards high eccentricity, where the load grows fast.
    const double u = static_cast<double>(k) / (curve_points - 1);
    const double eps = kMaxEccentricity * (1.0 - (1.0 - u) * (1.0 - u));
    const auto s = solveReynolds(eps, bearing_.length_mm / bearing_.radius_mm, 48, 15);
    eccentricity_.push_back(eps);
    load_number_.push_back(s.load_number);
    friction_number_.push_back(s.friction_number);
  }
}

double BearingFriction::viscosityPaS(double t_c) const {
  return bearing_.viscosity_pa_s * std::exp(-bearing_.viscosity_per_k * (t_c - bearing_.viscosity_reference_c));
}

BearingFriction::OperatingPoint BearingFriction::at(double speed_rpm, double t_c) const {
  OperatingPoint op;
  op.viscosity_pa_s = viscosityPaS(t_c);
  const double omega = std::abs(speed_rpm) * 2.0 * kPi / 60.0;
  if (omega == 0.0) return op;
  const double r = bearing_.radius_mm * 1e-3, c = bearing_.clearance_um * 1e-6;
  const double scale = op.viscosity_pa_s * omega * std::pow(r, 4);
  const double needed = bearing_.load_n * c * c / scale;  // load number the film must carry
  std::size_t k = 1;
  while (k + 1 < load_number_.size() && load_number_[k] < needed) ++k;
  const double w = std::clamp((needed - load_number_[k - 1]) / (load_number_[k] - load_number_[k - 1]), 0.0, 1.0);
  op.eccentricity = eccentricity_[k - 1] + w * (eccentricity_[k] - eccentricity_[k - 1]);
  const double friction = friction_number_[k - 1] + w * (friction_number_[k] - friction_number_[k - 1]);
  op.friction_power_w = scale / c * friction * omega;
  return op;
}

SpindleThermalModel SpindleThermalModel::headstock() {
  SpindleThermalModel m;
  m.front = JournalBearing{25.0, 25.0, 50.0, 500.0, 0.0275, 40.0, 0.03};
  m.rear = JournalBearing{25.0, 25.0, 50.0, 300.0, 0.0275, 40.0, 0.03};
  m.nodes = {{"front bearing", 1500.0, 0.0},
             {"rear bearing", 1200.0, 0.0},
             {"spindle", 8000.0, 2.0},
             {"headstock", 90000.0, 10.0},
             {"column", 900000.0, 35.0}};
  m.links = {{0, 2, 4.0}, {0, 3, 8.0}, {1, 2, 3.0}, {1, 3, 6.0}, {2, 3, 5.0}, {3, 4, 6.0}};
  m.drift_um_per_k.resize(3, 5);
  // X: the headstock's and the column's asymmetry; Y: the column bending as the headstock side
  // warms before its back; Z: the spindle growing towards the table (300 mm, 11.5 um/m/K), the
  // headstock below its mount, the column lifting the head (800 mm).
  m.drift_um_per_k << 0.0, 0.0, 0.0, 0.3, -0.3,  //
      0.0, 0.0, 0.0, 2.0, -1.2,                  //
      -0.5, 0.0, -3.45, -2.3, 9.2;
  auto site = [](const char* name, std::vector<double> w, double ambient) {
    return ThermalSensorSite{name, std::move(w), ambient};
  };
  m.sensors = {site("front_bearing", {0.7, 0, 0, 0.3, 0}, 0.0),
               site("rear_bearing", {0, 0.7, 0, 0.3, 0}, 0.0),
               site("spindle_nose", {0.2, 0, 0.6, 0, 0}, 0.2),
               site("headstock_front", {0.2, 0, 0, 0.8, 0}, 0.0),
               site("headstock_rear", {0, 0.2, 0, 0.8, 0}, 0.0),
               site("column_front", {0, 0, 0, 0.2, 0.8}, 0.0),
               site("column_rear", {0, 0, 0, 0, 0.9}, 0.1),
               site("ambient", {0, 0, 0, 0, 0}, 1.0),
               site("front_bearing_2", {0.65, 0, 0, 0.35, 0}, 0.0),
               site("rear_bearing_2", {0, 0.65, 0, 0.35, 0}, 0.0),
               site("headstock_top", {0, 0, 0, 0.7, 0}, 0.3),
               site("headstock_side", {0, 0, 0.1, 0.9, 0}, 0.0),
               site("column_mid", {0, 0, 0, 0, 1.0}, 0.0),
               site("column_base", {0, 0, 0, 0, 0.6}, 0.4),
               site("bed", {0, 0, 0, 0, 0.3}, 0.7),
               site("coolant_tank", {0, 0, 0, 0.5, 0}, 0.5)};
  return m;
}

ThermalNetwork::ThermalNetwork(SpindleThermalModel model, double initial_c, double dt_s)
    : model_(std::move(model)), front_(model_.front), rear_(model_.rear), dt_s_(dt_s) {
  const auto n = static_cast<Eigen::Index>(model_.nodes.size());
  if (n < 2 || !(dt_s > 0.0) || model_.drift_um_per_k.rows() != 3 || model_.drift_um_per_k.cols() != n) {
    throw InputError("thermal network: needs the two bearing nodes, a drift row per axis and column per node, dt > 0");
  }
  capacity_.resize(n);
  to_ambient_.resize(n);
  Eigen::MatrixXd g = Eigen::MatrixXd::Zero(n, n);
  for (Eigen::Index i = 0; i < n; ++i) {
    const auto& node = model_.nodes[static_cast<std::size_t>(i)];
    if (!(node.capacity_j_per_k > 0.0) || node.to_ambient_w_per_k < 0.0) {
      throw InputError("thermal network: node '" + node.name +
                       "' needs a capacity > 0 and a conductance to ambient >= 0");
    }
    capacity_(i) = node.capacity_j_per_k;
    to_ambient_(i) = node.to_ambient_w_per_k;
    g(i, i) += node.to_ambient_w_per_k;
  }
  for (const auto& l : model_.links) {
    if (l.a < 0 || l.b < 0 || l.a >= n || l.b >= n || l.a == l.b)
      throw InputError("thermal network: a link joins no two nodes");
    g(l.a, l.a) += l.conductance_w_per_k;
    g(l.b, l.b) += l.conductance_w_per_k;
    g(l.a, l.b) -= l.conductance_w_per_k;
    g(l.b, l.a) -= l.conductance_w_per_k;
  }
  for (const auto& s : model_.sensors) {
    if (static_cast<Eigen::Index>(s.node_weights.size()) != n)
      throw InputError("thermal network: sensor '" + s.name + "' needs a weight per node");
  }
  lu_.compute(Eigen::MatrixXd(capacity_.asDiagonal()) / dt_s_ + g);
  t_ = Eigen::VectorXd::Constant(n, initial_c);
}

void ThermalNetwork::step(double speed_rpm, double ambient_c) {
  // Heat from the films at the bearings' present temperature (explicit in the viscosity).
  const double front = front_.at(speed_rpm, t_(0)).friction_power_w, rear = rear_.at(speed_rpm, t_(1)).friction_power_w;
  last_power_w_ = {front, rear};
  Eigen::VectorXd b = capacity_.cwiseProduct(t_) / dt_s_ + to_ambient_ * ambient_c;
  b(0) += front;
  b(1) += rear;
  t_ = lu_.solve(b);
}

Eigen::Vector3d ThermalNetwork::driftUm(const Eigen::VectorXd& t) const {
  return model_.drift_um_per_k * (t.array() - model_.reference_c).matrix();
}

Eigen::VectorXd ThermalNetwork::sensorsC(const Eigen::VectorXd& t, double ambient_c) const {
  Eigen::VectorXd out(static_cast<Eigen::Index>(model_.sensors.size()));
  for (std::size_t s = 0; s < model_.sensors.size(); ++s) {
    const auto& site = model_.sensors[s];
    out(static_cast<Eigen::Index>(s)) =
        Eigen::Map<const Eigen::VectorXd>(site.node_weights.data(), t.size()).dot(t) + site.ambient_weight * ambient_c;
  }
  return out;
}

}  // namespace mtcal::processing
