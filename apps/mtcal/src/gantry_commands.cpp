// mtcal gantry run / analyze gantry / gantry evaluate / gantry export: point accuracy of a
// gantry drilling machine with a laser tracker (patent CN106017326, docs/gantry.md).

#include <fmt/format.h>

#include <algorithm>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>

#include "commands.h"
#include "mtcal/acquisition/gantry_test.h"
#include "mtcal/services/workshop.h"
#include "mtcal/drivers/registry.h"
#include "mtcal/drivers/uri.h"
#include "mtcal/error.h"
#include "mtcal/services/version.h"

namespace mtcal::app {
namespace {

nlohmann::json vec(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }

processing::GantryOptions evaluationOptions(const GantryEvaluateOptions& o) {
  processing::GantryOptions options;
  if (o.tcp0 == "axes") {
    options.tcp0 = processing::Tcp0Source::kAxes;
  } else if (o.tcp0 == "tool-point") {
    options.tcp0 = processing::Tcp0Source::kToolPoint;
  } else {
    throw InputError("--tcp0 must be axes (the patent's construction) or tool-point (the measured nest)");
  }
  if (o.fit == "auto") {
    options.target_fit = processing::TargetFit::kAuto;
  } else if (o.fit == "patent") {
    options.target_fit = processing::TargetFit::kPatentFrame;
  } else if (o.fit == "lsq") {
    options.target_fit = processing::TargetFit::kLeastSquares;
  } else {
    throw InputError("--fit must be auto, patent or lsq");
  }
  return options;
}

/// Evaluates, prints (text or JSON) and returns the JSON report.
nlohmann::json report(const Globals& g, const processing::GantryMeasurements& m, const GantryEvaluateOptions& o,
                      const processing::TrackerMpe& mpe, int trials, const std::string& title) {
  const auto options = evaluationOptions(o);
  const auto ev = processing::evaluateGantry(m, options);
  std::optional<processing::GantryUncertainty> u;
  if (trials > 0) u = processing::monteCarloGantry(m, options, mpe, trials, o.seed);
  nlohmann::json holes = nlohmann::json::array();
  for (std::size_t i = 0; i < ev.holes.size(); ++i) {
    const auto& h = ev.holes[i];
    nlohmann::json hj{{"id", h.id},
                      {"gantry_position", h.gantry_position},
                      {"np_mm", vec(h.np_mm)},
                      {"tcp_mm", vec(h.tcp_mm)},
                      {"dP_um", vec(h.dp_um)},
                      {"dP_norm_um", h.dp_norm_um},
                      {"dP_perp_um", h.dp_perp_um},
                      {"fit_rms_um", h.fit_rms_um}};
    if (u) {
      hj["dP_sigma_um"] = vec(u->holes[i].dp_sigma_um);
      hj["dP_norm_u95_um"] = u->holes[i].norm_u95_um;
      hj["dP_perp_u95_um"] = u->holes[i].perp_u95_um;
    }
    holes.push_back(hj);
  }
  const auto summaryJson = [](const processing::AccuracySummary& s) {
    return nlohmann::json{{"gantry_position", s.gantry_position}, {"holes", s.holes}, {"mean_dP_um", vec(s.mean_dp_um)},
                          {"mean_norm_um", s.mean_norm_um}, {"max_norm_um", s.max_norm_um}, {"rms_norm_um", s.rms_norm_um},
                          {"mean_perp_um", s.mean_perp_um}, {"max_perp_um", s.max_perp_um}, {"rms_perp_um", s.rms_perp_um},
                          {"worst_hole", s.worst_hole}};
  };
  nlohmann::json per_position = nlohmann::json::array();
  for (std::size_t k = 1; k < ev.summaries.size(); ++k) per_position.push_back(summaryJson(ev.summaries[k]));
  nlohmann::json j{
      {"method", "CN106017326"},
      {"target_fit", ev.target_fit},
      {"tcp0_source", o.tcp0},
      {"frame",
       {{"xy_plane_rms_um", ev.xy_plane.rms_mm * 1000.0},
        {"side_1_rms_um", ev.side_1_rms_um},
        {"side_2_rms_um", ev.side_2_rms_um},
        {"gantry_line_rms_um", ev.gantry_line_rms_um},
        {"gantry_tilt_urad", ev.gantry_tilt_urad},
        {"gantry_passes_spread_urad", ev.gantry_passes_spread_urad},
        {"gantry_outliers", ev.gantry_outliers}}},
      {"c_axis", {{"centre_mm", vec(ev.c_axis.centre)}, {"direction", vec(ev.c_axis.normal)}, {"radius_mm", ev.c_axis.radius_mm},
                  {"radial_rms_um", ev.c_axis.radial_rms_mm * 1000.0}, {"plane_rms_um", ev.c_axis.plane_rms_mm * 1000.0}}},
      {"a_axis", {{"centre_mm", vec(ev.a_axis.centre)}, {"direction", vec(ev.a_axis.normal)}, {"radius_mm", ev.a_axis.radius_mm},
                  {"radial_rms_um", ev.a_axis.radial_rms_mm * 1000.0}, {"plane_rms_um", ev.a_axis.plane_rms_mm * 1000.0}}},
      {"axes_offset_um", ev.axes.distance_mm * 1000.0},
      {"axes_squareness_urad", ev.axes_squareness_urad},
      {"wrist_centre_mm", vec(ev.wrist_centre_mm)},
      {"tcp0_mm", vec(ev.tcp0_mm)},
      {"tcp0_axes_minus_tool_point_um", ev.tcp0_axes_minus_tool_point_um ? vec(*ev.tcp0_axes_minus_tool_point_um) : nlohmann::json()},
      {"holes", holes},
      {"summary", ev.summaries.empty() ? nlohmann::json() : summaryJson(ev.summaries[0])},
      {"per_gantry_position", per_position},
      {"notes", ev.notes}};
  if (u) {
    j["uncertainty"] = {{"trials", u->trials},
                        {"seed", o.seed},
                        {"tracker_mpe",
                         {{"distance_um", mpe.distance_um}, {"distance_um_per_m", mpe.distance_um_per_m},
                          {"transverse_um", mpe.transverse_um}, {"transverse_um_per_m", mpe.transverse_um_per_m}}},
                        {"tcp0_sigma_um", vec(u->tcp0_sigma_um)},
                        {"max_norm_u95_um", u->max_norm_u95_um},
                        {"max_perp_u95_um", u->max_perp_u95_um}};
  }
  if (g.json) return j;
  auto& out = *g.out;
  out << fmt::format("{}\n", title);
  out << fmt::format("gantry point accuracy (patent CN106017326): {} holes, targets by {}, TCP0 from {}\n", ev.holes.size(),
                     ev.target_fit, o.tcp0 == "axes" ? "the A and C axes" : "the tool-point nest");
  out << fmt::format("global frame: XY plane rms {:.1f} um, side faces {:.1f} / {:.1f} um; gantry line rms {:.1f} um, "
                     "tilt {:.1f} urad, passes within {:.1f} urad\n",
                     ev.xy_plane.rms_mm * 1000.0, ev.side_1_rms_um, ev.side_2_rms_um, ev.gantry_line_rms_um,
                     ev.gantry_tilt_urad, ev.gantry_passes_spread_urad);
  for (const auto* axis : {&ev.c_axis, &ev.a_axis}) {
    out << fmt::format("{} axis: centre ({:.3f}, {:.3f}, {:.3f}) mm, direction ({:.6f}, {:.6f}, {:.6f}), radius {:.3f} mm, "
                       "radial rms {:.1f} um, arc {:.0f} deg\n",
                       axis == &ev.c_axis ? "C" : "A", axis->centre.x(), axis->centre.y(), axis->centre.z(), axis->normal.x(),
                       axis->normal.y(), axis->normal.z(), axis->radius_mm, axis->radial_rms_mm * 1000.0, axis->arc_deg);
  }
  out << fmt::format("A and C axes: {:.1f} um apart (common perpendicular), {:+.1f} urad out of square\n",
                     ev.axes.distance_mm * 1000.0, ev.axes_squareness_urad);
  out << fmt::format("wrist centre ({:.3f}, {:.3f}, {:.3f}) mm; TCP0 ({:.3f}, {:.3f}, {:.3f}) mm\n", ev.wrist_centre_mm.x(),
                     ev.wrist_centre_mm.y(), ev.wrist_centre_mm.z(), ev.tcp0_mm.x(), ev.tcp0_mm.y(), ev.tcp0_mm.z());
  if (ev.tcp0_axes_minus_tool_point_um) {
    const auto& d = *ev.tcp0_axes_minus_tool_point_um;
    out << fmt::format("TCP0 from the axes minus the tool-point nest: ({:+.1f}, {:+.1f}, {:+.1f}) um, |{:.1f}| um\n", d.x(), d.y(),
                       d.z(), d.norm());
  }
  out << fmt::format("\n{:<10} {:>3} {:>8} {:>8} {:>8} {:>8} {:>8}{}\n", "hole", "pos", "dX um", "dY um", "dZ um", "|dP| um",
                     "perp um", u ? "  U95 |dP|  U95 perp" : "");
  for (std::size_t i = 0; i < ev.holes.size(); ++i) {
    const auto& h = ev.holes[i];
    out << fmt::format("{:<10} {:>3} {:>8.1f} {:>8.1f} {:>8.1f} {:>8.1f} {:>8.1f}", h.id, h.gantry_position, h.dp_um.x(),
                       h.dp_um.y(), h.dp_um.z(), h.dp_norm_um, h.dp_perp_um);
    if (u) out << fmt::format("  {:>9.1f} {:>9.1f}", u->holes[i].norm_u95_um, u->holes[i].perp_u95_um);
    out << "\n";
  }
  out << "\n";
  for (const auto& s : ev.summaries) {
    out << fmt::format("{:<14} {:>3} holes: |dP| mean {:.1f} max {:.1f} ({}) rms {:.1f} um; perpendicular mean {:.1f} max {:.1f} "
                       "rms {:.1f} um\n",
                       s.gantry_position == 0 ? "all" : fmt::format("position {}", s.gantry_position), s.holes, s.mean_norm_um,
                       s.max_norm_um, s.worst_hole, s.rms_norm_um, s.mean_perp_um, s.max_perp_um, s.rms_perp_um);
  }
  if (u) {
    out << fmt::format("uncertainty (Monte Carlo, {} trials, tracker MPE {:g} um + {:g} um/m along, {:g} um + {:g} um/m across): "
                       "U95 of |dP| up to {:.1f} um, of the perpendicular error up to {:.1f} um\n",
                       u->trials, mpe.distance_um, mpe.distance_um_per_m, mpe.transverse_um, mpe.transverse_um_per_m,
                       u->max_norm_u95_um, u->max_perp_u95_um);
  }
  for (const auto& n : ev.notes) out << "note: " << n << "\n";
  return j;
}

/// JSON for people: nested objects and arrays indented, an array of numbers (a point) on one line.
void writeReadable(std::ostream& out, const nlohmann::json& j, int indent) {
  const std::string pad(static_cast<std::size_t>(indent) * 2, ' '), inner(static_cast<std::size_t>(indent + 1) * 2, ' ');
  const bool flat = !j.is_structured() || (j.is_array() && std::all_of(j.begin(), j.end(), [](const auto& v) { return v.is_primitive(); }));
  if (flat || j.empty()) {
    out << j.dump();
    return;
  }
  out << (j.is_object() ? "{\n" : "[\n");
  std::size_t i = 0;
  for (auto it = j.begin(); it != j.end(); ++it, ++i) {
    out << inner;
    if (j.is_object()) out << nlohmann::json(it.key()).dump() << ": ";
    writeReadable(out, *it, indent + 1);
    out << (i + 1 < j.size() ? ",\n" : "\n");
  }
  out << pad << (j.is_object() ? "}" : "]");
}

nlohmann::json analyzeStored(const Globals& g, storage::Store& store, storage::Id run_id, const GantryEvaluateOptions& o) {
  const auto m = acquisition::loadGantryMeasurements(store, run_id);
  const auto run = store.run(run_id);
  const auto plan = acquisition::gantryPlanOfRun(run);
  const int trials = o.trials >= 0 ? o.trials : plan.monte_carlo_trials;
  auto j = report(g, m, o, plan.mpe, trials, fmt::format("run {}: {} ({})", run_id, run.name, run.status));
  j["run_id"] = run_id;
  store.addResult(run_id, "gantry-point-accuracy", kVersion,
                  nlohmann::json{{"tcp0", o.tcp0}, {"fit", o.fit}, {"trials", trials}, {"seed", o.seed}}.dump(), j.dump());
  return j;
}

/// After a run: the reason it stopped (exit 1), or its evaluation.
int reportRun(const Globals& g, storage::Store& store, const acquisition::GantryRunResult& result, const GantryEvaluateOptions& evaluate) {
  if (result.outcome == acquisition::RunOutcome::kInterrupted) {
    *g.err << fmt::format("run {} interrupted: {}; the features measured are stored\n", result.run_id, result.reason);
    return 1;
  }
  if (!g.json) *g.out << fmt::format("run {}: {} tracker points\n\n", result.run_id, result.points);
  auto j = analyzeStored(g, store, result.run_id, evaluate);
  if (g.json) {
    j["points"] = result.points;
    *g.out << j.dump() << "\n";
  }
  return 0;
}

/// A CNC running the plan's NC program by itself: it tells nothing, the operator does.
class OperatorRunsTheProgram final : public acquisition::MachineController {
 public:
  std::optional<double> moveTo(const std::string&, double) override { return std::nullopt; }
};

int runGantryOnRealMachine(const Globals& g, const acquisition::GantryPlan& plan, const std::string& plan_path,
                           const std::string& device_uri, const SimulationOptions& sim_options, const GantryEvaluateOptions& evaluate) {
  // The kinematics: a kinematic description (*.model.json) or a machine file that has one.
  const auto file = nlohmann::json::parse(readTextFile(sim_options.machine_file), nullptr, false);
  if (file.is_discarded()) throw InputError(sim_options.machine_file + ": not valid JSON");
  std::string unused;
  const auto kinematics = file.contains("joints") ? processing::MultibodyModel::fromJson(file, sim_options.machine_file)
                                                  : machineConfig(sim_options, &unused).kinematics();
  drivers::Registry registry;
  drivers::registerBuiltInDrivers(registry);
  auto tracker = registry.openAs<drivers::tracker::TrackerDevice>(device_uri);
  storage::Store store(g.db);
  const storage::Id machine_id = store.ensureMachine(kinematics.name(), "real machine", "{}");
  const storage::Id campaign_id = store.addCampaign(machine_id, plan.name);
  const auto prompt = [&g](const std::string& text) {
    *g.err << text << " [Enter] " << std::flush;
    std::string answer;
    if (!g.in || !std::getline(*g.in, answer)) throw InputError("no operator input (standard input closed) at: " + text);
  };
  acquisition::GantryRunOptions options;
  options.software_version = kVersion;
  options.stop_requested = g.stop;
  options.place_reflector = [&](const std::string& place) { prompt("put the reflector on " + place); };
  options.confirm_in_position = [&](const std::string& what) { prompt("NC program (" + plan_path + "): " + what); };
  OperatorRunsTheProgram controller;
  const auto result = acquisition::runGantryTest(store, campaign_id, *tracker, controller, plan, kinematics, options);
  *g.err << "\n";
  return reportRun(g, store, result, evaluate);
}

}  // namespace

int runGantry(const Globals& g, const std::string& plan_path, const std::string& device_uri, const SimulationOptions& sim_options,
              const GantryEvaluateOptions& evaluate) {
  const auto plan = acquisition::GantryPlan::fromJson(nlohmann::json::parse(readTextFile(plan_path)), plan_path);
  if (sim_options.machine_file.empty()) {
    throw InputError("gantry runs need the machine: --machine-config FILE (examples/machines/gantry-drilling.json for the "
                     "simulated gantry; for a real one its machine file or kinematic description, *.model.json)");
  }
  if (drivers::DeviceUri::parse(device_uri).scheme != "mock") return runGantryOnRealMachine(g, plan, plan_path, device_uri, sim_options, evaluate);
  std::string file_json;
  const auto config = machineConfig(sim_options, &file_json);
  // Every hole inside the travel before anything moves.
  for (const auto& h : acquisition::planHoles(plan, config.kinematics())) {
    const double position[] = {h.x_mm, h.y_mm, h.z_mm};
    for (int a = 0; a < 3; ++a) {
      const auto& travel = config.axes[static_cast<std::size_t>(a)];
      if (position[a] < travel.min_mm - 1e-9 || position[a] > travel.max_mm + 1e-9) {
        throw InputError(fmt::format("{}: hole {} needs {} at {:.3f} mm, outside the machine's travel [{}, {}]", plan_path, h.id,
                                     "XYZ"[a], position[a], travel.min_mm, travel.max_mm));
      }
    }
  }
  Simulation sim(config, demoInterferometer(), sim_options.time_scale);
  auto tracker = sim.registry.openAs<drivers::tracker::TrackerDevice>(device_uri);
  storage::Store store(g.db);
  const storage::Id machine_id = store.ensureMachine(machineName(config, true), "simulated machine",
                                                     simulationDescription(config, file_json));
  const storage::Id campaign_id = store.addCampaign(machine_id, plan.name);
  acquisition::GantryRunOptions options;
  options.software_version = kVersion;
  options.stop_requested = g.stop;
  options.place_reflector = [&sim](const std::string& place) { sim.world.tracker().placeReflector(place); };
  options.run_clock = &sim.run_clock;
  // The operator reads the air at the machine into the tracker.
  options.environment = drivers::tracker::Environment{config.air_temp_c, config.air_pressure_pa / 100.0, config.humidity_pct};
  if (g.terminal && !g.json) options.on_progress = [&g](const std::string& what) { *g.err << "\r" << fmt::format("{:<40}", what) << std::flush; };
  const auto result = acquisition::runGantryTest(store, campaign_id, *tracker, sim.controller, plan, sim.world.machine.kinematics(), options);
  if (g.terminal && !g.json) *g.err << "\r" << std::string(40, ' ') << "\r";
  return reportRun(g, store, result, evaluate);
}

int analyzeGantry(const Globals& g, storage::Id run_id, const GantryEvaluateOptions& options) {
  storage::Store store(g.db);
  const auto j = analyzeStored(g, store, run_id, options);
  if (g.json) *g.out << j.dump() << "\n";
  return 0;
}

int gantryEvaluate(const Globals& g, const std::string& path, const GantryEvaluateOptions& options) {
  const auto j = nlohmann::json::parse(readTextFile(path), nullptr, false);
  if (j.is_discarded()) throw InputError(path + ": not valid JSON");
  const auto m = acquisition::measurementsFromJson(j, path);
  const processing::TrackerMpe mpe =
      j.contains("tracker_mpe") ? acquisition::trackerMpeFromJson(j["tracker_mpe"], path, "tracker_mpe") : processing::TrackerMpe{};
  const auto out = report(g, m, options, mpe, options.trials >= 0 ? options.trials : 200, path);
  if (g.json) *g.out << out.dump() << "\n";
  return 0;
}

int gantryExport(const Globals& g, storage::Id run_id, const std::string& path) {
  storage::Store store(g.db);
  const auto m = acquisition::loadGantryMeasurements(store, run_id);
  auto j = acquisition::measurementsToJson(m);
  const auto plan = acquisition::gantryPlanOfRun(store.run(run_id));
  j["tracker_mpe"] = plan.toJson()["tracker_mpe"];
  std::ofstream out(path);
  if (!out) throw InputError(path + ": cannot write");
  writeReadable(out, j, 0);
  out << "\n";
  if (!out.flush()) throw InputError(path + ": write failed");
  if (g.json) {
    *g.out << nlohmann::json{{"file", path}, {"holes", m.holes.size()}}.dump() << "\n";
  } else {
    *g.out << fmt::format("run {}: {} holes written to {}\n", run_id, m.holes.size(), path);
  }
  return 0;
}

}  // namespace mtcal::app
