#include "mtcal/acquisition/diagnosis_data.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>
#include <numbers>

#include "mtcal/acquisition/circle_measurements.h"
#include "mtcal/acquisition/error_models.h"
#include "mtcal/acquisition/est_run.h"
#include "mtcal/acquisition/gantry_measurements.h"
#include "mtcal/acquisition/linear_plan.h"
#include "mtcal/acquisition/thermal_data.h"
#include "mtcal/error.h"
#include "mtcal/processing/line_identification.h"

namespace mtcal::acquisition {
namespace {

Eigen::VectorXd vec(const std::vector<double>& v) {
  return Eigen::Map<const Eigen::VectorXd>(v.data(), static_cast<Eigen::Index>(v.size()));
}

/// A channel's unit from its name's last part (coolant_temp_c: degC; hydraulic_pressure_bar:
/// bar); empty when it names none.
std::string unitOfChannel(const std::string& name) {
  static const std::pair<const char*, const char*> units[] = {
      {"_c", "degC"}, {"_k", "K"},   {"_pa", "Pa"}, {"_hpa", "hPa"}, {"_bar", "bar"}, {"_pct", "%"},
      {"_mm", "mm"},  {"_um", "um"}, {"_s", "s"},   {"_v", "V"},     {"_a", "A"}};
  for (const auto& [suffix, unit] : units) {
    const std::string s = suffix;
    if (name.size() > s.size() && name.compare(name.size() - s.size(), s.size(), s) == 0) return unit;
  }
  return "";
}

/// The environment unit's columns of a linear run, where every target has one.
void environmentChannels(const std::vector<storage::TargetRecord>& targets,
                         std::vector<processing::DiagnosisVariable>& out) {
  using Field = std::optional<double> storage::TargetRecord::*;
  const std::pair<const char*, Field> fields[] = {{"air_temp_c", &storage::TargetRecord::air_temp_c},
                                                  {"air_pressure_pa", &storage::TargetRecord::air_pressure_pa},
                                                  {"humidity_pct", &storage::TargetRecord::humidity_pct},
                                                  {"material_temp_c", &storage::TargetRecord::material_temp_c}};
  // A quantity no target has is not a channel; one some targets lack is, with those values
  // missing (the diagnosis says it does not use it, rather than it vanishing unsaid).
  for (const auto& [name, field] : fields) {
    std::vector<double> v;
    for (const auto& t : targets) v.push_back((t.*field).value_or(std::numeric_limits<double>::quiet_NaN()));
    if (std::any_of(v.begin(), v.end(), [](double x) { return !std::isnan(x); }))
      out.push_back({name, unitOfChannel(name), vec(v)});
  }
}

/// The rotations of the moving axis' carriage that an offset turns into a reading along it
/// (pitch and yaw; not the roll about the axis itself).
std::vector<std::string> abbeAngles(const std::string& axis) {
  if (axis == "X" || axis == "x") return {"EBX", "ECX"};
  if (axis == "Y" || axis == "y") return {"EAY", "ECY"};
  if (axis == "Z" || axis == "z") return {"EAZ", "EBZ"};
  return {};
}

/// Adds the model's extensions for readings of `kind` (and out.measures) to the prediction, and
/// says which in the model's description; `predicts_alone`: its geometry predicts the readings
/// (else, with no extension applied, the description says it predicts nothing).
void addExtensions(const storage::ModelRecord& record, const std::string& kind, RunDiagnosisInput& out,
                   bool predicts_alone = true) {
  const auto added = processing::applyExtensions(extensionsFor(record, kind, out.measures), out.data);
  out.data.simulated += added.values;
  out.applied = added.applied;
  out.left_out = added.left_out;
  for (std::size_t k = 0; k < added.left_out.size(); ++k) {
    out.data.notes.push_back(fmt::format("the model's {} extension was left out: {}", added.left_out[k], added.why[k]));
  }
  if (!out.applied.empty()) {
    // Listed unless they are every extension the version has and its name lists them already
    // ("x.csv + thermal_drift (run 1)").
    const auto all = modelExtensions(record);
    const auto applied = [&](const std::string& effect) {
      return std::find(out.applied.begin(), out.applied.end(), effect) != out.applied.end();
    };
    const bool named =
        out.left_out.empty() &&
        std::all_of(all.begin(), all.end(), [&](const auto& e) { return applied(e.extension.effect); }) &&
        std::all_of(out.applied.begin(), out.applied.end(),
                    [&](const std::string& e) { return record.name.find(" + " + e + " ") != std::string::npos; });
    out.data.model_description += named ? std::string(" with its extensions")
                                        : fmt::format(" with its extensions ({})", fmt::join(out.applied, ", "));
  } else if (!predicts_alone) {
    out.data.model_description +=
        out.left_out.empty()
            ? fmt::format(": it has no {} extensions, so it predicts nothing", kind)
            : fmt::format(": none of its {} extensions applies (see the notes), so it predicts nothing", kind);
  }
}

RunDiagnosisInput linearInput(storage::Store& store, const storage::RunInfo& info, const RunDiagnosisOptions& options) {
  const auto targets = store.targets(info.id);
  processing::LinearRunInput in;
  in.source = fmt::format("run {}", info.id);
  in.min_knot_spacing_mm = options.min_knot_spacing_mm;
  bool any_time = false;
  for (const auto& t : targets) {
    in.position_mm.push_back(t.target_mm);
    in.direction.push_back(t.direction >= 0 ? 1 : -1);
    in.cycle.push_back(t.cycle);
    in.deviation_um.push_back(t.deviation_um);
    any_time = any_time || t.time_s.has_value();
    in.time_s.push_back(t.time_s.value_or(std::numeric_limits<double>::quiet_NaN()));  // missing: said
  }
  if (!any_time) in.time_s.clear();
  RunDiagnosisInput out;
  out.run = info;
  if (!info.axis.empty()) {
    // A positioning run's reversal is its drive's lost motion, which circles of the axis read too.
    const auto setup = lineSetupOf(info);
    out.measures = measuredError(setup);
    in.measures = out.measures;
  }
  environmentChannels(targets, in.channels);
  const auto names = store.channelNames(info.id);
  const auto rows = store.channelRows(info.id);
  for (std::size_t c = 0; c < names.size(); ++c) {
    Eigen::VectorXd v(static_cast<Eigen::Index>(rows.size()));
    for (std::size_t i = 0; i < rows.size(); ++i)
      v(static_cast<Eigen::Index>(i)) = rows[i][c].value_or(std::numeric_limits<double>::quiet_NaN());
    in.channels.push_back({names[c], unitOfChannel(names[c]), v});
  }
  if (!options.model_id) {
    out.data = processing::linearDiagnosisData(in);
    return out;
  }
  // Against a model: its prediction of every target, the angles an offset turns into the
  // reading, and the model's extensions for this kind of reading.
  const auto record = store.model(*options.model_id);
  const auto model = modelOf(record);
  const auto lines = linesFromRuns(store, {info.id}, model.kinematics());
  const auto& line = lines.front();
  out.measures = line.measures;
  const auto comparison = processing::compareLine(model, line);
  std::map<double, std::size_t> predicted;  // a position's index in the comparison
  for (std::size_t k = 0; k < comparison.position_mm.size(); ++k) predicted[comparison.position_mm[k]] = k;
  processing::LinearRunInput kept = in;
  kept.position_mm.clear();
  kept.direction.clear();
  kept.cycle.clear();
  kept.deviation_um.clear();
  kept.time_s.clear();
  std::vector<std::size_t> rows_kept;  // a kept reading's row
  std::vector<Eigen::Index> compared;  // and its position's in the comparison
  for (std::size_t i = 0; i < in.position_mm.size(); ++i) {
    const auto it = predicted.find(in.position_mm[i]);
    if (it == predicted.end()) continue;
    rows_kept.push_back(i);
    compared.push_back(static_cast<Eigen::Index>(it->second));
    kept.position_mm.push_back(in.position_mm[i]);
    kept.direction.push_back(in.direction[i]);
    kept.cycle.push_back(in.cycle[i]);
    kept.deviation_um.push_back(in.deviation_um[i]);
    if (!in.time_s.empty()) kept.time_s.push_back(in.time_s[i]);
    kept.simulated_um.push_back(comparison.predicted[it->second]);
  }
  if (comparison.predicted_error_factor.size()) {  // the model's own error, where it states it
    kept.simulated_error_factor_um = comparison.predicted_error_factor(compared, Eigen::all);
  }
  for (auto& c : kept.channels) c.values = c.values(rows_kept).eval();
  kept.model_description = fmt::format("model {} ({})", record.id, record.name);
  std::vector<std::pair<std::string, int>> angles;  // the model's terms among them
  for (const auto& name : abbeAngles(info.axis)) {
    try {
      angles.emplace_back(name, model.kinematics().termIndex(name));
    } catch (const InputError&) {
    }
  }
  const auto points = static_cast<Eigen::Index>(kept.position_mm.size());
  for (const auto& [name, term] : angles)
    kept.model_angles_urad.push_back({name + "_urad", "urad", Eigen::VectorXd(points)});
  for (Eigen::Index i = 0; i < points; ++i) {
    Eigen::VectorXd q = line.q;
    q(line.coordinate) = kept.position_mm[static_cast<std::size_t>(i)];
    const Eigen::VectorXd errors = model.errorsAt(q);
    for (std::size_t a = 0; a < angles.size(); ++a) kept.model_angles_urad[a].values(i) = errors(angles[a].second);
  }
  out.data = processing::linearDiagnosisData(kept);
  if (comparison.outside > 0) {
    out.data.notes.push_back(fmt::format("{} target(s) outside the range the model was measured over were left out",
                                         in.position_mm.size() - rows_kept.size()));
  }
  addExtensions(record, "linear", out);
  return out;
}

/// The index in the model's coordinates of the linear axis `axis` (X, Y or Z, either case).
/// @throws InputError when the model's machine has no such axis
int coordinateOf(const processing::ErrorModel& model, std::string axis) {
  std::transform(axis.begin(), axis.end(), axis.begin(), [](unsigned char c) { return std::tolower(c); });
  const auto& coordinates = model.kinematics().coordinates();
  const auto it = std::find(coordinates.begin(), coordinates.end(), axis);
  if (it == coordinates.end())
    throw InputError(fmt::format("model's machine '{}' has no axis {}", model.kinematics().name(), axis));
  return static_cast<int>(it - coordinates.begin());
}

/// The bar's length change a model predicts on a circle: the tool ball at p(a) = c + R u(a) and
/// the table ball set where the tool was at the centre, so with E = P_ideal - P (the model's
/// spatial error) the length changes by -u(a) . (E(p(a)) - E(c)) to first order.
/// @throws InputError when the model's machine lacks one of the plane's axes
Eigen::VectorXd circlePrediction(const processing::ErrorModel& model, processing::Plane plane,
                                 const Eigen::Vector3d& centre_mm, double radius_mm,
                                 const std::vector<double>& angle_deg, std::vector<std::string>& notes) {
  const auto& coordinates = model.kinematics().coordinates();
  Eigen::Vector3i index;
  for (int axis = 0; axis < 3; ++axis) index(axis) = coordinateOf(model, std::string(1, "xyz"[axis]));
  const auto axes = processing::planeAxes(plane);
  auto errorAt = [&](const Eigen::Vector3d& p, bool& outside) {
    Eigen::VectorXd q = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(coordinates.size()));
    for (int axis = 0; axis < 3; ++axis) {
      q(index(axis)) = p(axis);
      const auto [lo, hi] = model.coordinateRange(index(axis));
      outside = outside || (hi > lo && (p(axis) < lo || p(axis) > hi));
    }
    return model.predictUm(q);
  };
  bool outside = false;
  const Eigen::Vector3d at_centre = errorAt(centre_mm, outside);
  Eigen::VectorXd out(static_cast<Eigen::Index>(angle_deg.size()));
  for (std::size_t k = 0; k < angle_deg.size(); ++k) {
    const double a = angle_deg[k] * std::numbers::pi / 180.0;
    Eigen::Vector3d u = Eigen::Vector3d::Zero();
    u(axes.first) = std::cos(a);
    u(axes.second) = std::sin(a);
    out(static_cast<Eigen::Index>(k)) = -u.dot(errorAt(centre_mm + radius_mm * u, outside) - at_centre);
  }
  if (outside)
    notes.push_back("the circle leaves the range the model was measured over: its errors there are extrapolated");
  return out;
}

RunDiagnosisInput circleInput(storage::Store& store, const storage::RunInfo& info, const RunDiagnosisOptions& options) {
  const auto plan = nlohmann::json::parse(info.plan_json);
  processing::CircleRunInput in;
  in.source = fmt::format("run {}", info.id);
  in.radius_mm = plan.at("radius_mm").get<double>();
  in.feed_mm_per_min = plan.value("feed_mm_per_min", kAssumedFeedMmPerMin);
  in.plane = plan.value("plane", std::string());
  bool timed = true;
  for (const auto& p : store.circlePoints(info.id)) {
    in.angle_deg.push_back(p.angle_deg);
    in.direction.push_back(p.direction == "cw" ? -1 : 1);
    in.deviation_um.push_back(p.deviation_um);
    timed = timed && p.time_s.has_value();
    in.time_s.push_back(p.time_s.value_or(0.0));
  }
  if (!timed) in.time_s.clear();
  // A circle's extensions apply to circles of its plane and radius (a shape's size on the bar
  // depends on both).
  RunDiagnosisInput out{processing::circleDiagnosisData(in),
                        fmt::format("{} R{:g} mm", plan.value("plane", std::string("?")), in.radius_mm),
                        {},
                        {},
                        info};
  if (auto note = feedAssumedNote(plan)) out.data.notes.push_back(*note);
  if (!options.model_id) return out;
  const auto record = store.model(*options.model_id);
  out.data.model_description = fmt::format("model {} ({})", record.id, record.name);
  const bool placed = plan.contains("centre_mm") && plan.contains("plane");  // the geometry can predict it
  if (placed) {
    const auto& c = plan.at("centre_mm");
    const Eigen::Vector3d centre(c.at(0).get<double>(), c.at(1).get<double>(), c.at(2).get<double>());
    out.data.simulated = circlePrediction(modelOf(record), processing::parsePlane(plan.at("plane").get<std::string>()),
                                          centre, in.radius_mm, in.angle_deg, out.data.notes);
  } else {
    if (plan.contains("plane")) {  // a model of a machine without the circle's axes is another machine's
      const auto model = modelOf(record);
      const auto axes = processing::planeAxes(processing::parsePlane(plan.at("plane").get<std::string>()));
      for (const int axis : {axes.first, axes.second}) coordinateOf(model, std::string(1, "xyz"[axis]));
    }
    out.data.notes.push_back(
        "to predict a circle from the model's geometry, mtcal needs where it was measured: import it with "
        "--centre-mm X,Y,Z (the table ball's position in machine coordinates; run ballbar records it)");
    out.data.model_description = fmt::format("model {} ({}; the circle's centre unknown)", record.id, record.name);
  }
  addExtensions(record, "circle", out, placed);
  return out;
}

/// Against a model for readings its geometry does not predict (thermal drift, tracker holes):
/// its extensions for the kind, found by diagnosing earlier runs.
void againstExtensionsOnly(storage::Store& store, const RunDiagnosisOptions& options, const std::string& kind,
                           RunDiagnosisInput& out) {
  if (!options.model_id) return;
  const auto record = store.model(*options.model_id);
  out.data.model_description = fmt::format("model {} ({})", record.id, record.name);
  out.data.notes.push_back(fmt::format(
      "a geometric model does not predict {} readings: only its {} extensions (causes found in earlier runs) are "
      "applied",
      kind, kind));
  addExtensions(record, kind, out, false);
}

RunDiagnosisInput thermalInput(storage::Store& store, const storage::RunInfo& info,
                               const RunDiagnosisOptions& options) {
  std::string target = options.thermal_target;
  if (target.empty()) {
    for (const auto& c : store.thermalChannels(info.id)) {
      if (c.kind == "displacement") {
        target = c.name;
        break;
      }
    }
    if (target.empty()) throw InputError(fmt::format("run {} has no displacement channel to diagnose", info.id));
  }
  const auto td = thermalDataOfRun(store, info.id, target);
  processing::ThermalRunInput in;
  in.source = fmt::format("run {} ({})", info.id, target);
  std::vector<Eigen::Index> rows;
  for (Eigen::Index i = 0; i < td.target_um.size(); ++i) {
    if (std::isnan(td.target_um(i))) continue;
    rows.push_back(i);
    in.time_s.push_back(td.time_s(i));
    in.segment.push_back(td.segment[static_cast<std::size_t>(i)]);
    in.displacement_um.push_back(td.target_um(i));
  }
  for (std::size_t s = 0; s < td.sensors.size(); ++s) {
    in.temperatures_c.push_back(
        {td.sensors[s], "degC", td.temperature_c.col(static_cast<Eigen::Index>(s))(rows).eval()});
  }
  auto data = processing::thermalDiagnosisData(in);
  if (rows.size() < static_cast<std::size_t>(td.target_um.size())) {
    data.notes.push_back(fmt::format("{} sample(s) without a displacement were left out",
                                     td.target_um.size() - static_cast<Eigen::Index>(rows.size())));
  }
  RunDiagnosisInput out{std::move(data), target, {}, {}, info};
  againstExtensionsOnly(store, options, "thermal", out);
  return out;
}

/// What a model predicts of a three-probe run's probe 3 less its two-probe prediction. Probe i
/// (0, 1, 2) sits i d along the axis from the tool point and reads the surface plus the
/// carriage's part E_i = (P_ideal - P) at its tip, along the measured direction; probe 3 less
/// the two-probe prediction is E_3(x_k) - E_2(x_k) - E_2(x_k+1) + E_1(x_k+1): the surface and
/// the carriage's translation cancel, its rotation's change per step times d stays (yaw for Y
/// readings of an X axis, pitch for Z readings). The other axes stand where the plan put them,
/// or at the model's workspace centre.
/// @throws InputError when the model's machine lacks the plan's axis
Eigen::VectorXd estPrediction(const processing::ErrorModel& model, const EstPlan& plan,
                              const std::vector<double>& position_mm, std::vector<std::string>& notes) {
  const auto& coordinates = model.kinematics().coordinates();
  const int moving = coordinateOf(model, plan.axis);
  const int along = static_cast<int>(std::string("XYZ").find(plan.axis.front()));
  const int measured = static_cast<int>(std::string("XYZ").find(plan.measures.front()));
  if (along == static_cast<int>(std::string::npos) || measured == static_cast<int>(std::string::npos)) {
    throw InputError(
        fmt::format("the plan's axis {} or measured direction {} is not X, Y or Z", plan.axis, plan.measures));
  }
  Eigen::VectorXd q = model.workspaceCentre();
  bool placed = true;
  for (std::size_t c = 0; c < coordinates.size(); ++c) {
    if (static_cast<int>(c) == moving) continue;
    std::string name = coordinates[c];
    std::transform(name.begin(), name.end(), name.begin(), [](unsigned char ch) { return std::toupper(ch); });
    const auto it = plan.line_position_mm.find(name);
    if (it != plan.line_position_mm.end())
      q(static_cast<Eigen::Index>(c)) = it->second;
    else
      placed = false;
  }
  if (!placed) {
    notes.push_back(
        "the run does not record where the other axes stood: the model is read with them at its workspace centre");
  }
  const auto [lo, hi] = model.coordinateRange(moving);
  const auto& kinematics = model.kinematics();
  std::vector<std::array<double, 3>> carriage;  // E at each probe's tip, per step, um
  for (const double x : position_mm) {
    q(moving) = x;
    const Eigen::VectorXd errors = model.errorsAt(q), none = Eigen::VectorXd::Zero(errors.size());
    std::array<double, 3> at{};
    for (int i = 0; i < 3; ++i) {
      Eigen::Vector3d tip = kinematics.toolPoint();
      tip(along) += i * plan.spacing_mm;
      at[static_cast<std::size_t>(i)] =
          1000.0 * (kinematics.actualPoint(q, none, tip) - kinematics.actualPoint(q, errors, tip))(measured);
    }
    carriage.push_back(at);
  }
  if (std::any_of(position_mm.begin(), position_mm.end(), [&](double x) { return hi > lo && (x < lo || x > hi); }))
    notes.push_back("the run leaves the range the model was measured over: its errors there are extrapolated");
  Eigen::VectorXd out(static_cast<Eigen::Index>(position_mm.size() - 1));
  for (std::size_t k = 0; k + 1 < position_mm.size(); ++k) {
    out(static_cast<Eigen::Index>(k)) = carriage[k][2] - carriage[k][1] - carriage[k + 1][1] + carriage[k + 1][0];
  }
  return out;
}

RunDiagnosisInput estInput(storage::Store& store, const storage::RunInfo& info, const RunDiagnosisOptions& options) {
  // Each probe's reading at a step is the mean of the readings captured there; their scatter
  // states the noise (a step read once states none).
  processing::EstRunInput in = storedEstRun(store, info);
  if (in.v3_um.empty()) {
    throw InputError(
        fmt::format("run {} has two probes: the two-probe separation reproduces every reading, so nothing can be "
                    "diagnosed from it alone; a third probe (plan probes: 3) gives the redundancy",
                    info.id));
  }
  // The zeros the run measured (on a reference flat, or given with its import) are taken off,
  // as the separation takes them off: a probe offset named is what they left.
  const auto zeroing = storedZeroing(store, info.id);
  const bool zeroed = zeroing && zeroing->zero_um.size() == 3;
  if (zeroed) {
    for (std::size_t p = 0; p < 3; ++p)
      for (auto& v : in.probeUm(p)) v -= zeroing->zero_um[p];
  }
  RunDiagnosisInput out{processing::estDiagnosisData(in), "", {}, {}, info};
  if (zeroed)
    out.data.notes.push_back(
        fmt::format("the probes' zeros the run measured ({}: z3 - 2 z2 + z1 = {:.4f} um) are taken off the readings: a "
                    "probe_offset named is what they left",
                    zeroing->method, zeroing->combinationUm()));
  if (!options.model_id) return out;
  // Against a model: its carriage rotations predict what probe 3 sees beyond the two-probe
  // prediction (along the plan's line), then its EST extensions.
  const auto plan = EstPlan::fromJson(nlohmann::json::parse(info.plan_json), fmt::format("run {} plan", info.id));
  const auto record = store.model(*options.model_id);
  out.data.model_description = fmt::format(
      "the two-probe separation of probes 1 and 2, plus model {} ({}): its carriage's rotations along the run",
      record.id, record.name);
  out.data.simulated += estPrediction(modelOf(record), plan, in.position_mm, out.data.notes);
  addExtensions(record, "est", out);
  return out;
}

RunDiagnosisInput trackerInput(storage::Store& store, const storage::RunInfo& info,
                               const RunDiagnosisOptions& options) {
  const auto m = loadGantryMeasurements(store, info.id);
  processing::TrackerRunInput in;
  in.source = fmt::format("run {}", info.id);
  in.initial_targets = m.initial_targets;
  for (const auto& hole : m.holes) in.hole_targets.push_back(hole.targets);
  in.c_sweep = m.c_sweep;
  in.a_sweep = m.a_sweep;
  RunDiagnosisInput out{processing::trackerDiagnosisData(in), "", {}, {}, info};
  againstExtensionsOnly(store, options, "tracker", out);
  return out;
}

}  // namespace

std::vector<AppliedExtension> modelExtensions(const storage::ModelRecord& record) {
  std::vector<AppliedExtension> out;
  if (record.provenance_json.empty()) return out;
  try {
    const auto provenance = nlohmann::json::parse(record.provenance_json);
    if (!provenance.is_object() || !provenance.contains("extensions")) return out;
    for (const auto& e : provenance.at("extensions")) {
      out.push_back({processing::ModelExtension::fromJson(e), e.value("kind", "linear"), e.value("measures", ""),
                     e.value("found_in_run", storage::Id{0})});
    }
  } catch (const nlohmann::json::exception& ex) {
    throw InputError(fmt::format("model {}: its extensions are damaged: {}", record.id, ex.what()));
  }
  return out;
}

std::vector<processing::ModelExtension> extensionsFor(const storage::ModelRecord& record, const std::string& kind,
                                                      const std::string& measures) {
  std::vector<processing::ModelExtension> out;
  for (const auto& e : modelExtensions(record)) {
    if (e.kind == kind && (e.measures.empty() || e.measures == measures)) out.push_back(e.extension);
  }
  return out;
}

RunDiagnosisInput diagnosisInputOfRun(storage::Store& store, storage::Id run_id, const RunDiagnosisOptions& options) {
  const auto info = store.run(run_id);
  if (info.kind == storage::run_kind::kLinear) return linearInput(store, info, options);
  if (info.kind == storage::run_kind::kCircle) return circleInput(store, info, options);
  if (info.kind == storage::run_kind::kThermal) return thermalInput(store, info, options);
  if (info.kind == storage::run_kind::kEst) return estInput(store, info, options);
  if (info.kind == storage::run_kind::kGantry) return trackerInput(store, info, options);
  throw InputError(fmt::format("run {} is {}: diagnose takes linear, circle, thermal, est and gantry runs", run_id,
                               storage::run_kind::aRunOf(info.kind)));
}

std::optional<std::string> unfinishedRunWarning(const storage::RunInfo& info) {
  if (info.status == storage::run_status::kCompleted || info.status == storage::run_status::kImported) return {};
  const auto held = fmt::format("{} {}", info.measurement_count, storage::measurementUnit(info.kind));
  if (info.status == storage::run_status::kRunning && !info.stale)
    return fmt::format("run {} is still being recorded ({} so far): what it measures later is not in it", info.id,
                       held);
  const std::string then = info.status == storage::run_status::kInterrupted || info.stale
                               ? fmt::format("; resume it (mtcal resume {}) for the whole plan", info.id)
                               : std::string();
  return fmt::format(
      "run {} is {} after {}: its last cycle or pass may be partial and the rest of its plan is not in "
      "it{}",
      info.id, info.stale ? storage::run_status::kInterrupted : info.status, held, then);
}

std::vector<std::string> importWarnings(const storage::RunInfo& info) {
  std::vector<std::string> out;
  const auto plan = nlohmann::json::parse(info.plan_json, nullptr, false);
  if (!plan.is_object() || !plan.contains("import_warnings") || !plan["import_warnings"].is_array()) return out;
  for (const auto& w : plan["import_warnings"])
    if (w.is_string())
      out.push_back(fmt::format("run {} was imported with a warning: {}", info.id, w.get<std::string>()));
  return out;
}

ExtendedModel saveExtendedModel(storage::Store& store, storage::Id base_model, storage::Id run_id,
                                const std::vector<AppliedExtension>& added, const std::string& software_version) {
  auto record = store.model(base_model);
  nlohmann::json extensions = nlohmann::json::array();
  for (const auto& e : modelExtensions(record)) {
    auto j = e.extension.toJson();
    j["kind"] = e.kind;
    j["measures"] = e.measures;
    extensions.push_back(j);
  }
  std::vector<std::string> effects;
  std::vector<storage::Id> found_in;
  for (const auto& e : added) {
    auto j = e.extension.toJson();
    j["kind"] = e.kind;
    j["measures"] = e.measures;
    j["found_in_run"] = e.found_in_run != 0 ? e.found_in_run : run_id;
    extensions.push_back(j);
    if (std::find(effects.begin(), effects.end(), e.extension.effect) == effects.end())
      effects.push_back(e.extension.effect);
    if (std::find(found_in.begin(), found_in.end(), j["found_in_run"].get<storage::Id>()) == found_in.end())
      found_in.push_back(j["found_in_run"].get<storage::Id>());
  }
  nlohmann::json base_provenance = nlohmann::json::object();
  try {
    base_provenance = nlohmann::json::parse(record.provenance_json.empty() ? "{}" : record.provenance_json);
  } catch (const nlohmann::json::exception&) {
    base_provenance = record.provenance_json;
  }
  record.provenance_json = nlohmann::json{
      {"base_model", base_model},
      {"base_provenance", base_provenance},
      {"diagnosed_run", run_id},
      {"extensions",
       extensions}}.dump();
  std::sort(found_in.begin(), found_in.end());
  record.name = fmt::format("{} + {} ({} {})", record.name, fmt::join(effects, " + "),
                            found_in.size() > 1 ? "runs" : "run", fmt::join(found_in, ", "));
  record.method = "diagnosis";
  record.software_version = software_version;
  for (const auto& stored : store.listModels()) {
    if (stored.method == record.method && stored.name == record.name && stored.machine_json == record.machine_json &&
        stored.provenance_json == record.provenance_json && stored.software_version == record.software_version &&
        store.model(stored.id).error_functions == record.error_functions)
      return {stored.id, true};
  }
  return {store.addModel(record), false};
}

}  // namespace mtcal::acquisition
