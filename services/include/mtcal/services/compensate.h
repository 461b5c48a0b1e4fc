#pragma once
// Compensation tables a controller loads, from a linear positioning run (ISO 230-2's mean
// deviations per direction) or from an identified model (any linear axis, with its
// extensions), in the controller's own file format (docs/compensation.md).

#include <array>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "mtcal/mocks/virtual_machine.h"
#include "mtcal/processing/compensation.h"
#include "mtcal/processing/compensation_formats.h"
#include "mtcal/processing/volumetric_compensation.h"
#include "mtcal/services/session.h"
#include "mtcal/services/workshop.h"

namespace mtcal::services {

/// The controllers a table is written for (processing::controllerNames()).
std::vector<std::string> compensationControllers();

struct CompensateRequest {
  std::string controller = "csv";  ///< processing::controllerNames()
  std::string axis;                ///< a run's own axis when empty; required for a model
  std::optional<int> axis_index;   ///< the controller's number of the axis (default: X 0, Y 1, Z 2)
  /// Start, end, interval (a model's default: 10 mm), reference point, bidirectional or mean,
  /// resolution (the controller's when 0), modulo. The controller's entry limit is added.
  processing::TableOptions table;
  /// A table the machine ran while it was measured, in the controller's format: the new table
  /// adds the measured (remaining) error to it. A run measured on a simulated machine with
  /// --compensation has its table stored: it is taken when this is empty.
  std::string existing_path;
  std::string at;         ///< a model's other coordinates ("x,y,z"; default: the workspace centre)
  std::string file_name;  ///< the name the table is saved under, for the configuration lines (-o's)
};

struct Compensation {
  std::string source;  ///< "run 3", "model 2"
  std::string axis, controller, controller_description;
  processing::CompensationTable table;  ///< as the controller reads the file written (its resolution, its zero)
  processing::ControllerFile file;
  std::vector<std::string> extensions_applied, extensions_left_out;  ///< a model's
  std::size_t outside = 0;            ///< a model's positions outside its measured range, left out
  std::string existing_path;          ///< or the table the run itself was measured with
  std::vector<std::string> warnings;  ///< e.g. --existing is not the table the run ran
  /// The table (position, correction per direction), the file's text and setup lines.
  nlohmann::json document() const;
};

/// @throws InputError for a run that is not a completed linear positioning run, an axis that
///         is not the run's, or a table the controller cannot take
Compensation compensateRun(Session& session, storage::Id run_id, const CompensateRequest& request);
/// @throws InputError for an axis the model does not have, or a table the controller cannot take
Compensation compensateModel(Session& session, storage::Id model_id, const CompensateRequest& request);

/// The controller name of the volumetric compensation (a model's, every axis in one file).
using processing::kIsgVolumetric;

struct VolumetricRequest {
  double interval = 10.0;    ///< row spacing, mm (deg for rotary axes)
  std::string file_name;     ///< the name the file is saved under, for the configuration lines (-o's)
  std::size_t points = 200;  ///< random points of the verification on a simulated machine (0: none)
  std::uint64_t seed = 1;    ///< of the random points
};

/// The simulated machine's tool point at random points of the model's measured volume (each
/// approached moving positive on every axis: a table without direction cannot take out the
/// lost motion of reversals), with and without the volumetric compensation: the error vector's length after a best-fit
/// rigid motion (the datum no line measurement fixes, docs/conventions.md; a tracker's alignment).
struct VolumetricVerification {
  std::size_t points = 0;
  std::uint64_t seed = 0;
  double before_rms_um = 0, before_max_um = 0;  ///< the machine without the table
  double after_rms_um = 0, after_max_um = 0;    ///< the machine running the table
  /// What the model leaves: the machine's error minus the model's prediction at the same
  /// points (the residual the model's validation predicts), the same fit removed.
  double expected_rms_um = 0, expected_max_um = 0;
};

struct VolumetricCompensation {
  std::string source;                 ///< "model 2"
  processing::VolumetricTable table;  ///< as the controller reads the file written
  std::string text, setup;            ///< the file and the configuration lines
  std::vector<std::string> extensions_left_out;
  std::optional<VolumetricVerification> verification;  ///< when the model's runs are simulated
  nlohmann::json document() const;
};

/// The model's errors as ISG's volumetric compensation (TwinCAT CNC, TF5280), verified on the
/// simulated machine its runs were measured on. @throws InputError for a damaged model or a
/// term ISG has no name for
VolumetricCompensation compensateVolumetric(Session& session, storage::Id model_id, const VolumetricRequest& request);

/// Reads a table file of a controller (what --compensation and --existing take).
/// @throws InputError naming the file and line
processing::CompensationTable readCompensationFile(const std::string& path, const std::string& controller);

/// The tables read from their files, as a run stores them (storage::NewRun::compensation_json).
/// @throws InputError for an axis other than X, Y, Z or given twice, or a file the controller would not load
std::string compensationRecord(const std::vector<ControllerTable>& tables);
/// A table a run's controller applied, with the controller's rules.
struct AppliedTable {
  processing::CompensationTable table;
  processing::TableRules rules;
  std::string controller, file;
};
/// The tables of a run's record, by axis index (0 X, 1 Y, 2 Z).
std::array<std::optional<AppliedTable>, 3> appliedTables(const std::string& compensation_json);
/// Sets the virtual machine's controller tables from a run's record.
void applyCompensation(const std::string& compensation_json, mocks::VirtualMachineConfig& machine);

}  // namespace mtcal::services
