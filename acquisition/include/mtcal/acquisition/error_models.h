#pragma once
// Error models from files and in the database: import of error curves measured elsewhere
// (CSV), and saving / loading an ErrorModel with its provenance.
//
// CSV (read as csv.h says) columns: error (ISO 230-1 name), position_mm (empty for squareness and other constant
// errors), value (um for translations, urad for rotations); optional s (standard deviation
// of the value) and n (repeats behind s; 2 when s is given without it). Rows repeating an (error, position) pair are
// repeats: their mean and s make the node. A malformed row is reported with its line number and nothing is imported.

#include <istream>
#include <string>
#include <vector>

#include "mtcal/acquisition/csv.h"
#include "mtcal/acquisition/linear_plan.h"
#include "mtcal/processing/error_model.h"
#include "mtcal/processing/line_identification.h"
#include "mtcal/storage/store.h"

namespace mtcal::acquisition {

/// @throws InputError "SOURCE:LINE: column 'c': why"
std::vector<processing::ErrorCurveData> parseErrorCurvesCsv(std::istream& in, const std::string& source,
                                                            const CsvDialect& dialect = {});

/// The measured line of a stored linear run as its plan gives it: axis, measures, the other
/// axes' positions and the reflector offset (an imported run's partial plan: the defaults for
/// what it lacks). @throws InputError naming the run for a malformed key
LinearPlan lineSetupOf(const storage::RunInfo& run);

/// The measured lines of stored runs, for identification through the machine's model
/// (processing::identifyFromLines). A run of axis a measures the error its plan names
/// (`measures`: positioning E<a><a>, straightness, or an angle) with the other axes at the
/// plan's line_position_mm (0 for an axis it does not name) and the optic at the tool point
/// plus reflector_offset_mm. Node mean: the mean bidirectional deviation (ISO 230-2 x_i, so
/// the reversal is averaged out); s: the within-direction s pooled over both directions;
/// repeats: the cycles of both directions (degrees of freedom n_up + n_down - 2).
/// @throws InputError for a run that is not a linear run or an axis the machine lacks
std::vector<processing::MeasuredLine> linesFromRuns(storage::Store& store, const std::vector<storage::Id>& runs,
                                                    const processing::MultibodyModel& kinematics);

struct ModelProvenance {
  std::string name;
  std::string method;           ///< imported, direct, 9-line
  std::string provenance_json;  ///< what it was made from
  std::string machine_json;     ///< the kinematic description used
  std::string software_version;
};

/// Stores the model (one transaction). @return model id
storage::Id saveModel(storage::Store& store, const processing::ErrorModel& model, const ModelProvenance& provenance);

/// Rebuilds a stored model. @throws InputError when it does not exist or is damaged
processing::ErrorModel loadModel(storage::Store& store, storage::Id model_id);
/// The model of a record already read (store.model). @throws InputError when damaged
processing::ErrorModel modelOf(const storage::ModelRecord& record);

}  // namespace mtcal::acquisition
