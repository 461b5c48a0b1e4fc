#pragma once
// Cam grinding with geometric error compensation (Fan Jinwei et al., the MKS8332A camshaft
// grinder): the cam profile as a point list -> a periodic cubic spline -> the wheel-centre
// path, offset by the wheel radius along the outward normal -> the NC commands (x, c) of the
// wheel slide and the work head that put the wheel centre on that path. The machine's
// multi-body model gives the precise-machining constraint P_W = P_T: the actual wheel centre,
// seen in the cam's frame with every error at the commanded (x, c), must be the path point.
// The ideal commands (no error) start an iteration that evaluates the errors at the last
// commands and solves the ideal constraint for the point they displace (x_i+1, c_i+1), until
// the remaining error is below the axes' resolution (X: the slide's step; tangential: x times
// C's step).
//
// Units: mm, degrees for C, um for errors. Pure numerics.

#include <Eigen/Core>
#include <functional>
#include <string>
#include <vector>

#include "mtcal/processing/multibody.h"

namespace mtcal::processing {

/// A closed curve through points by a periodic cubic spline, parameterised by chord length.
/// @throws InputError for fewer than 4 points or repeated neighbours
class PeriodicSpline2d {
 public:
  explicit PeriodicSpline2d(const std::vector<Eigen::Vector2d>& points);
  double period() const { return period_; }  ///< total chord length
  Eigen::Vector2d at(double s) const;
  Eigen::Vector2d derivative(double s) const;
  Eigen::Vector2d second(double s) const;
  /// Signed curvature at s (+: turning counter-clockwise).
  double curvature(double s) const;

 private:
  std::pair<std::size_t, double> locate(double s) const;
  std::vector<double> s_;           ///< knot parameters (n + 1, last = period)
  std::vector<Eigen::Vector2d> p_;  ///< knot points (n)
  std::vector<Eigen::Vector2d> m_;  ///< second derivatives at the knots (n)
  double period_ = 0.0;
};

/// A cam profile from a polar lift table: radius (mm) at angle (deg), angles increasing over
/// one turn. @throws InputError (fewer than 4 points, angles not increasing within 360 deg,
/// a radius <= 0)
std::vector<Eigen::Vector2d> polarProfile(const std::vector<double>& angle_deg, const std::vector<double>& radius_mm);

struct WheelPathPoint {
  Eigen::Vector2d profile_mm, normal, centre_mm;  ///< cam point, outward unit normal, wheel centre
  double s_mm = 0.0;                              ///< along the profile
};

/// The wheel-centre path: `samples` points evenly along the profile (counter-clockwise after
/// orientation), each offset by the wheel radius along the outward normal.
/// @throws InputError when the wheel is larger than a concave part of the cam can take
/// (naming where and the radius of curvature there)
std::vector<WheelPathPoint> wheelCentrePath(const std::vector<Eigen::Vector2d>& profile_mm, double wheel_radius_mm,
                                            int samples);

/// The axes' steps the iteration can settle to: a nanometre and 1e-7 deg at the finest (finer is
/// below what the double arithmetic of a 100 mm cam resolves), 100 um and 1 deg at the coarsest.
inline constexpr double kFinestStepXUm = 1e-3, kCoarsestStepXUm = 100.0;
inline constexpr double kFinestStepCDeg = 1e-7, kCoarsestStepCDeg = 1.0;

struct CompensationOptions {
  double resolution_x_um = 0.1;      ///< X slide's step, kFinestStepXUm..kCoarsestStepXUm
  double resolution_c_deg = 0.0001;  ///< C axis' step, kFinestStepCDeg..kCoarsestStepCDeg
  int max_iterations = 30;
};

struct GrindCommand {
  double x_ideal_mm = 0.0, c_ideal_deg = 0.0;  ///< no error: the start of the iteration
  double x_mm = 0.0, c_deg = 0.0;              ///< corrected
  int iterations = 0;
  double error_ideal_um = 0.0;  ///< in-plane wheel-centre error with the ideal commands
  double error_um = 0.0;        ///< in-plane error left with the corrected ones
  double error_z_um = 0.0;      ///< along the camshaft: two axes cannot correct it
};

/// Errors (one value per term of `kinematics`, um / urad) at machine coordinates q.
using ErrorsAt = std::function<Eigen::VectorXd(const Eigen::VectorXd&)>;

/// Corrected commands for every wheel-centre point (cam frame, mm) on a two-axis X + C
/// machine (coordinates "x" and "c"; others held at 0). C is unwrapped along the path.
/// @throws InputError when the kinematics lack x or c, or a point cannot be reached
std::vector<GrindCommand> compensateGrinding(const MultibodyModel& kinematics, const ErrorsAt& errors,
                                             const std::vector<Eigen::Vector2d>& wheel_centre_mm,
                                             const CompensationOptions& options);

/// The work head's speeds a program is written for (rpm): a cam grinder's turns at up to a few
/// hundred; beyond 1000 or below 0.01 a value is in other units or no speed.
inline constexpr double kSlowestWorkHeadRpm = 0.01, kFastestWorkHeadRpm = 1000.0;

/// The part program: G93 inverse-time G1 X C blocks, the work head at `c_rpm`.
/// @throws InputError when c_rpm is outside kSlowestWorkHeadRpm..kFastestWorkHeadRpm
std::string grindingGcode(const std::vector<GrindCommand>& commands, double c_rpm, const std::string& title);

}  // namespace mtcal::processing
