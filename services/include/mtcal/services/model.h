#pragma once
// Geometric error models (docs/error-model.md): built from measured curves or identified from
// stored linear runs through the machine's kinematics, then used: the volumetric error
// predicted, its key errors, the bands of the plane random process, the model checked against
// runs and the positioning error of an axis (what its compensation table cancels).

#include <Eigen/Core>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "mtcal/acquisition/csv.h"
#include "mtcal/processing/compensation.h"
#include "mtcal/processing/error_model.h"
#include "mtcal/processing/line_identification.h"
#include "mtcal/processing/multibody.h"
#include "mtcal/processing/uncertainty.h"
#include "mtcal/services/session.h"

namespace mtcal::services {

/// A machine's kinematic description (examples/machines/*.model.json) and its model.
struct MachineDescription {
  nlohmann::json json;
  processing::MultibodyModel model;
};
/// @throws InputError naming the file when it cannot be read or is not a machine description
MachineDescription readMachine(const std::string& path);

struct ModelFitRequest {
  std::string csv_path;      ///< import: the error curves
  std::string machine_path;  ///< kinematic description (examples/machines/*.model.json)
  std::string name;          ///< empty: named after its source
  double min_knot_spacing_mm = 20.0;
  std::string method = "direct";         ///< identify: direct | 9-line
  double max_condition_number = 1000.0;  ///< identify: refusal limit of a line layout
  acquisition::CsvDialect csv;           ///< import: how the curves' file is written
};

/// A model stored from curves (imported or identified).
struct StoredModel {
  storage::Id model_id = 0;
  std::vector<std::string> errors;    ///< the error terms with a function
  std::vector<std::string> coverage;  ///< each one's range, for people: "EXX over x 50 to 600", "EC0Y constant"
  std::size_t machine_terms = 0;      ///< the error terms the machine's description has
  std::vector<storage::Id> runs;      ///< identified from
  std::vector<processing::AxisSolution> axes;  ///< identification: per axis, its lines and conditioning
  std::vector<std::string> notes;
  nlohmann::json document() const;
};
/// @throws InputError naming the file, the curve and why; nothing is stored then
StoredModel importModel(Session& session, const ModelFitRequest& request);
/// From stored linear runs (ids, or "cN" for the completed linear runs of campaign N) by the
/// direct or the 9-line method. @throws InputError for a layout that cannot identify the errors
StoredModel identifyModel(Session& session, const std::vector<std::string>& sources, const ModelFitRequest& request);

/// The runs a model was identified from, through the versions it extends (their provenance's
/// "runs", "base_provenance"), by the store's numbers; none for a model read from a file.
struct IdentifyingRuns {
  std::vector<storage::Id> runs;
  int not_held = 0;  ///< of a model pulled from the plant archive: its runs this store does not hold
};
IdentifyingRuns identifyingRuns(const storage::ModelRecord& model);

/// Every stored model, oldest first, without its functions.
std::vector<storage::ModelRecord> listModels(Session& session);
nlohmann::json modelListDocument(const std::vector<storage::ModelRecord>& models);

/// The volumetric error E at the tool point and its standard deviation at machine positions.
struct ModelPrediction {
  storage::Id model_id = 0;
  std::vector<Eigen::VectorXd> points;  ///< axis positions x, y, z (mm)
  std::vector<Eigen::Vector3d> error_um, sigma_um;
  /// Points with a coordinate outside the range the model was measured over: extrapolated,
  /// not to be trusted.
  std::size_t outside = 0;
  nlohmann::json document() const;
  /// x_mm,y_mm,z_mm,ex_um,ey_um,ez_um,sx_um,sy_um,sz_um
  std::string csv() const;
};
/// `grid` "X0:X1:N,Y0:Y1:N,Z0:Z1:N" or `points_csv` (x_mm,y_mm,z_mm): exactly one.
ModelPrediction predictModel(Session& session, storage::Id model_id, const std::string& grid,
                             const std::string& points_csv);

struct KeyErrorsAnalysis {
  storage::Id model_id = 0;
  Eigen::VectorXd at;
  Eigen::Vector3d sigma_um;
  std::vector<processing::KeyError> keys;
  std::vector<processing::SobolIndex> sobol;  ///< when samples were asked
  bool outside = false;                       ///< `at` is outside the measured range: extrapolated
  nlohmann::json document() const;
};
/// At `at` ("x,y,z"; the workspace centre when empty); with `sobol_samples` > 0 also the Monte
/// Carlo first-order Sobol indices.
KeyErrorsAnalysis keyErrors(Session& session, storage::Id model_id, const std::string& at, int sobol_samples);

struct ModelBands {
  storage::Id model_id = 0;
  processing::Plane plane = processing::Plane::kXY;
  double coverage_k = 3.0, widest_band_um = 0.0;
  std::vector<processing::PlaneBand> bands;  ///< over the plane's grid
  nlohmann::json document() const;
};
ModelBands modelBands(Session& session, storage::Id model_id, const std::string& plane, const std::string& at,
                      int grid_n);

struct LineValidation {
  storage::Id run_id = 0, result_id = 0;
  std::string measures;
  processing::LineComparison comparison;
  nlohmann::json document() const;
};
struct ModelValidation {
  storage::Id model_id = 0;
  std::vector<LineValidation> runs;
  std::size_t outside = 0;  ///< points outside the range the model was measured over
  nlohmann::json document() const;
};
/// Predicts each run's readings with the model; each comparison is stored as a result of its
/// run (processor "model-validation").
ModelValidation validateModel(Session& session, storage::Id model_id, const std::vector<storage::Id>& runs);

struct ModelAxisRequest {
  std::string axis = "X";
  std::optional<double> from_mm, to_mm;  ///< default: the range the model was measured over
  double step_mm = 10.0;
  std::string at;  ///< the other coordinates ("x,y,z"); the workspace centre when empty
};
/// The model's positioning reading along an axis per approach direction, with the model's
/// extensions that depend on the position and direction (backlash, cyclic error, scale ...):
/// the error a compensation table of the axis cancels.
struct ModelAxisError {
  std::string reading;  ///< the ISO 230-1 name of the reading (EXX, ...)
  processing::AxisError error;
  std::vector<std::string> applied, left_out;  ///< extensions; left out: they need time or temperatures
  std::size_t outside = 0;                     ///< positions outside the model's measured range, left out
};
ModelAxisError modelAxisError(Session& session, storage::Id model_id, const ModelAxisRequest& request);

}  // namespace mtcal::services
