#pragma once
// Point accuracy of a gantry drilling machine with a laser tracker (patent CN106017326;
// docs/gantry.md): the plan (JSON), its holes and NC program. The run is in gantry_run.h,
// the stored run's measurements and the exported measurement file (`mtcal gantry evaluate`)
// in gantry_measurements.h.

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <nlohmann/json_fwd.hpp>
#include <string>
#include <vector>

#include "mtcal/processing/gantry_accuracy.h"
#include "mtcal/processing/multibody.h"

namespace mtcal::acquisition {

/// A programmed hole: machine coordinates (x, y, z mm; c, a deg), the tool point they put in
/// the machine's frame and the tool vector there (ideal kinematics).
struct PlannedHole {
  std::string id;
  int gantry_position = 1;
  double x_mm = 0, y_mm = 0, z_mm = 0, c_deg = 0, a_deg = 0;
  Eigen::Vector3d np_mm = Eigen::Vector3d::Zero();
  Eigen::Vector3d tool_vector = Eigen::Vector3d::UnitZ();
};

struct GantryPlan {
  std::string name = "gantry point accuracy";
  std::string device = "mock://tracker";
  std::string reflector = "RRR1.5";  ///< RRR1.5 (19.05 mm), RRR0.875, RRR0.5
  int integration_ms = 500;          ///< stationary measurements
  // Global frame.
  std::vector<std::string> corners{"A", "B", "C", "D"};
  std::string origin_corner = "A";
  int points_per_face = 5;
  double gantry_from_mm = 0.0, gantry_to_mm = 4000.0;  ///< the tracked pass of the gantry (X)
  int passes = 2;                                      ///< back and forth
  std::uint32_t track_rate_hz = 100;
  double track_feed_mm_per_min = 3000.0;  ///< the gantry's feed during the tracked passes
  // Initial state (A = C = 0) and rotary axes.
  std::array<double, 3> initial_mm{0.0, 1500.0, 0.0};
  std::string sweep_target = "TB1";
  std::vector<double> c_sweep_deg, a_sweep_deg;  ///< defaults: C 0..330 step 30, A -40..40 step 10
  std::vector<std::string> targets{"TB1", "TB2", "TB3"};
  bool measure_tool_point = true;  ///< a nest at the tool point ("TCP"), beyond the patent
  double tool_length_mm = 300.0;   ///< L_sp: wrist centre to tool point
  // Holes: a grid of tool points at each gantry position, tool orientations cycled.
  std::vector<double> gantry_positions_mm{500.0, 1250.0, 2000.0, 2750.0, 3500.0};
  std::array<double, 3> hole_y_mm{300.0, 400.0, 7};   ///< start, step, count (Y of the tool point)
  std::array<double, 3> hole_z_mm{-500.0, -50.0, 5};  ///< start, step, count (Z of the tool point)
  std::vector<std::array<double, 2>> orientations_deg{{0, 0}, {15, 0}, {-15, 90}, {20, 45}, {-20, 180}};  ///< [a, c]
  double settle_s = 2.0;  ///< after a move before measuring
  // Uncertainty.
  processing::TrackerMpe mpe;
  int monte_carlo_trials = 200;

  /// Reads and validates a plan. @throws InputError "SOURCE: key 'k': why"
  static GantryPlan fromJson(const nlohmann::json& j, const std::string& source);
  nlohmann::json toJson() const;
  double reflectorRadiusMm() const;
  /// Where the run puts the reflector, in the run's order, each once: the corners' faces
  /// ("A.top"; side faces at the origin corner only), the sweep target, "TCP", the targets.
  std::vector<std::string> reflectorPlaces() const;
  /// The place of a corner's face: "A" and "top" give "A.top".
  static std::string cornerFace(const std::string& corner, const std::string& face);
  /// The faces measured at a corner: the top, and the sides at the origin corner.
  std::vector<std::string> facesAt(const std::string& corner) const;
};

/// A tracker's MPE from JSON {distance_um, distance_um_per_m, transverse_um,
/// transverse_um_per_m} (missing keys keep the defaults). @throws InputError "SOURCE: key 'k': why"
processing::TrackerMpe trackerMpeFromJson(const nlohmann::json& j, const std::string& source, const std::string& key);

/// The holes of the plan on a machine (its ideal kinematics: coordinates x, y, z, c, a).
/// @throws InputError when the kinematics lack those coordinates
std::vector<PlannedHole> planHoles(const GantryPlan& plan, const processing::MultibodyModel& kinematics);
/// The programmed tool point of the initial state.
Eigen::Vector3d initialToolPoint(const GantryPlan& plan, const processing::MultibodyModel& kinematics);

/// The NC program: every hole at each gantry position, positioning in machine coordinates
/// (X Y Z A C, as the patent's post-processor writes them), a dwell for the measurement.
std::string gantryGcode(const GantryPlan& plan, const std::vector<PlannedHole>& holes);

}  // namespace mtcal::acquisition
