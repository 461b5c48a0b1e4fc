#include "mtcal/mocks/machine_thermal.h"

#include <cmath>
#include <nlohmann/json.hpp>
#include <numbers>

#include "mtcal/error.h"

namespace mtcal::mocks {

MachineThermalConfig MachineThermalConfig::fromJson(const nlohmann::json& j, const std::string& source) {
  MachineThermalConfig c;
  if (!j.is_object()) throw InputError(source + ": thermal: must be an object");
  auto number = [&](const char* key, double fallback) {
    if (!j.contains(key)) return fallback;
    if (!j[key].is_number()) throw InputError(source + ": thermal." + key + ": must be a number");
    return j[key].get<double>();
  };
  for (const auto& [key, value] : j.items()) {
    if (key != "ambient_c" && key != "ambient_swing_k" && key != "ambient_period_h" && key != "ambient_phase_deg" &&
        key != "front_load_n" && key != "rear_load_n" && key != "clearance_um") {
      throw InputError(
          source + ": thermal." + key +
          ": unknown key (expected ambient_c, ambient_swing_k, ambient_period_h, ambient_phase_deg, front_load_n, "
          "rear_load_n, clearance_um)");
    }
  }
  c.ambient_c = number("ambient_c", c.ambient_c);
  c.ambient_swing_k = number("ambient_swing_k", c.ambient_swing_k);
  c.ambient_period_s = number("ambient_period_h", c.ambient_period_s / 3600.0) * 3600.0;
  c.ambient_phase_rad = number("ambient_phase_deg", 0.0) * std::numbers::pi / 180.0;
  c.model.front.load_n = number("front_load_n", c.model.front.load_n);
  c.model.rear.load_n = number("rear_load_n", c.model.rear.load_n);
  c.model.front.clearance_um = c.model.rear.clearance_um = number("clearance_um", c.model.front.clearance_um);
  if (c.ambient_c < -20.0 || c.ambient_c > 50.0) throw InputError(source + ": thermal.ambient_c: outside -20..50 degC");
  if (c.ambient_swing_k < 0.0 || !(c.ambient_period_s > 0.0)) {
    throw InputError(source + ": thermal: ambient_swing_k must be >= 0 and ambient_period_h > 0");
  }
  if (!(c.model.front.clearance_um > 0.0) || c.model.front.load_n < 0.0 || c.model.rear.load_n < 0.0) {
    throw InputError(source + ": thermal: clearance_um must be > 0, the loads >= 0");
  }
  return c;
}

MachineThermal::MachineThermal(MachineThermalConfig config)
    : config_(std::move(config)), network_(config_.model, config_.ambient_c, config_.step_s) {
  history_.push_back(network_.temperatures());
}

double MachineThermal::ambientAt(double since_start_s) const {
  return config_.ambient_c +
         config_.ambient_swing_k *
             std::sin(2.0 * std::numbers::pi * since_start_s / config_.ambient_period_s + config_.ambient_phase_rad);
}

double MachineThermal::speedAt(double since_start_s) const {
  double end = 0.0;
  for (const auto& p : phases_) {
    end += p.duration_s;
    if (since_start_s < end) return p.speed_rpm;
  }
  return 0.0;
}

void MachineThermal::startProgram(std::vector<SpindlePhase> phases, double start_s) {
  std::lock_guard lock(mutex_);
  phases_ = std::move(phases);
  start_s_ = std::round(start_s / config_.step_s) * config_.step_s;
  network_.setTemperatures(
      Eigen::VectorXd::Constant(static_cast<Eigen::Index>(config_.model.nodes.size()), ambientAt(0.0)));
  history_.assign(1, network_.temperatures());
}

double MachineThermal::programStartS() const {
  std::lock_guard lock(mutex_);
  return start_s_;
}

void MachineThermal::integrateTo(std::size_t k) const {
  while (history_.size() <= k) {
    const double since = static_cast<double>(history_.size() - 1) * config_.step_s;
    network_.step(speedAt(since), ambientAt(since + config_.step_s));
    history_.push_back(network_.temperatures());
  }
}

Eigen::VectorXd MachineThermal::nodesAt(double since_start_s) const {
  const double steps = since_start_s / config_.step_s;
  const auto k = static_cast<std::size_t>(std::floor(steps));
  integrateTo(k + 1);
  const double w = steps - static_cast<double>(k);
  return (1.0 - w) * history_[k] + w * history_[k + 1];
}

ThermalState MachineThermal::at(double t_s) const {
  std::lock_guard lock(mutex_);
  ThermalState s;
  const double since = std::max(0.0, t_s - start_s_);
  s.nodes_c = nodesAt(since);
  s.ambient_c = ambientAt(since);
  s.speed_rpm = speedAt(since);
  s.drift_um = network_.driftUm(s.nodes_c);
  s.sensors_c = network_.sensorsC(s.nodes_c, s.ambient_c);
  return s;
}

// Asked for every point the instruments see: the drift alone, without the sensor sites.
Eigen::Vector3d MachineThermal::driftUm(double t_s) const {
  std::lock_guard lock(mutex_);
  return network_.driftUm(nodesAt(std::max(0.0, t_s - start_s_)));
}

}  // namespace mtcal::mocks
