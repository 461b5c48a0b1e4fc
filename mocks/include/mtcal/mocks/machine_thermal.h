#pragma once
// The thermal state of the virtual machine: the spindle's bearings heat the
// headstock through their oil films (processing::ThermalNetwork: Reynolds friction power,
// lumped heat transfer), the shop's air swings around its mean, and the tool point drifts
// with the structure's temperatures. Integrated in steps of world time on demand, keyed to
// the start of the spindle program, so the same program and seed give the same temperatures
// and drift whatever the wall clock did.
//
// Before a program starts the machine stands in equilibrium with the shop. Starting one
// begins from that equilibrium (a thermal test starts on a machine that stood still, as
// ISO 230-3 asks), the air's swing counted from the program's start.
//
// Thread-safety: all methods lock.

#include <Eigen/Core>
#include <mutex>
#include <nlohmann/json_fwd.hpp>
#include <utility>
#include <vector>

#include "mtcal/processing/spindle_thermal.h"

namespace mtcal::mocks {

struct MachineThermalConfig {
  processing::SpindleThermalModel model = processing::SpindleThermalModel::headstock();
  double ambient_c = 20.0;       ///< the shop's mean air temperature
  double ambient_swing_k = 0.0;  ///< amplitude of its daily swing
  double ambient_period_s = 86400.0;
  double ambient_phase_rad = 0.0;  ///< at the program's start
  double step_s = 1.0;             ///< integration step of world time
  /// Reads the machine file's "thermal" object. @throws InputError naming key and why
  static MachineThermalConfig fromJson(const nlohmann::json& j, const std::string& source);
};

/// A spindle program: phases of constant speed.
struct SpindlePhase {
  double duration_s = 0.0;
  double speed_rpm = 0.0;
};

struct ThermalState {
  Eigen::VectorXd nodes_c;  ///< the network's node temperatures
  double ambient_c = 20.0;
  double speed_rpm = 0.0;
  Eigen::Vector3d drift_um = Eigen::Vector3d::Zero();  ///< tool relative to the table, X Y Z
  Eigen::VectorXd sensors_c;                           ///< every sensor site, noise-free
};

class MachineThermal {
 public:
  explicit MachineThermal(MachineThermalConfig config);
  /// Starts a spindle program at world time `start_s` (rounded to the integration step) on
  /// a machine in equilibrium with the shop; the spindle stops after the last phase.
  void startProgram(std::vector<SpindlePhase> phases, double start_s);
  /// The state at world time t (linear between steps).
  ThermalState at(double t_s) const;
  Eigen::Vector3d driftUm(double t_s) const;
  const MachineThermalConfig& config() const { return config_; }
  /// World time at which the current program started (0: none).
  double programStartS() const;

 private:
  double ambientAt(double since_start_s) const;
  double speedAt(double since_start_s) const;
  /// Steps the history up to step k (lock held).
  void integrateTo(std::size_t k) const;
  /// Node temperatures at a time since the program's start, linear between steps (lock held).
  Eigen::VectorXd nodesAt(double since_start_s) const;

  MachineThermalConfig config_;
  mutable std::mutex mutex_;
  std::vector<SpindlePhase> phases_;
  double start_s_ = 0.0;
  mutable processing::ThermalNetwork network_;
  mutable std::vector<Eigen::VectorXd> history_;  ///< node temperatures at start + k * step
};

}  // namespace mtcal::mocks
