// The candidate catalogue of thermal monitoring series: a constant baseline, contiguous blocks
// of time as folds, and drift with time, with each temperature, and with the sensors the
// thermal model keeps (its sensors, without their lags).
#include <fmt/format.h>

#include <algorithm>
#include <string>
#include <vector>

#include "diagnosis_internal.h"
#include "mtcal/error.h"
#include "mtcal/processing/diagnosis.h"
#include "mtcal/processing/thermal_model.h"

namespace mtcal::processing {

using detail::addChannels;
using detail::candidate;
using detail::checkSizes;
using detail::firstOrderDrift;
using detail::foldsByBlocks;
using detail::linearDrift;
using detail::mean;
using detail::shape;
using detail::varies;
using detail::vec;

DiagnosisData thermalDiagnosisData(const ThermalRunInput& in) {
  const std::size_t n = in.time_s.size();
  checkSizes(n, {in.displacement_um.size()}, in.source);
  DiagnosisData d;
  d.kind = "thermal";
  d.source = in.source;
  d.main_variable = "time_s";
  d.value_name = "displacement";
  d.measured = vec(in.displacement_um);
  d.simulated = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(n));
  d.model_description = "no thermal model (the machine as cold)";
  d.variables = {{"time_s", "s", vec(in.time_s)}};
  addChannels(d, in.temperatures_c, n, "sensor");
  // One level per segment: after a gap (a resumed run) the displacement's zero is not continuous.
  std::vector<int> levels;
  for (const int s : in.segment) {
    if (std::find(levels.begin(), levels.end(), s) == levels.end()) levels.push_back(s);
  }
  if (!in.segment.empty()) checkSizes(n, {in.segment.size()}, in.source);
  d.baseline = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(n),
                                     static_cast<Eigen::Index>(std::max<std::size_t>(1, levels.size())));
  for (std::size_t i = 0; i < n; ++i) {
    const auto level = in.segment.empty() ? 0 : std::find(levels.begin(), levels.end(), in.segment[i]) - levels.begin();
    d.baseline(static_cast<Eigen::Index>(i), level) = 1.0;
  }
  d.baseline_description =
      levels.size() > 1
          ? fmt::format("a constant displacement in each of the run's {} segments (it was resumed)", levels.size())
          : "a constant displacement";
  d.fold = foldsByBlocks(vec(in.time_s), std::max(2, in.folds));
  d.fold_description = fmt::format("{} contiguous blocks of time, each left out in turn", std::max(2, in.folds));
  d.candidates.push_back(linearDrift());
  d.candidates.push_back(firstOrderDrift(d.variables.front().values));
  std::vector<std::string> sensors;
  for (std::size_t k = 1; k < d.variables.size(); ++k) {
    const auto& v = d.variables[k];
    if (!varies(d, v.name)) continue;
    sensors.push_back(v.name);
    d.candidates.push_back(candidate("thermal_drift", v.name,
                                     fmt::format("thermal drift following the temperature {}", v.name),
                                     {shape("linear", {v.name}, 1.0, mean(v.values))}, {{"sensitivity", "um/K", 1.0}}));
  }
  // The fitted thermal model (thermal_model.h): the sensors of the model it keeps on the first
  // 60 % of the series.
  if (sensors.size() >= 2 && n >= 30) {
    ThermalData td;
    td.sensors = sensors;
    td.time_s = vec(in.time_s);
    td.segment = in.segment;
    td.target_um = d.measured;
    td.temperature_c.resize(static_cast<Eigen::Index>(n), static_cast<Eigen::Index>(sensors.size()));
    for (std::size_t k = 0; k < sensors.size(); ++k)
      td.temperature_c.col(static_cast<Eigen::Index>(k)) = d.variable(sensors[k])->values;
    try {
      const auto model = fitThermalModel(td, ThermalFitOptions{});
      // Its sensors, each taken as it reads (a lagged input's sensor once, without its lag).
      const std::vector<std::string> kept = thermalSensorsOf(model.chosen);
      if (kept.size() >= 2) {
        std::vector<ExtensionShape> shapes;
        std::vector<Candidate::Parameter> params;
        std::string names;
        for (const auto& s : kept) {
          shapes.push_back(shape("linear", {s}, 1.0, mean(d.variable(s)->values)));
          params.push_back({s, "um/K", 1.0});
          names += (names.empty() ? "" : ", ") + s;
        }
        d.candidates.push_back(
            candidate("thermal_drift", names,
                      fmt::format("thermal drift following the temperatures {} (the sensors a thermal model fitted to "
                                  "the run's first {:.0f} % keeps, each as it reads, without a lag)",
                                  names, 100.0 * ThermalFitOptions{}.train_fraction),
                      shapes, params));
      }
    } catch (const InputError& e) {
      d.notes.push_back(std::string("the thermal model could not be fitted: ") + e.what());
    }
  }
  d.notes.push_back(
      "one displacement at one point: the drift elsewhere in the volume and how it grows along an axis' travel are "
      "not seen; a heat source no sensor is near reads as a function of time");
  return d;
}

}  // namespace mtcal::processing
