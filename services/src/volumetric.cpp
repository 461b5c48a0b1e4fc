// The volumetric compensation of an identified model (ISG CSV) and its verification on the
// simulated machine the model was measured on.

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "mtcal/acquisition/diagnosis_data.h"
#include "mtcal/acquisition/error_models.h"
#include "mtcal/error.h"
#include "mtcal/mocks/random.h"
#include "mtcal/processing/geometry3d.h"
#include "mtcal/services/compensate.h"
#include "mtcal/services/model.h"
#include "mtcal/services/workshop.h"

namespace mtcal::services {
namespace {

/// Length of each error vector (um) left after the best-fit rigid motion of the points.
std::vector<double> afterRigidFit(const processing::Points3d& ideal_mm, const std::vector<Eigen::Vector3d>& error_um) {
  processing::Points3d actual_mm;
  for (std::size_t i = 0; i < ideal_mm.size(); ++i) actual_mm.push_back(ideal_mm[i] + error_um[i] / 1000.0);
  const auto fit = processing::rigidFit(ideal_mm, actual_mm);
  std::vector<double> out;
  for (const double r : fit.residuals_mm) out.push_back(r * 1000.0);
  return out;
}

std::pair<double, double> rmsAndMax(const std::vector<double>& values) {
  double sum = 0.0, max = 0.0;
  for (const double v : values) sum += v * v, max = std::max(max, v);
  return {std::sqrt(sum / static_cast<double>(values.size())), max};
}

/// The tool point's static error (um, actual - ideal, no per-approach scatter) at `points`
/// visited in order, every axis approaching its position moving positive (from 5 mm below,
/// the travel allowing): a table without direction cannot compensate the lost motion of a
/// reversal, so the check approaches the points the way volumetric checks do, one way.
std::vector<Eigen::Vector3d> measurePoints(const mocks::VirtualMachineConfig& machine,
                                           const std::vector<std::array<double, 3>>& points) {
  constexpr double kApproachMm = 5.0;
  mocks::WorldClock clock;
  mocks::VirtualMachine vm(machine, clock);
  std::vector<Eigen::Vector3d> out;
  for (const auto& p : points) {
    for (std::size_t a = 0; a < 3; ++a) {
      const auto axis = static_cast<mocks::Axis>(a);
      vm.moveTo(axis, std::max(machine.axes[a].min_mm, p[a] - kApproachMm));
      vm.moveTo(axis, p[a]);
    }
    Eigen::Vector3d e;
    for (int c = 0; c < 3; ++c) e(c) = vm.staticErrorUm(mocks::Axis::kX, {0.0, 0.0, 0.0}, p[0], +1, c);
    out.push_back(e);
  }
  return out;
}

VolumetricVerification verify(const processing::ErrorModel& model, mocks::VirtualMachineConfig machine,
                              const processing::VolumetricTable& table, const VolumetricRequest& request) {
  const auto& kinematics = model.kinematics();
  const auto& coordinates = kinematics.coordinates();
  std::array<int, 3> index{};
  for (int a = 0; a < 3; ++a) {
    const auto it = std::find(coordinates.begin(), coordinates.end(), std::string(1, static_cast<char>('x' + a)));
    index[static_cast<std::size_t>(a)] = static_cast<int>(it - coordinates.begin());
  }
  // Uniform in the box the model was measured over (and the machine can reach).
  std::vector<std::array<double, 3>> points;
  for (std::size_t i = 0; i < request.points; ++i) {
    std::array<double, 3> p{};
    for (std::size_t a = 0; a < 3; ++a) {
      auto [lo, hi] = model.coordinateRange(index[a]);
      lo = std::max(lo, machine.axes[a].min_mm), hi = std::min(hi, machine.axes[a].max_mm);
      p[a] = lo + (hi - lo) * mocks::uniformFromKey(mocks::mix64(request.seed * 0x9E37 + 3 * i + a));
    }
    points.push_back(p);
  }
  const auto before = measurePoints(machine, points);
  machine.volumetric = table;
  const auto after = measurePoints(machine, points);
  processing::Points3d ideal;
  std::vector<Eigen::Vector3d> left;
  Eigen::VectorXd q = model.workspaceCentre();
  for (std::size_t i = 0; i < points.size(); ++i) {
    for (std::size_t a = 0; a < 3; ++a) q(index[a]) = points[i][a];
    ideal.push_back(kinematics.idealPoint(q));
    left.push_back(before[i] + model.predictUm(q));  // actual - ideal + (ideal - actual) predicted
  }
  VolumetricVerification v;
  v.points = points.size();
  v.seed = request.seed;
  std::tie(v.before_rms_um, v.before_max_um) = rmsAndMax(afterRigidFit(ideal, before));
  std::tie(v.after_rms_um, v.after_max_um) = rmsAndMax(afterRigidFit(ideal, after));
  std::tie(v.expected_rms_um, v.expected_max_um) = rmsAndMax(afterRigidFit(ideal, left));
  return v;
}

}  // namespace

nlohmann::json VolumetricCompensation::document() const {
  // Without the binary conversion's noise: values to 1e-6 um (urad), figures to 0.001 um.
  const auto tidied = [&](const std::vector<double>& v) {
    std::vector<double> out;
    for (const double x : v) out.push_back(roundedTo(x, 6));
    return out;
  };
  nlohmann::json axes = nlohmann::json::array();
  for (const auto& a : table.axes) {
    nlohmann::json values = nlohmann::json::object();
    for (const auto& [term, v] : a.values) values[term] = tidied(v);
    axes.push_back({{"coordinate", a.coordinate}, {"position", a.position}, {"values", values}});
  }
  nlohmann::json constants = nlohmann::json::object();
  for (const auto& [term, v] : table.constants) constants[term] = roundedTo(v, 6);
  nlohmann::json d{{"schema_version", 1},
                   {"source", source},
                   {"controller", kIsgVolumetric},
                   {"units", "um and urad; positions mm (rotary axes deg); the file: mm and rad"},
                   {"axes", axes},
                   {"constants", constants},
                   {"records", table.records()},
                   {"file", text},
                   {"setup", setup},
                   {"extensions_left_out", extensions_left_out}};
  if (verification) {
    const auto& v = *verification;
    d["verification"] = {
        {"points", v.points},
        {"seed", v.seed},
        {"before", {{"rms_um", roundedTo(v.before_rms_um, 3)}, {"max_um", roundedTo(v.before_max_um, 3)}}},
        {"after", {{"rms_um", roundedTo(v.after_rms_um, 3)}, {"max_um", roundedTo(v.after_max_um, 3)}}},
        {"expected", {{"rms_um", roundedTo(v.expected_rms_um, 3)}, {"max_um", roundedTo(v.expected_max_um, 3)}}}};
  }
  return d;
}

VolumetricCompensation compensateVolumetric(Session& session, storage::Id model_id, const VolumetricRequest& request) {
  const auto record = session.store().model(model_id);
  const auto model = acquisition::modelOf(record);
  VolumetricCompensation c;
  c.source = fmt::format("model {}", model_id);
  const auto sampled = processing::sampleVolumetric(model, request.interval);
  c.text = processing::writeIsgVolumetricCsv(
      sampled,
      fmt::format("mtcal: volumetric compensation of {} ({}), rows every {:g} mm over the measured range (the last "
                  "at its end)",
                  c.source, record.name, request.interval));
  c.table = processing::readIsgVolumetricCsv(c.text, c.source);  // what the controller holds
  c.setup = processing::isgVolumetricSetup(
      c.table, request.file_name.empty() ? fmt::format("volcomp-model{}.csv", model_id) : request.file_name);
  for (const auto& e : acquisition::modelExtensions(record))
    c.extensions_left_out.push_back(e.measures.empty() ? fmt::format("{} ({} runs)", e.extension.effect, e.kind)
                                                       : fmt::format("{} on {}", e.extension.effect, e.measures));
  // Verified on the simulated machine of the model's first run, when there is one.
  if (const auto runs = identifyingRuns(record).runs; request.points > 0 && !runs.empty()) {
    const auto run_id = runs.front();
    if (auto machine = simulationFromDescription(session.store().machineDescriptionOfRun(run_id))) {
      applyCompensation(session.store().run(run_id).compensation_json, *machine);
      if (request.points < 3 || request.points > 100000)
        throw InputError("the verification takes 3 to 100000 points (or 0 for none)");
      c.verification = verify(model, *machine, c.table, request);
    }
  }
  return c;
}

}  // namespace mtcal::services
