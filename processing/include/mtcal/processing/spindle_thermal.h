#pragma once
// Thermal behaviour of a spindle with hydrodynamic journal bearings (seed 002):
// the oil film's pressure by the Reynolds equation solved with finite differences, the
// bearing's friction power as a function of speed and viscosity (temperature), and a lumped
// heat-transfer network (bearings, spindle, headstock, column, ambient) whose temperatures
// give the sensors' readings and the tool point's thermal drift. Pure numerics; the virtual
// machine (mocks) integrates it over its world time.
//
// Reynolds equation of a finite plain journal bearing, dimensionless (theta around the
// bearing from the widest gap... h = c (1 + eps cos theta), zeta = z / R along it):
//   d/dtheta (H^3 dP/dtheta) + d/dzeta (H^3 dP/dzeta) = 6 dH/dtheta,   H = 1 + eps cos theta
// with P = p c^2 / (mu omega R^2), P = 0 at both ends, periodic in theta, and the Reynolds
// (Swift-Stieber) cavitation condition P >= 0 (projected successive over-relaxation).
// Load W = mu omega R^4 / c^2 * |int int P (cos, sin) dtheta dzeta|; friction torque on the
// journal M = mu omega R^4 / c * int int (1/H + H/2 dP/dtheta) dtheta dzeta (Couette plus
// Poiseuille shear, the full film assumed in the cavitated zone); power M omega.

#include <Eigen/Core>
#include <Eigen/LU>
#include <string>
#include <vector>

namespace mtcal::processing {

struct ReynoldsSolution {
  double load_number = 0.0;      ///< W c^2 / (mu omega R^4)
  double attitude_rad = 0.0;     ///< between the line of centres and the load
  double friction_number = 0.0;  ///< M c / (mu omega R^4)
  int iterations = 0;
  Eigen::MatrixXd pressure;  ///< P at (theta_i, zeta_j), n_theta x n_axial (ends included)
};

/// Solves the dimensionless Reynolds equation for an eccentricity ratio 0 <= eps < 1 and
/// L / R. @throws InputError out of range, or when the iteration does not converge
ReynoldsSolution solveReynolds(double eccentricity, double length_over_radius, int n_theta = 72, int n_axial = 21);

struct JournalBearing {
  double radius_mm = 30.0, length_mm = 30.0;
  double clearance_um = 40.0;      ///< radial
  double load_n = 600.0;           ///< radial load carried
  double viscosity_pa_s = 0.0275;  ///< at viscosity_reference_c (ISO VG 32 near 40 degC)
  double viscosity_reference_c = 40.0;
  double viscosity_per_k = 0.03;  ///< Reynolds' law mu = mu_ref exp(-beta (T - T_ref))
};

/// A bearing's friction power from its load curve, computed once by solveReynolds.
class BearingFriction {
 public:
  /// @throws InputError for non-positive dimensions
  explicit BearingFriction(JournalBearing bearing, int curve_points = 28);
  double viscosityPaS(double film_temperature_c) const;
  struct OperatingPoint {
    double eccentricity = 0.0;
    double viscosity_pa_s = 0.0;
    double friction_power_w = 0.0;
  };
  /// The film at `film_temperature_c` carrying the load at `speed_rpm` (0: no power).
  OperatingPoint at(double speed_rpm, double film_temperature_c) const;
  const JournalBearing& bearing() const { return bearing_; }

 private:
  JournalBearing bearing_;
  std::vector<double> eccentricity_, load_number_, friction_number_;
};

/// A lumped heat-transfer network: node temperatures from C dT/dt = sum G (T_j - T_i) +
/// G_amb (T_amb - T_i) + heat, integrated by implicit Euler.
struct ThermalNode {
  std::string name;
  double capacity_j_per_k = 1.0;
  double to_ambient_w_per_k = 0.0;
};
struct ThermalLink {
  int a = 0, b = 0;
  double conductance_w_per_k = 0.0;
};
/// A temperature sensor: a weighted mean of node temperatures and the ambient (weights sum to 1).
struct ThermalSensorSite {
  std::string name;
  std::vector<double> node_weights;
  double ambient_weight = 0.0;
};

struct SpindleThermalModel {
  JournalBearing front, rear;
  std::vector<ThermalNode> nodes;  ///< nodes 0 and 1 receive the front and rear bearings' heat
  std::vector<ThermalLink> links;
  Eigen::MatrixXd drift_um_per_k;  ///< 3 x nodes: the tool point's X, Y, Z drift per K of each node
  std::vector<ThermalSensorSite> sensors;
  double reference_c = 20.0;  ///< drift is zero with every node here
  /// A grinder's headstock on a column: front and rear bearings, spindle, headstock, column;
  /// 16 sensor sites (the first 8 the usual layout, 9..16 next to them).
  static SpindleThermalModel headstock();
};

class ThermalNetwork {
 public:
  /// @throws InputError for an inconsistent model
  ThermalNetwork(SpindleThermalModel model, double initial_c, double dt_s);
  /// One step of dt at the spindle speed (rpm) and ambient temperature.
  void step(double speed_rpm, double ambient_c);
  const Eigen::VectorXd& temperatures() const { return t_; }
  void setTemperatures(const Eigen::VectorXd& t) { t_ = t; }
  /// Friction power (W) of the front and rear bearings in the last step.
  std::pair<double, double> lastPowerW() const { return last_power_w_; }
  const SpindleThermalModel& model() const { return model_; }
  /// The tool point's drift (um, X Y Z) at node temperatures t.
  Eigen::Vector3d driftUm(const Eigen::VectorXd& t) const;
  /// Every sensor site's temperature at node temperatures t and the ambient.
  Eigen::VectorXd sensorsC(const Eigen::VectorXd& t, double ambient_c) const;

 private:
  SpindleThermalModel model_;
  BearingFriction front_, rear_;
  double dt_s_;
  Eigen::VectorXd t_, capacity_, to_ambient_;
  Eigen::PartialPivLU<Eigen::MatrixXd> lu_;  ///< of C/dt + G
  std::pair<double, double> last_power_w_{0.0, 0.0};
};

}  // namespace mtcal::processing
