// The `mtcal model` commands: error models from measured curves, their prediction of the
// volumetric error, key errors and the bands of the plane random process.

#include <fmt/format.h>

#include <algorithm>
#include <charconv>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "commands.h"
#include "mtcal/acquisition/columns_csv.h"
#include "mtcal/acquisition/diagnosis_data.h"
#include "mtcal/acquisition/error_models.h"
#include "mtcal/services/version.h"
#include "mtcal/error.h"
#include "mtcal/processing/diagnosis.h"
#include "mtcal/processing/line_identification.h"
#include "mtcal/processing/uncertainty.h"

namespace mtcal::app {
namespace {

double parseNumber(const std::string& text, const std::string& what) {
  double v = 0.0;
  auto [ptr, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
  if (ec != std::errc() || ptr != text.data() + text.size()) throw InputError(what + ": '" + text + "' is not a number");
  return v;
}

std::vector<std::string> splitOn(const std::string& text, char sep) {
  std::vector<std::string> parts;
  std::stringstream s(text);
  std::string part;
  while (std::getline(s, part, sep)) parts.push_back(part);
  return parts;
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
  for (Eigen::Index i = 0; i < n; ++i) q(i) = parseNumber(parts[static_cast<std::size_t>(i)], "--at");
  return q;
}

std::vector<std::vector<double>> gridAxes(const processing::ErrorModel& model, const std::string& grid) {
  const auto& coords = model.kinematics().coordinates();
  const auto axes = splitOn(grid, ',');
  if (axes.size() != coords.size()) {
    throw InputError(fmt::format("--grid needs one FROM:TO:N per coordinate ({}), got '{}'", fmt::join(coords, ","), grid));
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
  std::ifstream in(path);
  if (!in) throw InputError(path + ": cannot open file");
  const auto columns = acquisition::readColumnsCsv(in, path, {"x_mm", "y_mm", "z_mm"});
  std::vector<Eigen::VectorXd> points;
  for (std::size_t i = 0; i < columns.at("x_mm").size(); ++i) {
    points.emplace_back(Eigen::Vector3d(columns.at("x_mm")[i], columns.at("y_mm")[i], columns.at("z_mm")[i]));
  }
  return points;
}

}  // namespace

MachineDescription readMachine(const std::string& path) {
  const auto json = nlohmann::json::parse(readTextFile(path), nullptr, false);
  if (json.is_discarded()) throw InputError(path + ": not valid JSON");
  return {json, processing::MultibodyModel::fromJson(json, path)};
}

namespace {

// Fits the curves, builds the model on the machine description and stores it. `extra` is
// added to the JSON output (identification reports).
int storeFittedModel(const Globals& g, storage::Store& store, const MachineDescription& machine,
                     const std::vector<processing::ErrorCurveData>& curves, const ModelImportOptions& options,
                     const std::string& method, nlohmann::json provenance, const nlohmann::json& extra = {}) {
  processing::ErrorFitOptions fit;
  fit.min_knot_spacing_mm = options.min_knot_spacing_mm;
  std::vector<processing::ErrorFunction> functions;
  for (const auto& curve : curves) {
    try {
      functions.push_back(processing::ErrorFunction::fit(curve, fit));
    } catch (const InputError& e) {
      throw InputError("error " + curve.name + ": " + e.what());
    }
  }
  const processing::ErrorModel model(machine.model, std::move(functions));
  provenance["machine"] = options.machine_path;
  provenance["min_knot_spacing_mm"] = options.min_knot_spacing_mm;
  acquisition::ModelProvenance p;
  p.name = options.name;
  p.method = method;
  p.provenance_json = provenance.dump();
  p.machine_json = machine.json.dump();
  p.software_version = kVersion;
  const storage::Id id = acquisition::saveModel(store, model, p);
  if (g.json) {
    nlohmann::json errors = nlohmann::json::array();
    for (const auto& f : model.functions()) errors.push_back(f.name());
    nlohmann::json out = {{"model_id", id}, {"errors", errors}};
    if (extra.is_object()) out.update(extra);
    *g.out << out.dump() << "\n";
  } else {
    *g.out << id << "\n";
  }
  return 0;
}

/// Run ids from "12" or "c3" (every completed or imported linear run of campaign 3), in order, once each.
std::vector<storage::Id> resolveRuns(storage::Store& store, const std::vector<std::string>& sources) {
  std::vector<storage::Id> runs;
  auto add = [&](storage::Id id) {
    if (std::find(runs.begin(), runs.end(), id) == runs.end()) runs.push_back(id);
  };
  for (const auto& source : sources) {
    const bool campaign = !source.empty() && (source[0] == 'c' || source[0] == 'C');
    const std::string digits = campaign ? source.substr(1) : source;
    storage::Id id = 0;
    const auto [ptr, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), id);
    if (digits.empty() || ec != std::errc() || ptr != digits.data() + digits.size() || id <= 0) {
      throw InputError("'" + source + "' is neither a run id nor cN (campaign N)");
    }
    if (!campaign) {
      add(id);
      continue;
    }
    bool any = false;
    for (const auto& r : store.listRuns()) {
      if (r.campaign_id == id && r.kind == "linear" &&
          (r.status == storage::run_status::kCompleted || r.status == storage::run_status::kImported)) {
        add(r.id);
        any = true;
      }
    }
    if (!any) throw InputError(fmt::format("campaign {} has no completed linear run", id));
  }
  return runs;
}

}  // namespace

int modelImport(const Globals& g, const ModelImportOptions& options) {
  std::ifstream csv(options.csv_path);
  if (!csv) throw InputError(options.csv_path + ": cannot open file");
  const auto curves = acquisition::parseErrorCurvesCsv(csv, options.csv_path);
  const auto machine = readMachine(options.machine_path);
  storage::Store store(g.db);
  ModelImportOptions named = options;
  if (named.name.empty()) named.name = options.csv_path;
  return storeFittedModel(g, store, machine, curves, named, "imported", {{"file", options.csv_path}});
}

int modelIdentify(const Globals& g, const std::vector<std::string>& sources, const ModelImportOptions& options) {
  const auto machine = readMachine(options.machine_path);
  storage::Store store(g.db);
  const auto runs = resolveRuns(store, sources);
  processing::LineIdentificationOptions id_options;
  id_options.method =
      options.method == "9-line" ? processing::IdentificationMethod::kNineLine : processing::IdentificationMethod::kDirect;
  id_options.max_condition_number = options.max_condition_number;
  const auto id = processing::identifyFromLines(machine.model, acquisition::linesFromRuns(store, runs, machine.model),
                                                id_options);
  nlohmann::json axes = nlohmann::json::array();
  for (const auto& a : id.axes) {
    axes.push_back({{"axis", a.coordinate},
                    {"lines", a.lines},
                    {"errors", a.terms},
                    {"condition_number", a.condition_number},
                    {"noise_gain", a.noise_gain}});
    if (!g.json) {
      *g.err << fmt::format("axis {}: {} from {} (condition number {:.3g})\n", a.coordinate, fmt::join(a.terms, " "),
                            fmt::join(a.lines, ", "), a.condition_number);
    }
  }
  if (!g.json) {
    for (const auto& note : id.notes) *g.err << "note: " << note << "\n";
  }
  ModelImportOptions named = options;
  if (named.name.empty()) named.name = fmt::format("{} identification from run(s) {}", options.method, fmt::join(runs, ", "));
  const nlohmann::json report = {{"axes", axes}, {"notes", id.notes}};
  nlohmann::json provenance = {{"runs", runs}, {"max_condition_number", options.max_condition_number}};
  provenance.update(report);
  return storeFittedModel(g, store, machine, id.curves, named, options.method, provenance, report);
}

int modelList(const Globals& g) {
  storage::Store store(g.db);
  nlohmann::json list = nlohmann::json::array();
  for (const auto& m : store.listModels()) {
    if (g.json) {
      list.push_back({{"id", m.id}, {"name", m.name}, {"method", m.method}, {"created_at", m.created_at},
                      {"provenance", nlohmann::json::parse(m.provenance_json)}});
    } else {
      *g.out << fmt::format("{:>4}  {:<24} {:<9} {}\n", m.id, m.created_at, m.method, m.name);
    }
  }
  if (g.json) *g.out << nlohmann::json{{"models", list}}.dump() << "\n";
  return 0;
}

int modelPredict(const Globals& g, storage::Id model_id, const std::string& grid, const std::string& points_csv,
                 const std::string& out_csv) {
  if (grid.empty() == points_csv.empty()) throw InputError("give exactly one of --grid and --points");
  storage::Store store(g.db);
  const auto model = acquisition::loadModel(store, model_id);
  if (model.kinematics().coordinates().size() != 3) {
    throw InputError("model " + std::to_string(model_id) + " is not a 3-axis machine: predict takes x, y, z");
  }
  std::vector<Eigen::VectorXd> points;
  std::vector<Eigen::Vector3d> errors;
  if (grid.empty()) {
    points = csvPoints(points_csv);
    for (const auto& q : points) errors.push_back(model.predictUm(q));
  } else {
    const auto axes = gridAxes(model, grid);
    points = gridPoints(axes);
    errors = model.predictGridUm(axes);
  }
  nlohmann::json list = nlohmann::json::array();
  std::ostringstream csv;
  csv << "x_mm,y_mm,z_mm,ex_um,ey_um,ez_um,sx_um,sy_um,sz_um\n";
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Eigen::VectorXd& q = points[i];
    const Eigen::Vector3d& e = errors[i];
    const Eigen::Vector3d s = model.sigmaUm(q);
    if (g.json) {
      list.push_back({{"x_mm", q(0)}, {"y_mm", q(1)}, {"z_mm", q(2)}, {"ex_um", e(0)}, {"ey_um", e(1)}, {"ez_um", e(2)},
                      {"sx_um", s(0)}, {"sy_um", s(1)}, {"sz_um", s(2)}});
    } else {
      csv << fmt::format("{},{},{},{:.4f},{:.4f},{:.4f},{:.4f},{:.4f},{:.4f}\n", q(0), q(1), q(2), e(0), e(1), e(2), s(0),
                         s(1), s(2));
    }
  }
  if (g.json) {
    *g.out << nlohmann::json{{"model_id", model_id}, {"points", list}}.dump() << "\n";
  } else if (out_csv.empty()) {
    *g.out << csv.str();
  } else {
    std::ofstream out(out_csv);
    if (!(out << csv.str())) throw InputError(out_csv + ": cannot write");
    *g.out << fmt::format("{} points written to {}\n", points.size(), out_csv);
  }
  return 0;
}

int modelKeyErrors(const Globals& g, storage::Id model_id, const std::string& at, int sobol_samples) {
  storage::Store store(g.db);
  const auto model = acquisition::loadModel(store, model_id);
  const Eigen::VectorXd q = pointOrCentre(model, at);
  const auto keys = model.keyErrors(q);
  std::vector<processing::SobolIndex> sobol;
  if (sobol_samples > 0) sobol = processing::sobolFirstOrder(model, q, sobol_samples, 20261122);
  const Eigen::Vector3d sigma = model.sigmaUm(q);
  nlohmann::json list = nlohmann::json::array();
  for (const auto& k : keys) {
    nlohmann::json item = {{"name", k.name}, {"share_x", k.share[0]}, {"share_y", k.share[1]}, {"share_z", k.share[2]}};
    for (const auto& s : sobol) {
      if (s.name == k.name) item["sobol"] = {s.first_order[0], s.first_order[1], s.first_order[2]};
    }
    list.push_back(item);
  }
  if (g.json) {
    *g.out << nlohmann::json{{"model_id", model_id},
                             {"at", std::vector<double>(q.begin(), q.end())},
                             {"sigma_um", {sigma(0), sigma(1), sigma(2)}},
                             {"key_errors", list}}
                  .dump()
           << "\n";
    return 0;
  }
  *g.out << fmt::format("key errors of model {} at ({}): share of each error in the variance of E\n", model_id,
                        fmt::join(std::vector<double>(q.begin(), q.end()), ", "));
  *g.out << fmt::format("  sigma of E: x {:.3f} um, y {:.3f} um, z {:.3f} um\n", sigma(0), sigma(1), sigma(2));
  *g.out << fmt::format("  {:<6} {:>8} {:>8} {:>8}{}\n", "error", "x", "y", "z", sobol.empty() ? "" : "   Sobol x / y / z");
  for (const auto& item : list) {
    if (item["share_x"].get<double>() + item["share_y"].get<double>() + item["share_z"].get<double>() < 1e-6) continue;
    std::string line = fmt::format("  {:<6} {:>8.3f} {:>8.3f} {:>8.3f}", item["name"].get<std::string>(),
                                   item["share_x"].get<double>(), item["share_y"].get<double>(),
                                   item["share_z"].get<double>());
    if (item.contains("sobol")) {
      line += fmt::format("   {:.3f} / {:.3f} / {:.3f}", item["sobol"][0].get<double>(), item["sobol"][1].get<double>(),
                          item["sobol"][2].get<double>());
    }
    *g.out << line << "\n";
  }
  return 0;
}

int modelBands(const Globals& g, storage::Id model_id, const std::string& plane_text, const std::string& at, int grid_n) {
  const processing::Plane plane = processing::parsePlane(plane_text);
  if (grid_n < 1 || grid_n > 200) throw InputError("--grid must be 1..200");
  storage::Store store(g.db);
  const auto model = acquisition::loadModel(store, model_id);
  if (model.kinematics().coordinates().size() != 3) throw InputError("bands need a 3-axis model");
  const Eigen::VectorXd centre = pointOrCentre(model, at);
  const int a = plane == processing::Plane::kYZ ? 1 : 0;
  const int b = plane == processing::Plane::kXY ? 1 : 2;
  const auto [a0, a1] = model.coordinateRange(a);
  const auto [b0, b1] = model.coordinateRange(b);
  nlohmann::json list = nlohmann::json::array();
  double widest = 0.0, k = 3.0;
  for (int i = 0; i < grid_n; ++i) {
    for (int j = 0; j < grid_n; ++j) {
      Eigen::VectorXd q = centre;
      q(a) = grid_n == 1 ? centre(a) : a0 + (a1 - a0) * i / (grid_n - 1);
      q(b) = grid_n == 1 ? centre(b) : b0 + (b1 - b0) * j / (grid_n - 1);
      const auto band = processing::planeBand(model, plane, q);
      k = band.coverage_k;
      widest = std::max(widest, band.widestBandUm());
      const double sa = std::sqrt(band.covariance[0]), sb = std::sqrt(band.covariance[1]);
      list.push_back({{"x_mm", q(0)}, {"y_mm", q(1)}, {"z_mm", q(2)}, {"mean_um", band.mean_um},
                      {"sigma_um", {sa, sb}}, {"correlation", sa > 0 && sb > 0 ? band.covariance[2] / (sa * sb) : 0.0},
                      {"band_um", band.widestBandUm()}});
    }
  }
  if (g.json) {
    *g.out << nlohmann::json{{"model_id", model_id}, {"plane", processing::planeName(plane)}, {"coverage_k", k},
                             {"widest_band_um", widest}, {"points", list}}
                  .dump()
           << "\n";
    return 0;
  }
  *g.out << fmt::format("plane {} of model {}: error band +-{:.2f} sigma (3 sigma, t-corrected for the repeats)\n",
                        processing::planeName(plane), model_id, k);
  *g.out << fmt::format("{:>9} {:>9} {:>9} {:>9} {:>9} {:>10}\n", "x_mm", "y_mm", "z_mm", "mean_a", "mean_b", "band_um");
  for (const auto& p : list) {
    *g.out << fmt::format("{:>9.2f} {:>9.2f} {:>9.2f} {:>9.3f} {:>9.3f} {:>10.3f}\n", p["x_mm"].get<double>(),
                          p["y_mm"].get<double>(), p["z_mm"].get<double>(), p["mean_um"][0].get<double>(),
                          p["mean_um"][1].get<double>(), p["band_um"].get<double>());
  }
  *g.out << fmt::format("widest band: +-{:.3f} um\n", widest);
  return 0;
}

int modelValidate(const Globals& g, storage::Id model_id, const std::vector<storage::Id>& runs) {
  storage::Store store(g.db);
  const auto model = acquisition::loadModel(store, model_id);
  const auto lines = acquisition::linesFromRuns(store, runs, model.kinematics());
  nlohmann::json out = nlohmann::json::array();
  if (!g.json) *g.out << "run    error  points   RMS      peak     (um or urad; the line's zero removed)\n";
  std::size_t outside = 0;
  for (std::size_t i = 0; i < lines.size(); ++i) {
    const auto c = processing::compareLine(model, lines[i]);
    nlohmann::json nodes = nlohmann::json::array();
    for (std::size_t n = 0; n < c.position_mm.size(); ++n) {
      nodes.push_back({{"position_mm", c.position_mm[n]},
                       {"measured", c.measured[n]},
                       {"predicted", c.predicted[n] + c.offset},
                       {"residual", c.residual[n]},
                       {"sigma", c.sigma[n]}});
    }
    const nlohmann::json summary = {{"run_id", runs[i]},         {"measures", lines[i].measures},
                                    {"points", c.residual.size()}, {"outside", c.outside},
                                    {"rms", c.rms},                {"peak", c.peak},
                                    {"offset", c.offset}};
    nlohmann::json result = summary;
    result["nodes"] = nodes;
    store.addResult(runs[i], "model-validation", kVersion, nlohmann::json{{"model_id", model_id}}.dump(), result.dump());
    out.push_back(result);
    if (!g.json) {
      *g.out << fmt::format("{:<6} {:<6} {:>6}   {:<8.3f} {:<8.3f}\n", runs[i], lines[i].measures, c.residual.size(), c.rms,
                            c.peak);
    }
    outside += c.outside;
  }
  if (!g.json && outside > 0) {
    *g.err << fmt::format("note: {} point(s) outside the range the model was measured over were not compared\n", outside);
  }
  if (g.json) *g.out << nlohmann::json{{"model_id", model_id}, {"runs", out}}.dump() << "\n";
  return 0;
}

int modelCompensation(const Globals& g, storage::Id model_id, const CompensationOptions& o) {
  storage::Store store(g.db);
  const auto record = store.model(model_id);
  const auto model = acquisition::modelOf(record);
  const auto& coords = model.kinematics().coordinates();
  std::string lower = o.axis;
  std::transform(lower.begin(), lower.end(), lower.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  const auto it = std::find(coords.begin(), coords.end(), lower);
  if (it == coords.end() || lower.size() != 1 || lower[0] < 'x' || lower[0] > 'z') {
    throw InputError(fmt::format("model {} has no linear axis '{}' (its coordinates: {})", model_id, o.axis, fmt::join(coords, ", ")));
  }
  const int coordinate = static_cast<int>(it - coords.begin());
  const auto [range_lo, range_hi] = model.coordinateRange(coordinate);
  const double from = o.from_mm ? *o.from_mm : range_lo, to = o.to_mm ? *o.to_mm : range_hi;
  if (!(to > from) || !(o.step_mm > 0.0)) throw InputError(fmt::format("compensation: no positions from {} to {} mm every {} mm", from, to, o.step_mm));
  // The positioning reading along the axis at the tool point, the other axes at --at: what a
  // linear run of the axis reads, and the model's extensions for those readings.
  processing::MeasuredLine line;
  line.id = fmt::format("model {} axis {}", model_id, o.axis);
  line.measures = fmt::format("E{}{}", static_cast<char>(std::toupper(lower[0])), static_cast<char>(std::toupper(lower[0])));
  line.coordinate = coordinate;
  line.q = pointOrCentre(model, o.at);
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
  const auto extensions = processing::applyExtensions(acquisition::extensionsFor(record, "linear", line.measures), d);
  const Eigen::VectorXd& added = extensions.values;
  const auto& applied = extensions.applied;
  const auto& left_out = extensions.left_out;
  nlohmann::json rows = nlohmann::json::array();
  std::ostringstream csv;
  csv << "position_mm,deviation_up_um,deviation_down_um,correction_up_um,correction_down_um\n";
  for (Eigen::Index i = 0; i < n; ++i) {
    const double up = c.predicted[static_cast<std::size_t>(i)] + added(i), down = c.predicted[static_cast<std::size_t>(i)] + added(n + i);
    rows.push_back({{"position_mm", position(i)}, {"deviation_up_um", up}, {"deviation_down_um", down}, {"correction_up_um", -up},
                    {"correction_down_um", -down}});
    csv << fmt::format("{},{:.4f},{:.4f},{:.4f},{:.4f}\n", position(i), up, down, -up, -down);
  }
  if (g.json) {
    *g.out << nlohmann::json{{"model_id", model_id}, {"axis", o.axis}, {"reading", line.measures}, {"extensions_applied", applied},
                             {"extensions_left_out", left_out}, {"rows", rows}}
                  .dump()
           << "\n";
    return 0;
  }
  if (o.output_path.empty()) {
    *g.out << csv.str();
  } else {
    std::ofstream out(o.output_path);
    if (!(out << csv.str())) throw InputError(o.output_path + ": cannot write");
    *g.out << fmt::format("{} positions written to {}\n", n, o.output_path);
  }
  if (!applied.empty()) *g.err << fmt::format("extensions included: {}\n", fmt::join(applied, ", "));
  if (!left_out.empty()) {
    *g.err << fmt::format("extensions left out (they depend on time or temperatures, not on the position): {}\n", fmt::join(left_out, ", "));
  }
  if (c.outside > 0) *g.err << fmt::format("note: {} position(s) outside the model's measured range were left out\n", c.outside);
  return 0;
}

}  // namespace mtcal::app
