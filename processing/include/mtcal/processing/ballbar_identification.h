#pragma once
// Identification of one axis' six motion errors from ballbar length changes at several ball
// positions (Fan Jinwei et al., the MKS8332A camshaft grinder): for the C axis a ball on the
// work head at six places and one at the tailstock (eight places when the tailstock ball's
// eccentricity m, n is unknown too), for the X axis six places on the wheel slide and one ball
// on the bed. The bar's length comes from the machine's multi-body model: each pair's
// distance between a point on the tool side and a point on the workpiece side, with the
// axis' errors at its coordinate, so the method works for any kinematics in the model's JSON.
//
// The first position is the reference: the bar is zeroed there and the axis' errors are zero
// there (the convention of docs/multibody-model.md).
//
// Two things the paper's layouts do not give, found here and stated in docs/grinding.md:
// with one tailstock ball on the C axis a tilt of the head reads as a translation (the
// length change of a ball at (x, y, z) is (x dx + y dy + (z - z1) dz + z1 (x beta - y alpha)) / L),
// so six placements give three combinations, not six errors: the tailstock end must sit at
// two heights. Likewise a rotation of the X slide about any axis through the bed ball changes
// no length: the bed ball must sit at three places not on one line. And the eccentricity
// m, n cannot be identified with the motion errors. Errors the layout cannot see (about the
// C axis a rotation leaves every length unchanged when the tailstock ball is on the axis)
// are reported as not determined, never guessed.
//
// Units: coordinates mm or deg, lengths mm, length changes and errors um / urad.

#include <Eigen/Core>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "mtcal/processing/multibody.h"

namespace mtcal::processing {

/// One ball pair: the ball on the tool side (tool frame, mm) and the one on the workpiece
/// side (workpiece frame, mm).
struct BallPair {
  Eigen::Vector3d tool_ball_mm = Eigen::Vector3d::Zero();
  Eigen::Vector3d work_ball_mm = Eigen::Vector3d::Zero();
};

struct BallbarSetup {
  std::string coordinate;       ///< the axis moved: "c", "x", ...
  std::vector<BallPair> pairs;  ///< one per ball placement
  /// The tool-side ball's offset in its x, y (the tailstock's eccentricity m, n) is unknown:
  /// two more unknowns, common to every position.
  bool unknown_tool_ball_offset = false;
  double max_condition_number = 1e4;
};

/// The bar length changes (um) of every pair at one axis position, from the first position.
struct BallbarReadings {
  double coordinate = 0.0;
  std::vector<double> delta_length_um;
};

struct BallbarIdentification {
  std::vector<std::string> terms;                      ///< identified: dx, dy, dz, rx, ry, rz order
  std::vector<std::string> not_determined;             ///< motion errors of the axis the layout cannot see
  std::vector<double> coordinate;                      ///< positions, the reference first
  Eigen::MatrixXd values;                              ///< positions x terms (um / urad; 0 at the reference)
  std::optional<Eigen::Vector2d> tool_ball_offset_um;  ///< m, n when asked for
  double rms_residual_um = 0.0;                        ///< of the length changes after the fit
  double condition_number = 0.0;                       ///< of one position's block (columns scaled)
};

/// The bar lengths (mm) of every pair at coordinate `value` with the given error values (one
/// per model term) and tool-ball offset (um, x and y). Other coordinates are held at 0.
std::vector<double> ballbarLengthsMm(const MultibodyModel& model, const BallbarSetup& setup, double value,
                                     const Eigen::VectorXd& errors, const Eigen::Vector2d& tool_ball_offset_um);

/// @throws InputError (unknown coordinate, fewer than two positions, a reading with the wrong
/// number of pairs, fewer pairs than unknowns per position; an unknown tool-ball offset the
/// layout cannot separate from the axis' translations, which is the case for any fixed
/// tailstock eccentricity: it reads as the C axis' EXC, EYC at every angle)
BallbarIdentification identifyFromBallbar(const MultibodyModel& model, const BallbarSetup& setup,
                                          const std::vector<BallbarReadings>& readings);

/// The C-X linkage test: the head turns while the slide moves so that the bar's ideal length
/// stays that of the start (one pass per ball placement). The lengths then see what the
/// single-axis tests could not: the head's angular positioning (per angle, `per_angle`, e.g.
/// ECC) and the C axis' tilts to X (static, `tied` groups share one value, as the paper takes
/// the tilts in XZ and YZ as equal). The other errors are known (the single-axis tests).
struct LinkagePass {
  BallPair pair;                        ///< ball on the slide (tool frame), ball on the head (workpiece frame)
  std::vector<double> delta_length_um;  ///< at every angle of the grid, the first 0
};
struct LinkageSetup {
  std::string rotary = "c", linear = "x";
  std::vector<double> angles_deg;              ///< the grid, the first the reference
  std::vector<std::string> per_angle;          ///< e.g. {"ECC"}
  std::vector<std::vector<std::string>> tied;  ///< e.g. {{"EA0C", "EB0C"}}
  double max_condition_number = 1e4;
};
struct LinkageIdentification {
  Eigen::MatrixXd per_angle;        ///< angles x per_angle terms (0 at the reference)
  std::vector<double> tied_values;  ///< one per group
  double rms_residual_um = 0.0, condition_number = 0.0;
};

/// The slide position (mm) at which the ideal bar length of `pair` is `length_mm` with the
/// head at `angle_deg`, by Newton from `start_mm`. @throws InputError when none is found
double linkedPositionMm(const MultibodyModel& model, const LinkageSetup& setup, const BallPair& pair, double angle_deg,
                        double length_mm, double start_mm);
/// The coordinates of every pass at every angle (the slide linked to the head).
std::vector<std::vector<Eigen::VectorXd>> linkagePath(const MultibodyModel& model, const LinkageSetup& setup,
                                                      const std::vector<BallPair>& pairs, double start_mm);

/// @throws InputError (unknown names, lengths of the wrong count, a layout that cannot
/// separate the unknowns: condition number over the limit)
LinkageIdentification identifyLinkage(const MultibodyModel& model, const LinkageSetup& setup,
                                      const std::vector<LinkagePass>& passes, double start_mm,
                                      const std::function<Eigen::VectorXd(const Eigen::VectorXd&)>& known_errors);

}  // namespace mtcal::processing
