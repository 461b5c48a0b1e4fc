#include "mtcal/services/model.h"

#include <fmt/format.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

#include "mtcal/acquisition/csv.h"
#include "mtcal/acquisition/diagnosis_data.h"
#include "mtcal/acquisition/error_models.h"
#include "mtcal/error.h"
#include "mtcal/processing/diagnosis.h"
#include "mtcal/services/version.h"
#include "mtcal/services/workshop.h"

namespace mtcal::services {
namespace {

double parseNumber(const std::string& text, const std::string& what) {
  double v = 0.0;
  auto [ptr, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
  if (ec != std::errc() || ptr != text.data() + text.size())
    throw InputError(what + ": '" + text + "' is not a number");
  return v;
}

std::vector<std::string> splitOn(const std::string& text, char sep) {
  std::vector<std::string> parts;
  std::stringstream s(text);
  std::string part;
  while (std::getline(s, part, sep)) parts.push_back(part);
  return parts;
}

/// Whether a point lies outside the range the model was measured over (extrapolated there).
bool outsideMeasuredRange(const processing::ErrorModel& model, const Eigen::VectorXd& q) {
  for (Eigen::Index c = 0; c < q.size(); ++c) {
    const auto [lo, hi] = model.coordinateRange(static_cast<int>(c));
    if (q(c) < lo - 1e-9 || q(c) > hi + 1e-9) return true;
  }
  return false;
}

Eigen::VectorXd pointOrCentre(const processing::ErrorModel& model, const std::string& at) {
  const auto n = static_cast<Eigen::Index>(model.kinematics().coordinates().size());
  if (at.empty()) return model.workspaceCentre();
  const auto parts = splitOn(at, ',');
  if (static_cast<Eigen::Index>(parts.size()) != n) {
    throw InputError(fmt::format("--at needs {} comma-separated coordinates ({}), got '{}'", n,
                                 fmt::join(model.kinematics().coordinates(), ","), at));
  }
  Eigen::VectorXd q(n);
  for (Eigen::Index i = 0; i < n; ++i) {
    q(i) = parseNumber(parts[static_cast<std::size_t>(i)], "--at");
    if (!std::isfinite(q(i)))
      throw InputError(fmt::format("--at: {} = '{}' is not a finite number", model.kinematics().coordinates()[i],
                                   parts[static_cast<std::size_t>(i)]));
  }
  return q;
}

std::vector<std::vector<double>> gridAxes(const processing::ErrorModel& model, const std::string& grid) {
  const auto& coords = model.kinematics().coordinates();
  const auto axes = splitOn(grid, ',');
  if (axes.size() != coords.size()) {
    throw InputError(
        fmt::format("--grid needs one FROM:TO:N per coordinate ({}), got '{}'", fmt::join(coords, ","), grid));
  }
  std::vector<std::vector<double>> values;
  for (const auto& axis : axes) {
    const auto p = splitOn(axis, ':');
    if (p.size() != 3) throw InputError("--grid: '" + axis + "' is not FROM:TO:N");
    const double from = parseNumber(p[0], "--grid"), to = parseNumber(p[1], "--grid");
    const double n = parseNumber(p[2], "--grid");
    if (n < 1 || n != std::floor(n) || n > 1000) throw InputError("--grid: N must be a whole number 1..1000");
    std::vector<double> v;
    for (int i = 0; i < static_cast<int>(n); ++i) v.push_back(n == 1 ? from : from + (to - from) * i / (n - 1));
    values.push_back(v);
  }
  std::size_t points = 1;
  for (const auto& v : values) points *= v.size();
  if (points > 1'000'000) {
    throw InputError(
        fmt::format("--grid: {} points; at most 1000000 (a finer grid of a smaller region instead)", points));
  }
  return values;
}

// Every combination of the axis values, the last varying fastest (predictGridUm's order).
std::vector<Eigen::VectorXd> gridPoints(const std::vector<std::vector<double>>& axes) {
  std::vector<Eigen::VectorXd> points;
  std::vector<std::size_t> index(axes.size(), 0);
  for (;;) {
    Eigen::VectorXd q(static_cast<Eigen::Index>(axes.size()));
    for (std::size_t a = 0; a < axes.size(); ++a) q(static_cast<Eigen::Index>(a)) = axes[a][index[a]];
    points.push_back(q);
    std::size_t a = axes.size();
    while (a > 0 && ++index[a - 1] == axes[a - 1].size()) index[--a] = 0;
    if (a == 0) return points;
  }
}

std::vector<Eigen::VectorXd> csvPoints(const std::string& path) {
  std::ifstream in = acquisition::openInputFile(path);
  const auto columns = acquisition::readColumnsCsv(in, path, {"x_mm", "y_mm", "z_mm"});
  std::vector<Eigen::VectorXd> points;
  for (std::size_t i = 0; i < columns.at("x_mm").size(); ++i) {
    points.emplace_back(Eigen::Vector3d(columns.at("x_mm")[i], columns.at("y_mm")[i], columns.at("z_mm")[i]));
  }
  return points;
}

// Fits the curves, builds the model on the machine description and stores it.
StoredModel storeFittedModel(Session& session, const MachineDescription& machine,
                             const std::vector<processing::ErrorCurveData>& curves, const ModelFitRequest& request,
                             const std::string& method, nlohmann::json provenance) {
  processing::ErrorFitOptions fit;
  fit.min_knot_spacing_mm = request.min_knot_spacing_mm;
  std::vector<processing::ErrorFunction> functions;
  for (const auto& curve : curves) {
    try {
      functions.push_back(processing::ErrorFunction::fit(curve, fit));
    } catch (const InputError& e) {
      throw InputError("error " + curve.name + ": " + e.what());
    }
  }
  const processing::ErrorModel model(machine.model, std::move(functions));
  provenance["machine"] = request.machine_path;
  provenance["min_knot_spacing_mm"] = request.min_knot_spacing_mm;
  acquisition::ModelProvenance p;
  p.name = request.name;
  p.method = method;
  p.provenance_json = provenance.dump();
  p.machine_json = machine.json.dump();
  p.software_version = kVersion;
  StoredModel stored;
  stored.model_id = acquisition::saveModel(session.store(Access::kCreate), model, p);
  const auto& kin = machine.model;
  for (const auto& f : model.functions()) {
    stored.errors.push_back(f.name());
    const auto& term = kin.terms()[static_cast<std::size_t>(kin.termIndex(f.name()))];
    const int coordinate = kin.coordinateOfJoint(term.joint);
    stored.coverage.push_back(f.constant() || coordinate < 0
                                  ? f.name() + " constant"
                                  : fmt::format("{} over {} {:g} to {:g}", f.name(),
                                                kin.coordinates()[static_cast<std::size_t>(coordinate)],
                                                f.nodes().front(), f.nodes().back()));
  }
  stored.machine_terms = kin.terms().size();
  return stored;
}

nlohmann::json axesDocument(const std::vector<processing::AxisSolution>& axes) {
  nlohmann::json list = nlohmann::json::array();
  for (const auto& a : axes) {
    list.push_back({{"axis", a.coordinate},
                    {"lines", a.lines},
                    {"errors", a.terms},
                    {"condition_number", a.condition_number},
                    {"noise_gain", a.noise_gain}});
  }
  return list;
}

}  // namespace

MachineDescription readMachine(const std::string& path) {
  const auto json = readJsonFile(path);
  return {json, processing::MultibodyModel::fromJson(json, path)};
}

nlohmann::json StoredModel::document() const {
  nlohmann::json j = {{"schema_version", 1}, {"model_id", model_id}, {"errors", errors}};
  if (!runs.empty()) {
    j["axes"] = axesDocument(axes);
    j["notes"] = notes;
  }
  return j;
}

StoredModel importModel(Session& session, const ModelFitRequest& request) {
  std::ifstream csv = acquisition::openInputFile(request.csv_path);
  const auto curves = acquisition::parseErrorCurvesCsv(csv, request.csv_path, request.csv);
  const auto machine = readMachine(request.machine_path);
  ModelFitRequest named = request;
  if (named.name.empty()) named.name = std::filesystem::path(request.csv_path).filename().string();
  return storeFittedModel(session, machine, curves, named, "imported", {{"file", request.csv_path}});
}

StoredModel identifyModel(Session& session, const std::vector<std::string>& sources, const ModelFitRequest& request) {
  const auto machine = readMachine(request.machine_path);
  auto& store = session.store();
  const auto runs = resolveRuns(store, sources, {storage::run_kind::kLinear});
  processing::LineIdentificationOptions options;
  options.method = request.method == "9-line" ? processing::IdentificationMethod::kNineLine
                                              : processing::IdentificationMethod::kDirect;
  options.max_condition_number = request.max_condition_number;
  const auto id =
      processing::identifyFromLines(machine.model, acquisition::linesFromRuns(store, runs, machine.model), options);
  ModelFitRequest named = request;
  if (named.name.empty())
    named.name = fmt::format("{} identification from run(s) {}", request.method, fmt::join(runs, ", "));
  nlohmann::json provenance = {{"runs", runs},
                               {"max_condition_number", request.max_condition_number},
                               {"axes", axesDocument(id.axes)},
                               {"notes", id.notes}};
  auto stored = storeFittedModel(session, machine, id.curves, named, request.method, provenance);
  stored.runs = runs;
  stored.axes = id.axes;
  stored.notes = id.notes;
  return stored;
}

IdentifyingRuns identifyingRuns(const storage::ModelRecord& model) {
  const auto provenance =
      nlohmann::json::parse(model.provenance_json.empty() ? "{}" : model.provenance_json, nullptr, false);
  for (auto at = &provenance; at->is_object();) {
    if (at->contains("runs") && at->at("runs").is_array()) {
      IdentifyingRuns found;
      for (const auto& id : at->at("runs"))
        if (id.is_number_integer()) found.runs.push_back(id.get<storage::Id>());
      if (const auto n = at->find("runs_not_held"); n != at->end() && n->is_number_integer())
        found.not_held = n->get<int>();
      return found;
    }
    if (!at->contains("base_provenance")) break;
    at = &at->at("base_provenance");
  }
  return {};
}

std::vector<storage::ModelRecord> listModels(Session& session) { return session.store().listModels(); }

nlohmann::json modelListDocument(const std::vector<storage::ModelRecord>& models) {
  nlohmann::json list = nlohmann::json::array();
  for (const auto& m : models) {
    list.push_back({{"id", m.id},
                    {"name", m.name},
                    {"method", m.method},
                    {"created_at", m.created_at},
                    {"provenance", nlohmann::json::parse(m.provenance_json)}});
  }
  return {{"schema_version", 1}, {"models", list}};
}

nlohmann::json ModelPrediction::document() const {
  nlohmann::json list = nlohmann::json::array();
  for (std::size_t i = 0; i < points.size(); ++i) {
    const auto& q = points[i];
    const auto& e = error_um[i];
    const auto& s = sigma_um[i];
    list.push_back({{"x_mm", q(0)},
                    {"y_mm", q(1)},
                    {"z_mm", q(2)},
                    {"ex_um", e(0)},
                    {"ey_um", e(1)},
                    {"ez_um", e(2)},
                    {"sx_um", s(0)},
                    {"sy_um", s(1)},
                    {"sz_um", s(2)}});
  }
  return {{"schema_version", 1}, {"model_id", model_id}, {"points", list}, {"outside_measured_range", outside}};
}

std::string ModelPrediction::csv() const {
  std::string csv = "x_mm,y_mm,z_mm,ex_um,ey_um,ez_um,sx_um,sy_um,sz_um\n";
  for (std::size_t i = 0; i < points.size(); ++i) {
    const auto& q = points[i];
    const auto& e = error_um[i];
    const auto& s = sigma_um[i];
    csv += fmt::format("{},{},{},{:.4f},{:.4f},{:.4f},{:.4f},{:.4f},{:.4f}\n", q(0), q(1), q(2), e(0), e(1), e(2), s(0),
                       s(1), s(2));
  }
  return csv;
}

ModelPrediction predictModel(Session& session, storage::Id model_id, const std::string& grid,
                             const std::string& points_csv) {
  if (grid.empty() == points_csv.empty()) throw InputError("give exactly one of --grid and --points");
  const auto model = acquisition::loadModel(session.store(), model_id);
  if (model.kinematics().coordinates().size() != 3) {
    throw InputError("model " + std::to_string(model_id) + " is not a 3-axis machine: predict takes x, y, z");
  }
  ModelPrediction p;
  p.model_id = model_id;
  if (grid.empty()) {
    p.points = csvPoints(points_csv);
    for (const auto& q : p.points) p.error_um.push_back(model.predictUm(q));
  } else {
    const auto axes = gridAxes(model, grid);
    p.points = gridPoints(axes);
    p.error_um = model.predictGridUm(axes);
  }
  for (const auto& q : p.points) {
    p.sigma_um.push_back(model.sigmaUm(q));
    if (outsideMeasuredRange(model, q)) ++p.outside;
  }
  return p;
}

nlohmann::json KeyErrorsAnalysis::document() const {
  nlohmann::json list = nlohmann::json::array();
  for (const auto& k : keys) {
    nlohmann::json item = {{"name", k.name}, {"share_x", k.share[0]}, {"share_y", k.share[1]}, {"share_z", k.share[2]}};
    for (const auto& s : sobol) {
      if (s.name == k.name) item["sobol"] = {s.first_order[0], s.first_order[1], s.first_order[2]};
    }
    list.push_back(item);
  }
  return {{"schema_version", 1},
          {"model_id", model_id},
          {"at", std::vector<double>(at.begin(), at.end())},
          {"sigma_um", {sigma_um(0), sigma_um(1), sigma_um(2)}},
          {"outside_measured_range", outside},
          {"key_errors", list}};
}

KeyErrorsAnalysis keyErrors(Session& session, storage::Id model_id, const std::string& at, int sobol_samples) {
  const auto model = acquisition::loadModel(session.store(), model_id);
  KeyErrorsAnalysis k;
  k.model_id = model_id;
  k.at = pointOrCentre(model, at);
  k.keys = model.keyErrors(k.at);
  if (sobol_samples > 0) k.sobol = processing::sobolFirstOrder(model, k.at, sobol_samples, 20261122);
  k.sigma_um = model.sigmaUm(k.at);
  k.outside = outsideMeasuredRange(model, k.at);
  return k;
}

nlohmann::json ModelBands::document() const {
  nlohmann::json list = nlohmann::json::array();
  for (const auto& band : bands) {
    const double sa = std::sqrt(band.covariance[0]), sb = std::sqrt(band.covariance[1]);
    list.push_back({{"x_mm", band.point_mm[0]},
                    {"y_mm", band.point_mm[1]},
                    {"z_mm", band.point_mm[2]},
                    {"mean_um", band.mean_um},
                    {"sigma_um", {sa, sb}},
                    {"correlation", sa > 0 && sb > 0 ? band.covariance[2] / (sa * sb) : 0.0},
                    {"band_um", band.widestBandUm()}});
  }
  return {{"schema_version", 1},
          {"model_id", model_id},
          {"plane", processing::planeName(plane)},
          {"coverage_k", coverage_k},
          {"widest_band_um", widest_band_um},
          {"points", list}};
}

ModelBands modelBands(Session& session, storage::Id model_id, const std::string& plane_text, const std::string& at,
                      int grid_n) {
  ModelBands r;
  r.model_id = model_id;
  r.plane = processing::parsePlane(plane_text);
  if (grid_n < 1 || grid_n > 200) throw InputError("--grid must be 1..200");
  const auto model = acquisition::loadModel(session.store(), model_id);
  if (model.kinematics().coordinates().size() != 3) throw InputError("bands need a 3-axis model");
  const Eigen::VectorXd centre = pointOrCentre(model, at);
  const int a = r.plane == processing::Plane::kYZ ? 1 : 0;
  const int b = r.plane == processing::Plane::kXY ? 1 : 2;
  const auto [a0, a1] = model.coordinateRange(a);
  const auto [b0, b1] = model.coordinateRange(b);
  for (int i = 0; i < grid_n; ++i) {
    for (int j = 0; j < grid_n; ++j) {
      Eigen::VectorXd q = centre;
      q(a) = grid_n == 1 ? centre(a) : a0 + (a1 - a0) * i / (grid_n - 1);
      q(b) = grid_n == 1 ? centre(b) : b0 + (b1 - b0) * j / (grid_n - 1);
      r.bands.push_back(processing::planeBand(model, r.plane, q));
      r.coverage_k = r.bands.back().coverage_k;
      r.widest_band_um = std::max(r.widest_band_um, r.bands.back().widestBandUm());
    }
  }
  return r;
}

nlohmann::json LineValidation::document() const {
  const auto& c = comparison;
  nlohmann::json nodes = nlohmann::json::array();
  for (std::size_t n = 0; n < c.position_mm.size(); ++n) {
    nodes.push_back({{"position_mm", c.position_mm[n]},
                     {"measured", c.measured[n]},
                     {"predicted", c.predicted[n] + c.offset},
                     {"residual", c.residual[n]},
                     {"sigma", c.sigma[n]}});
  }
  return {{"schema_version", 1},  {"run_id", run_id}, {"measures", measures}, {"points", c.residual.size()},
          {"outside", c.outside}, {"rms", c.rms},     {"peak", c.peak},       {"offset", c.offset},
          {"nodes", nodes}};
}

nlohmann::json ModelValidation::document() const {
  nlohmann::json list = nlohmann::json::array();
  for (const auto& r : runs) list.push_back(r.document());
  return {{"schema_version", 1}, {"model_id", model_id}, {"runs", list}};
}

ModelValidation validateModel(Session& session, storage::Id model_id, const std::vector<storage::Id>& runs) {
  for (auto run = runs.begin(); run != runs.end(); ++run) {
    if (std::find(runs.begin(), run, *run) != run)
      throw InputError(fmt::format("validate: run {} is given twice (each run is compared once)", *run));
  }
  auto& store = session.store();
  const auto model = acquisition::loadModel(store, model_id);
  const auto lines = acquisition::linesFromRuns(store, runs, model.kinematics());
  ModelValidation v;
  v.model_id = model_id;
  for (std::size_t i = 0; i < lines.size(); ++i) {
    LineValidation line{runs[i], 0, lines[i].measures, processing::compareLine(model, lines[i])};
    line.result_id = session
                         .storeResult(runs[i], "model-validation", kVersion,
                                      nlohmann::json{{"model_id", model_id}}.dump(), line.document().dump())
                         .value_or(0);
    v.outside += line.comparison.outside;
    v.runs.push_back(std::move(line));
  }
  return v;
}

ModelAxisError modelAxisError(Session& session, storage::Id model_id, const ModelAxisRequest& o) {
  const auto record = session.store().model(model_id);
  const auto model = acquisition::modelOf(record);
  const auto& coords = model.kinematics().coordinates();
  std::string lower = o.axis;
  std::transform(lower.begin(), lower.end(), lower.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  const auto it = std::find(coords.begin(), coords.end(), lower);
  if (it == coords.end() || lower.size() != 1 || lower[0] < 'x' || lower[0] > 'z') {
    throw InputError(fmt::format("model {} has no linear axis '{}' (its coordinates: {})", model_id, o.axis,
                                 fmt::join(coords, ", ")));
  }
  const int coordinate = static_cast<int>(it - coords.begin());
  const auto [range_lo, range_hi] = model.coordinateRange(coordinate);
  if (!o.from_mm && !o.to_mm && !(range_hi > range_lo)) {
    // A model identified from runs of other axes: what it holds along them, said.
    const auto& kin = model.kinematics();
    std::vector<std::string> measured;
    std::set<int> listed;
    for (int j = 0; j < static_cast<int>(kin.joints().size()); ++j) {
      const int c = kin.coordinateOfJoint(j);
      if (c < 0 || c == coordinate || !listed.insert(c).second) continue;  // a coordinate once
      const auto [lo, hi] = model.coordinateRange(c);
      const auto& joint = kin.joints()[static_cast<std::size_t>(j)];
      if (hi > lo)
        measured.push_back(fmt::format("{} {:g} to {:g} {}", joint.coordinate, lo, hi,
                                       joint.type == processing::JointType::kRevolute ? "deg" : "mm"));
    }
    throw InputError(fmt::format(
        "model {} was not measured along {} ({}): a table of {} needs a model identified from "
        "runs along it",
        model_id, o.axis,
        measured.empty() ? "nor along any axis" : "only " + fmt::format("{}", fmt::join(measured, ", ")), o.axis));
  }
  const double from = o.from_mm ? *o.from_mm : range_lo, to = o.to_mm ? *o.to_mm : range_hi;
  if (!(to > from) || !(o.step_mm > 0.0))
    throw InputError(fmt::format("compensation: no positions from {} to {} mm every {} mm", from, to, o.step_mm));
  if (o.step_mm > to - from)
    throw InputError(
        fmt::format("compensation: an interval of {} mm is longer than the range {} to {} mm", o.step_mm, from, to));
  // The positioning reading along the axis at the tool point, the other axes at --at: what a
  // linear run of the axis reads, and the model's extensions for those readings.
  processing::MeasuredLine line;
  line.id = fmt::format("model {} axis {}", model_id, o.axis);
  line.measures =
      fmt::format("E{}{}", static_cast<char>(std::toupper(lower[0])), static_cast<char>(std::toupper(lower[0])));
  line.coordinate = coordinate;
  line.q = pointOrCentre(model, o.at);
  // The other axes where the model was measured: it does not extrapolate.
  for (int c = 0; c < static_cast<int>(coords.size()); ++c) {
    const auto [lo, hi] = model.coordinateRange(c);
    if (c == coordinate || hi <= lo) continue;
    if (line.q(c) < lo - 1e-9 || line.q(c) > hi + 1e-9)
      throw InputError(fmt::format("--at: {} = {:g} is outside the range the model was measured over ({:g} to {:g})",
                                   coords[static_cast<std::size_t>(c)], line.q(c), lo, hi));
  }
  line.point_mm = model.kinematics().toolPoint();
  line.component = lower[0] - 'x';
  for (double x = from; x <= to + 1e-9 * o.step_mm; x += o.step_mm) line.position_mm.push_back(x);
  line.mean.assign(line.position_mm.size(), 0.0);
  line.s.assign(line.position_mm.size(), std::nullopt);
  line.repeats.assign(line.position_mm.size(), 1);
  const auto c = processing::compareLine(model, line);
  const auto n = static_cast<Eigen::Index>(c.position_mm.size());
  processing::DiagnosisData d;
  d.source = line.id;
  d.measured = Eigen::VectorXd::Zero(2 * n);
  Eigen::VectorXd position(2 * n), direction(2 * n);
  for (Eigen::Index i = 0; i < n; ++i) {
    position(i) = position(n + i) = c.position_mm[static_cast<std::size_t>(i)];
    direction(i) = 1.0;
    direction(n + i) = -1.0;
  }
  d.variables = {{"position_mm", "mm", position}, {"direction", "", direction}};
  // Extensions needing time or a temperature are not a table's: left out.
  const auto extensions =
      processing::applyExtensions(acquisition::extensionsFor(record, storage::run_kind::kLinear, line.measures), d);
  ModelAxisError t;
  t.reading = line.measures;
  t.applied = extensions.applied;
  t.left_out = extensions.left_out;
  t.outside = c.outside;
  for (Eigen::Index i = 0; i < n; ++i) {
    const double predicted = c.predicted[static_cast<std::size_t>(i)];
    t.error.position.push_back(position(i));
    t.error.up_um.push_back(predicted + extensions.values(i));
    t.error.down_um.push_back(predicted + extensions.values(n + i));
  }
  return t;
}

}  // namespace mtcal::services
