#pragma once
// Volumetric compensation as a controller with a kinematic model holds it (ISG's TwinCAT CNC,
// TF5280): the ISO 230-1 component errors of every axis sampled along it and the position
// errors (constants); the controller evaluates them at the axes' positions (interpolated
// between rows), computes the tool point's error through the machine's kinematics and moves
// the axes against it. Text in, text out: no file I/O here. Format and sources:
// docs/compensation.md#volumetric-compensation-isg-csv.

#include <Eigen/Core>
#include <array>
#include <map>
#include <string>
#include <string_view>
#include <vector>

#include "mtcal/processing/error_model.h"
#include "mtcal/processing/multibody.h"

namespace mtcal::processing {

/// Units inside: um and urad, positions mm (rotary axes deg); names as the kinematics' terms
/// (EXX, EBX, EC0Y). The file is in mm and rad.
struct VolumetricTable {
  /// One axis' component errors at its rows.
  struct AxisBlock {
    std::string coordinate;                             ///< "x", "y", "z", "c", ...
    std::vector<double> position;                       ///< mm (deg), increasing
    std::map<std::string, std::vector<double>> values;  ///< term -> value per row
  };
  std::vector<AxisBlock> axes;
  std::map<std::string, double> constants;  ///< position errors (EC0Y, ...)

  /// Every term of `kinematics` at q: motion errors interpolated linearly between the rows of
  /// their axis and held beyond its ends, constants as they are, zero for a term not listed.
  Eigen::VectorXd errorsAt(const MultibodyModel& kinematics, const Eigen::VectorXd& q) const;
  std::size_t records() const;  ///< data rows in the file (the controller's max_records)
};

/// The model's errors of every axis at `interval` (mm, deg for rotary axes) over the range each
/// was measured over (the last row at the range's end), and its constants.
/// @throws InputError for an interval that is not positive
VolumetricTable sampleVolumetric(const ErrorModel& model, double interval);

/// Axis commands (um on the positioning error terms `positioning_terms` of the x, y and z
/// axes, indices into kinematics.terms()) that cancel the table's error of the tool point at
/// q, to first order: what the controller adds to them.
std::array<double, 3> volumetricCorrectionUm(const MultibodyModel& kinematics, const VolumetricTable& table,
                                             const Eigen::VectorXd& q, const std::array<int, 3>& positioning_terms);

/// ISG's CSV: a header block per axis ("X EXX EYX ... " then rows), '#' before each next
/// block, the position errors in a block of one row; "//" comments; mm and rad.
std::string writeIsgVolumetricCsv(const VolumetricTable& table, const std::string& comment);
/// Reads it the way the controller does, refusing what it refuses (an unknown name, a name
/// twice, a row of the wrong length) and what mtcal's reader cannot take (a block with two
/// arguments). @throws InputError "source: line N: why"
VolumetricTable readIsgVolumetricCsv(std::string_view text, const std::string& source);
/// The controller's configuration lines for the file (axis numbers, records, file and format).
std::string isgVolumetricSetup(const VolumetricTable& table, const std::string& file_name);

}  // namespace mtcal::processing
