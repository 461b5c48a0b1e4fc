#pragma once
// The independent numpy implementations in bench/ (model_map_numpy.py, model_identify_numpy.py,
// gantry_numpy.py), the inputs both they and mtcal are given, and the comparison of their
// results. One place for both users: the benchmarks (bench/model_bench.cpp,
// bench/gantry_bench.cpp) time the two and print the difference; the cross-check tests
// (tests/crosscheck) assert it.

#include <Eigen/Core>
#include <array>
#include <cstddef>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "mtcal/processing/error_model.h"
#include "mtcal/processing/gantry_accuracy.h"
#include "mtcal/processing/line_identification.h"

namespace mtcal::reference {

/// Runs bench/SCRIPT with the Python that CMake found with numpy (MTCAL_PYTHON) on `input`,
/// written to a temporary file, followed by `args`; returns the JSON object the script prints.
/// @throws std::runtime_error naming the command, its exit status and its standard error
nlohmann::json runNumpy(const std::string& script, const nlohmann::json& input, const std::vector<std::string>& args);

/// runNumpy for a benchmark, which goes on without it: the result, or why there is none.
struct NumpyRun {
  nlohmann::json result;
  std::string error;  ///< empty when the script ran
};
NumpyRun tryRunNumpy(const std::string& script, const nlohmann::json& input, const std::vector<std::string>& args);

/// How two implementations' results agree: the largest absolute difference over the values
/// both have, how many were compared, where the largest was, and what one has and the other
/// lacks (names, lengths), each a sentence.
struct Agreement {
  double max_abs_difference = 0.0;
  std::size_t compared = 0;
  std::string worst;
  std::vector<std::string> mismatches;
};

// --- The VMC's error model -----------------------------------------------------------------

/// The three-axis VMC (examples/machines/vmc3-cn104200063.model.json) with the error curves
/// of examples/models/vmc3-error-curves.csv fitted: the model mapped and the truth of the
/// identification.
struct ModelCase {
  processing::ErrorModel model;
  nlohmann::json machine;
};
ModelCase vmc3Model();

// --- Volumetric error map -------------------------------------------------------------------

/// A grid of `points_per_axis[k]` values evenly spaced from 50 to 600 mm on each axis.
std::vector<std::vector<double>> mapGrid(const std::array<int, 3>& points_per_axis);
/// model_map_numpy.py's input: {"machine", "functions", "axes"}.
nlohmann::json mapInput(const ModelCase& c, const std::vector<std::vector<double>>& axes);
/// model_map_numpy.py's arguments: best of `repeats`, `samples` evenly spaced points of the
/// grid returned (0: every point).
std::vector<std::string> mapArgs(int repeats, int samples);
/// mtcal's grid (ErrorModel::predictGridUm, last coordinate fastest) against the script's
/// "sample" values ({"index": [Ex, Ey, Ez]}, um).
Agreement compareMap(const std::vector<Eigen::Vector3d>& mtcal_um, const nlohmann::json& numpy);

// --- Identification from measured lines (direct method) -------------------------------------

/// The direct method's 18 lines (the layout of examples/plans/direct-21, nodes every 20 mm
/// from 50 to 600 mm) read through the full model with `truth` as the machine's errors, plus
/// 0.05 um / 0.05 urad of normal noise per node (std::mt19937_64 seeded 3).
std::vector<processing::MeasuredLine> directMethodLines(const processing::ErrorModel& truth);
/// model_identify_numpy.py's input: {"machine", "lines"}.
nlohmann::json identificationInput(const nlohmann::json& machine, const std::vector<processing::MeasuredLine>& lines);
/// mtcal's identified curves (node means) against the script's "curves" ({name: [values]}).
Agreement compareIdentification(const processing::LineIdentification& mtcal, const nlohmann::json& numpy);

// --- Gantry point accuracy -----------------------------------------------------------------

/// examples/gantry/quick-6x2-export.json: a simulated run's measurement file (12 holes).
const nlohmann::json& gantryExport();
processing::GantryMeasurements gantryMeasurements();
/// mtcal's dP per hole against the script's "dp_um" ([[dx, dy, dz], ...], um).
Agreement compareGantry(const processing::GantryEvaluation& mtcal, const nlohmann::json& numpy);

}  // namespace mtcal::reference
