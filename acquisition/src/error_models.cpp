#include "mtcal/acquisition/error_models.h"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <map>
#include <nlohmann/json.hpp>

#include "mtcal/acquisition/csv.h"
#include "mtcal/acquisition/linear_plan.h"
#include "mtcal/error.h"
#include "mtcal/processing/iso230_2.h"

namespace mtcal::acquisition {

std::vector<processing::ErrorCurveData> parseErrorCurvesCsv(std::istream& in, const std::string& source,
                                                            const CsvDialect& dialect) {
  CsvReader reader(in, source, dialect);
  const std::string need = "error, position_mm, value; optional s, n";
  const auto error_column = reader.require("error", need);
  const auto position_column = reader.require("position_mm", need);
  const auto value_column = reader.require("value", need);
  const auto s_column = reader.find("s");
  const auto n_column = reader.find("n");
  reader.refuseUnusedMappings();
  // error -> position (NaN for a constant) -> values and given s
  struct Node {
    std::vector<double> values;
    std::optional<double> s;
    std::optional<int> n;  ///< repeats behind a given s
  };
  std::map<std::string, std::map<double, Node>> curves;
  const double kConstant = -std::numeric_limits<double>::infinity();
  while (const auto row = reader.row()) {
    const auto& cells = *row;
    const std::string error = cells[error_column.index];
    if (error.empty()) throw reader.error(error_column.header, "empty");
    const double value = reader.required(cells, value_column);
    const auto position = reader.number(cells, position_column);
    Node& node = curves[error][position.value_or(kConstant)];
    node.values.push_back(value);
    if (s_column) {
      if (auto s = reader.number(cells, *s_column)) {
        if (*s < 0.0) throw reader.error(s_column->header, "must not be negative");
        node.s = s;
      }
    }
    if (n_column) {
      if (auto n = reader.number(cells, *n_column)) {
        if (*n < 1 || *n != std::floor(*n) || *n > 1e6)
          throw reader.error(n_column->header, "a whole number from 1 to 1000000");
        node.n = static_cast<int>(*n);
      }
    }
  }
  std::vector<processing::ErrorCurveData> out;
  for (const auto& [error, nodes] : curves) {
    processing::ErrorCurveData d;
    d.name = error;
    if (nodes.count(kConstant) && nodes.size() > 1) {
      throw InputError(fmt::format("{}: error {} has rows with and without a position", source, error));
    }
    for (const auto& [position, node] : nodes) {
      const auto n = static_cast<int>(node.values.size());
      double mean = 0.0;
      for (double v : node.values) mean += v;
      mean /= n;
      std::optional<double> s = node.s;
      if (!s && n >= 2) {
        double ss = 0.0;
        for (double v : node.values) ss += (v - mean) * (v - mean);
        s = std::sqrt(ss / (n - 1));
      }
      if (position != kConstant) d.position_mm.push_back(position);
      d.mean.push_back(mean);
      d.s.push_back(s);
      // A given s without its n counts as estimated from 2 repeats: the fewest degrees of
      // freedom, so the t-corrected bands are never narrower than the data justify.
      d.repeats.push_back(node.s ? node.n.value_or(std::max(n, 2)) : n);
    }
    out.push_back(std::move(d));
  }
  if (out.empty()) throw InputError(source + ": no data rows");
  return out;
}

LinearPlan lineSetupOf(const storage::RunInfo& run) {
  // Imported runs carry a partial plan: what it lacks takes the plan defaults (positioning,
  // other axes at 0, optic at the tool point).
  auto plan_json = nlohmann::json::parse(run.plan_json, nullptr, false);
  if (plan_json.is_discarded() || !plan_json.is_object()) plan_json = nlohmann::json::object();
  nlohmann::json setup = {{"axis", run.axis}};
  for (const char* key : {"measures", "line_position_mm", "reflector_offset_mm"}) {
    if (plan_json.contains(key)) setup[key] = plan_json[key];
  }
  return LinearPlan::fromJson(setup, fmt::format("run {} plan", run.id));
}

std::vector<processing::MeasuredLine> linesFromRuns(storage::Store& store, const std::vector<storage::Id>& runs,
                                                    const processing::MultibodyModel& kinematics) {
  if (runs.empty()) throw InputError("no runs given");
  const auto& coordinates = kinematics.coordinates();
  auto coordinateOf = [&](const std::string& axis, storage::Id run_id) {
    std::string name = axis;
    for (auto& c : name) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    const auto it = std::find(coordinates.begin(), coordinates.end(), name);
    if (it == coordinates.end()) {
      throw InputError(fmt::format("run {}: machine '{}' has no axis {}", run_id, kinematics.name(), axis));
    }
    return static_cast<int>(it - coordinates.begin());
  };
  std::vector<processing::MeasuredLine> out;
  for (const storage::Id run_id : runs) {
    const auto run = store.run(run_id);
    if (run.kind != storage::run_kind::kLinear) {
      throw InputError(fmt::format("run {} is {}: a model is identified from and validated against linear runs", run_id,
                                   storage::run_kind::aRunOf(run.kind)));
    }
    const LinearPlan plan = lineSetupOf(run);
    processing::MeasuredLine line;
    line.id = fmt::format("run {}", run_id);
    line.measures = measuredError(plan);
    line.component = measuredComponent(plan);
    line.coordinate = coordinateOf(run.axis, run_id);
    line.q = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(coordinates.size()));
    for (const auto& [axis, position_mm] : plan.line_position_mm) line.q(coordinateOf(axis, run_id)) = position_mm;
    line.point_mm = kinematics.toolPoint() + Eigen::Vector3d(plan.reflector_offset_mm[0], plan.reflector_offset_mm[1],
                                                             plan.reflector_offset_mm[2]);

    std::vector<processing::PositionDeviation> deviations;
    for (const auto& t : store.targets(run_id)) {
      deviations.push_back({t.target_mm, t.direction > 0 ? processing::Direction::kUp : processing::Direction::kDown,
                            t.cycle, t.deviation_um});
    }
    if (deviations.empty()) throw InputError(fmt::format("run {} has no captured targets", run_id));
    const auto iso = processing::evaluateIso230_2(deviations);
    for (const auto& p : iso.positions) {
      line.position_mm.push_back(p.target_mm);
      const bool both = p.mean_um.has_value();
      line.mean.push_back(both ? *p.mean_um : p.mean_up_um.value_or(p.mean_down_um.value_or(0.0)));
      const int n_up = p.cycles_up, n_down = p.cycles_down;
      double ss = 0.0;
      if (p.s_up_um) ss += (n_up - 1) * *p.s_up_um * *p.s_up_um;
      if (p.s_down_um) ss += (n_down - 1) * *p.s_down_um * *p.s_down_um;
      const int dof = (n_up > 0 ? n_up - 1 : 0) + (n_down > 0 ? n_down - 1 : 0);
      line.s.push_back(dof > 0 ? std::optional<double>(std::sqrt(ss / dof)) : std::nullopt);
      line.repeats.push_back(dof + 1);  // ErrorFunction counts repeats - 1 degrees of freedom per node
    }
    out.push_back(std::move(line));
  }
  return out;
}

storage::Id saveModel(storage::Store& store, const processing::ErrorModel& model, const ModelProvenance& provenance) {
  storage::ModelRecord record;
  record.name = provenance.name;
  record.method = provenance.method;
  record.provenance_json = provenance.provenance_json;
  record.machine_json = provenance.machine_json;
  record.software_version = provenance.software_version;
  for (const auto& f : model.functions()) record.error_functions.emplace_back(f.name(), f.toJson().dump());
  return store.addModel(record);
}

processing::ErrorModel loadModel(storage::Store& store, storage::Id model_id) { return modelOf(store.model(model_id)); }

processing::ErrorModel modelOf(const storage::ModelRecord& record) {
  const auto source = fmt::format("model {}", record.id);
  auto machine = processing::MultibodyModel::fromJson(nlohmann::json::parse(record.machine_json), source);
  std::vector<processing::ErrorFunction> functions;
  for (const auto& [name, json] : record.error_functions) {
    functions.push_back(processing::ErrorFunction::fromJson(name, nlohmann::json::parse(json)));
  }
  return processing::ErrorModel(std::move(machine), std::move(functions));
}

}  // namespace mtcal::acquisition
