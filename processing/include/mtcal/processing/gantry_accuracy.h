#pragma once
// Point accuracy of a gantry drilling machine with an A/C swivel head measured with a laser
// tracker (patent CN106017326, seed 003; docs/gantry.md).
//
// Steps, as the patent gives them (all coordinates first in the tracker's frame, mm):
//  1. Global frame O-XYZ: one plane through the top faces of the bed's four corners -> XY
//     plane and Z (pointing to the machine); the two side faces of one corner meet the XY
//     plane in the origin O; a target on the gantry tracked while the gantry travels (one or
//     more passes, back and forth) -> a line -> X; Y = Z x X. The faces are measured with a
//     spherical reflector whose centre is one radius off the surface: the planes are moved
//     back by that radius (towards the bed).
//  2. C and A axes: one target tracked while C turns, then while A turns -> a circle each
//     (plane by SVD, geometric circle fit) -> axis lines; their common perpendicular meets
//     the C axis in the wrist centre T; TCP0 = T + L_sp along the C axis towards the tool.
//  3. Three targets TB1..TB3 on the A body: a frame on them (TB1 origin, X towards TB2, Z
//     normal to their plane) M0 in the initial state and M_i at each programmed hole;
//     T_i = M_i M0^-1, TCP_i = T_i TCP0; dP_i = TCP_i - NP_i, |dP_i| and the part
//     perpendicular to the tool axis |(I - V_i V_i^T) dP_i|.
// Beyond the patent: a tracked pass's outliers (a short integration's stray points) are left
// out of its line (distance beyond 5 times the median distance and 5 um, refitted once) and counted;
// with more than three targets (or on request) T_i is the least-squares
// rigid motion (Umeyama) and its residuals are reported; nearly collinear targets are
// warned about; a tool-point nest measured in the initial state gives TCP0 directly and the
// difference to the axes' construction is reported (it shows axis offsets the patent's
// construction assumes away); the uncertainty of every result from the tracker's MPE by
// Monte Carlo.
//
// The programmed holes NP_i are in the machine's coordinates; they are placed in the global
// frame with the initial state as datum: NP_i = TCP0 + (np_i - np_0), axes parallel (the
// patent builds the workpiece frame parallel to the machine's).

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "mtcal/processing/geometry3d.h"

namespace mtcal::processing {

/// A corner of the bed: its top face and (for the origin corner) its two side faces, as
/// reflector centres touching the faces.
struct BedCorner {
  std::string name;
  Points3d top, side_1, side_2;
};

/// One pass of the gantry: the tracked target's positions in time order and the direction
/// the gantry moved (+1: increasing X, -1: decreasing).
struct GantryPass {
  int direction = 1;
  Points3d points;
};

struct HoleMeasurement {
  std::string id;
  int gantry_position = 1;                                 ///< 1..n: which of the gantry's stations
  Eigen::Vector3d np_mm = Eigen::Vector3d::Zero();         ///< programmed tool point, machine coordinates
  Eigen::Vector3d tool_vector = Eigen::Vector3d::UnitZ();  ///< unit tool axis (tip towards the spindle)
  Points3d targets;                                        ///< TB1..TBn with the tool at the hole
};

/// Everything the tracker measured, in its own frame (mm), and what the machine was told.
struct GantryMeasurements {
  double reflector_radius_mm = 0.0;  ///< for the faces (0: points are on the surfaces)
  std::vector<BedCorner> corners;    ///< four with tops; the origin corner with sides
  std::string origin_corner;
  std::vector<GantryPass> gantry_passes;
  Points3d c_sweep, a_sweep;                                ///< one target while C, then A, turns (in order)
  double tool_length_mm = 0.0;                              ///< L_sp: wrist centre to tool point
  std::optional<Eigen::Vector3d> tool_point;                ///< a nest at the tool point, initial state
  Points3d initial_targets;                                 ///< TB1..TBn in the initial state
  Eigen::Vector3d initial_np_mm = Eigen::Vector3d::Zero();  ///< tool point programmed in the initial state
  std::vector<HoleMeasurement> holes;
};

/// Calls `f` with every measured point of a set (tracker frame, mm), in one fixed order: the
/// corners' faces, the passes, the sweeps, the tool point, the initial targets, the holes'.
template <typename F>
void forEachPoint(GantryMeasurements& m, F f) {
  const auto all = [&](Points3d& points) {
    for (auto& p : points) f(p);
  };
  for (auto& c : m.corners) {
    all(c.top);
    all(c.side_1);
    all(c.side_2);
  }
  for (auto& pass : m.gantry_passes) all(pass.points);
  all(m.c_sweep);
  all(m.a_sweep);
  if (m.tool_point) f(*m.tool_point);
  all(m.initial_targets);
  for (auto& h : m.holes) all(h.targets);
}

enum class TargetFit { kAuto, kPatentFrame, kLeastSquares };
enum class Tcp0Source { kAxes, kToolPoint };

struct GantryOptions {
  TargetFit target_fit = TargetFit::kAuto;  ///< auto: the patent's frame for 3 targets, least squares above
  Tcp0Source tcp0 = Tcp0Source::kAxes;
  double collinear_spread = 0.1;  ///< warn when the targets' planarSpread is below this
};

struct HoleResult {
  std::string id;
  int gantry_position = 1;
  Eigen::Vector3d np_mm = Eigen::Vector3d::Zero(), tcp_mm = Eigen::Vector3d::Zero();  ///< global frame
  Eigen::Vector3d dp_um = Eigen::Vector3d::Zero();
  double dp_norm_um = 0.0, dp_perp_um = 0.0;
  double fit_rms_um = 0.0;  ///< residual of the targets' rigid fit (0 for the patent's frame)
};

struct AccuracySummary {
  int gantry_position = 0;  ///< 0: all holes
  int holes = 0;
  Eigen::Vector3d mean_dp_um = Eigen::Vector3d::Zero();
  double mean_norm_um = 0.0, max_norm_um = 0.0, rms_norm_um = 0.0;
  double mean_perp_um = 0.0, max_perp_um = 0.0, rms_perp_um = 0.0;
  std::string worst_hole;  ///< largest |dP|
};

struct GantryEvaluation {
  /// Maps tracker coordinates to the global frame: p_global = global_from_tracker * p.
  Eigen::Isometry3d global_from_tracker = Eigen::Isometry3d::Identity();
  PlaneFit xy_plane;  ///< tops of the corners (tracker frame, reflector centres)
  double side_1_rms_um = 0.0, side_2_rms_um = 0.0;
  double gantry_line_rms_um = 0.0;         ///< largest over the passes
  double gantry_tilt_urad = 0.0;           ///< angle of the gantry's travel out of the XY plane
  double gantry_passes_spread_urad = 0.0;  ///< largest angle between a pass and their mean
  int gantry_outliers = 0;  ///< tracked points left out of the passes' lines (beyond 5x the median distance and 5 um)
  Circle3dFit c_axis, a_axis;         ///< global frame
  CommonPerpendicular axes;           ///< first foot on C, second on A
  double axes_squareness_urad = 0.0;  ///< angle between A and C minus 90 deg
  Eigen::Vector3d wrist_centre_mm = Eigen::Vector3d::Zero(), tcp0_mm = Eigen::Vector3d::Zero();
  std::optional<Eigen::Vector3d> tcp0_axes_minus_tool_point_um;  ///< when the tool point was measured
  std::string target_fit;                                        ///< "patent-frame" or "least-squares"
  std::vector<HoleResult> holes;
  std::vector<AccuracySummary> summaries;  ///< overall first, then per gantry position
  std::vector<std::string> notes;
};

/// @throws InputError naming the missing or degenerate measurement.
GantryEvaluation evaluateGantry(const GantryMeasurements& m, const GantryOptions& options = {});

/// A tracker's maximum permissible errors (ISO 10360-10 style, 95 %): a constant plus a part
/// proportional to the range, for the distance (along the beam) and for the angles
/// (transverse to the beam). Standard uncertainty = MPE / 2.
struct TrackerMpe {
  double distance_um = 10.0, distance_um_per_m = 0.4;
  double transverse_um = 15.0, transverse_um_per_m = 6.0;
};

/// The evaluation's uncertainty from the tracker's MPE by Monte Carlo: every measured point
/// moved by normal errors (distance along the line of sight from the tracker at the origin,
/// transverse across it) and the whole evaluation repeated.
struct HoleUncertainty {
  std::string id;
  Eigen::Vector3d dp_sigma_um = Eigen::Vector3d::Zero();  ///< standard deviation per component
  double norm_u95_um = 0.0, perp_u95_um = 0.0;            ///< half-width of the central 95 % interval
};
struct GantryUncertainty {
  int trials = 0;
  std::vector<HoleUncertainty> holes;
  Eigen::Vector3d tcp0_sigma_um = Eigen::Vector3d::Zero();
  double max_norm_u95_um = 0.0, max_perp_u95_um = 0.0;
};
GantryUncertainty monteCarloGantry(const GantryMeasurements& m, const GantryOptions& options, const TrackerMpe& mpe,
                                   int trials, std::uint64_t seed);

/// Summary statistics of hole results (all of them when gantry_position is 0).
AccuracySummary summarise(const std::vector<HoleResult>& holes, int gantry_position);

}  // namespace mtcal::processing
