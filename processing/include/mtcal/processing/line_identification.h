#pragma once
// Identification of the geometric errors from measured lines, through the multi-body model.
//
// A measured line is one instrument run: one axis moves over a node grid while the others
// stand at known positions, and an optic fixed to the tool at a known point reads one
// component of the tool's displacement (linear or straightness optics, um) or rotation
// (angular optics, urad) relative to the workpiece side. The model says how every error
// term enters that reading: the row of the reading's Jacobian. During a line only the
// moving axis' own motion errors vary, so per node the readings of all lines of one axis
// are a linear system in that axis' errors. Its solution is the identification:
//
// - direct method: each line names the error its optics measure; terms measured by several
//   lines at different lever arms are solved together (e.g. roll from two parallel
//   straightness lines), and angular terms that were measured correct the Abbe terms of
//   the translations. A term nobody measured is zero, and its Abbe share stays in the
//   translation measured off its reference point (the patent's convention).
// - 9-line method: three displacement lines along each axis at non-collinear offsets give
//   its positioning error and the two rotations with a lever arm along it; straightness
//   follows from the rotations under the rigid-body assumption (docs/multibody-model.md).
//
// Conventions (docs/conventions.md): motion errors are relative to their value at the first
// node of the grid; straightness errors have their least-squares line removed (ISO 230-1
// reference straight line); squareness errors come from the slopes of straightness lines
// that share one reference (an optical square), with the workpiece frame's own orientation
// as a free gauge. Pure numerics.

#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

#include "mtcal/processing/error_model.h"
#include "mtcal/processing/multibody.h"

namespace mtcal::processing {

struct MeasuredLine {
  std::string id;        ///< for messages, e.g. "run 12"
  std::string measures;  ///< ISO 230-1 name of the error its optics measure (EXX, EZX, EBX)
  int coordinate = 0;    ///< index in model.coordinates() of the moving axis
  Eigen::VectorXd q;     ///< every coordinate during the line (the moving one is ignored)
  Eigen::Vector3d point_mm = Eigen::Vector3d::Zero();  ///< measured point, tool frame (tool point + offset)
  int component = 0;                                   ///< 0..2 displacement along X, Y, Z; 3..5 rotation about X, Y, Z
  std::vector<double> position_mm;                     ///< node grid of the moving axis, ascending
  std::vector<double> mean;                            ///< reading per node (um or urad), any zero
  std::vector<std::optional<double>> s;
  std::vector<int> repeats;
};

enum class IdentificationMethod { kDirect, kNineLine };

/// How the lines of one axis were solved.
struct AxisSolution {
  std::string coordinate;
  std::vector<std::string> lines;  ///< ids
  std::vector<std::string> terms;  ///< identified jointly from these lines
  /// 2-norm condition number of the per-node system (rows: readings in um or urad; columns:
  /// um per um, um per urad). Large means a lever arm too short or lines collinear.
  double condition_number = 0.0;
  /// Standard deviation of each term per unit standard deviation of the readings.
  std::vector<double> noise_gain;
};

struct LineIdentification {
  std::vector<ErrorCurveData> curves;
  std::vector<AxisSolution> axes;
  std::vector<std::string> notes;  ///< assumptions applied and terms left out, for the record
};

struct LineIdentificationOptions {
  IdentificationMethod method = IdentificationMethod::kDirect;
  /// Refuse a layout whose condition number exceeds this.
  double max_condition_number = 1000.0;
};

/// @throws InputError naming the lines and why: unknown error names, lines of one axis on
///         different node grids, an error measured twice without a second lever arm, an
///         ill-posed 9-line layout (with its condition number).
LineIdentification identifyFromLines(const MultibodyModel& model, const std::vector<MeasuredLine>& lines,
                                     const LineIdentificationOptions& options);

/// A model against a measured line (the patent's validation: a second run samples other
/// points, e.g. random ones every ~3 mm, and the model built from the nodes predicts them).
/// The line's zero is free: `offset` is the mean of measured - predicted, removed from the
/// residuals. Nodes outside the range the model's functions of the moving axis were measured
/// over are not compared (a spline's end pieces extrapolate): counted in `outside`.
struct LineComparison {
  std::vector<double> position_mm, measured, predicted, residual;
  std::size_t outside = 0;
  std::vector<double> sigma;  ///< the model's standard deviation of the reading (first order)
  /// The model's own error of each prediction as it states it (ErrorModel::readingFitErrorFactor),
  /// a row per position; empty: not stated.
  Eigen::MatrixXd predicted_error_factor;
  double offset = 0.0;
  double rms = 0.0, peak = 0.0;  ///< of the residuals; peak is the largest |residual|
};

/// @throws InputError when the line does not fit the model's machine or no node is inside
LineComparison compareLine(const ErrorModel& model, const MeasuredLine& line);

/// The reading's row of one line at q: d(reading)/d(error) for every term (um or urad per
/// um or urad). Readings are what the optics see: tool displacement (P - P_ideal, the
/// negative of E) or tool rotation, relative to the workpiece.
Eigen::RowVectorXd readingRow(const MultibodyModel& model, const Eigen::VectorXd& q, const Eigen::Vector3d& point_mm,
                              int component);

}  // namespace mtcal::processing
