#pragma once
// Compensation tables a controller loads, from a linear positioning run (ISO 230-2's mean
// deviations per direction) or from an identified model (any linear axis, with its
// extensions), in the controller's own file format (docs/compensation.md).

#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "mtcal/processing/compensation.h"
#include "mtcal/processing/compensation_formats.h"
#include "mtcal/services/session.h"

namespace mtcal::services {

struct CompensateRequest {
  std::string controller = "csv";  ///< processing::controllerNames()
  std::string axis;                ///< a run's own axis when empty; required for a model
  std::optional<int> axis_index;   ///< the controller's number of the axis (default: X 0, Y 1, Z 2)
  /// Start, end, interval (a model's default: 10 mm), reference point, bidirectional or mean,
  /// resolution (the controller's when 0), modulo. The controller's entry limit is added.
  processing::TableOptions table;
  /// A table the machine ran while it was measured, in the controller's format: the new table
  /// adds the measured (remaining) error to it.
  std::string existing_path;
  std::string at;  ///< a model's other coordinates ("x,y,z"; default: the workspace centre)
};

struct Compensation {
  std::string source;  ///< "run 3", "model 2"
  std::string axis, controller, controller_description;
  processing::CompensationTable table;
  processing::ControllerFile file;
  std::vector<std::string> extensions_applied, extensions_left_out;  ///< a model's
  std::size_t outside = 0;  ///< a model's positions outside its measured range, left out
  std::string existing_path;
  /// The table (position, correction per direction), the file's text and setup lines.
  nlohmann::json document() const;
};

/// @throws InputError for a run that is not a completed linear positioning run, an axis that
///         is not the run's, or a table the controller cannot take
Compensation compensateRun(Session& session, storage::Id run_id, const CompensateRequest& request);
/// @throws InputError for an axis the model does not have, or a table the controller cannot take
Compensation compensateModel(Session& session, storage::Id model_id, const CompensateRequest& request);

/// Reads a table file of a controller (what --compensation and --existing take).
/// @throws InputError naming the file and line
processing::CompensationTable readCompensationFile(const std::string& path, const std::string& controller);

}  // namespace mtcal::services
