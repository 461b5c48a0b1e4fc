#include "mtcal/services/gantry.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <sstream>

#include "mtcal/acquisition/gantry_measurements.h"
#include "mtcal/drivers/registry.h"
#include "mtcal/drivers/uri.h"
#include "mtcal/error.h"
#include "mtcal/services/version.h"

namespace mtcal::services {

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

GantryAnalysis evaluate(const processing::GantryMeasurements& m, const GantryEvaluateOptions& o,
                        const processing::TrackerMpe& mpe, int trials, std::string title) {
  const auto options = evaluationOptions(o);
  GantryAnalysis a;
  a.title = std::move(title);
  a.options = o;
  a.trials = trials;
  a.mpe = mpe;
  try {
    a.evaluation = processing::evaluateGantry(m, options);
    if (trials > 0) a.uncertainty = processing::monteCarloGantry(m, options, mpe, trials, o.seed);
  } catch (const InputError& e) {
    throw InputError(a.title + ": " + e.what());  // which measurements: the file, or the run
  }
  return a;
}

/// JSON for people: nested objects and arrays indented, an array of numbers (a point) on one line.
void writeReadable(std::ostream& out, const nlohmann::json& j, int indent) {
  const std::string pad(static_cast<std::size_t>(indent) * 2, ' '),
      inner(static_cast<std::size_t>(indent + 1) * 2, ' ');
  const bool flat = !j.is_structured() ||
                    (j.is_array() && std::all_of(j.begin(), j.end(), [](const auto& v) { return v.is_primitive(); }));
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

/// A CNC running the plan's NC program by itself: it tells nothing, the operator does.
class OperatorRunsTheProgram final : public acquisition::MachineController {
 public:
  std::optional<double> moveTo(const std::string&, double) override { return std::nullopt; }
};

/// Every place the plan takes the machine inside its travel, before anything moves (a run
/// stopped half-way by a move it could never make cannot be resumed either).
void checkPlanInTravel(const GantryRunRequest& request, const mocks::VirtualMachineConfig& config) {
  const auto& plan = request.plan;
  const auto start = fmt::format("{}: the start of the passes (initial_mm)", request.plan_path);
  requireInTravel(config, mocks::Axis::kY, plan.initial_mm[1], start);
  requireInTravel(config, mocks::Axis::kZ, plan.initial_mm[2], start);
  for (const double x : {plan.gantry_from_mm, plan.gantry_to_mm})
    requireInTravel(config, mocks::Axis::kX, x,
                    fmt::format("{}: the tracked pass (gantry_from_mm, gantry_to_mm)", request.plan_path));
  for (const auto& h : acquisition::planHoles(plan, config.kinematics())) {
    const auto what = fmt::format("{}: hole {}", request.plan_path, h.id);
    requireInTravel(config, mocks::Axis::kX, h.x_mm, what);
    requireInTravel(config, mocks::Axis::kY, h.y_mm, what);
    requireInTravel(config, mocks::Axis::kZ, h.z_mm, what);
  }
}

}  // namespace

nlohmann::json GantryAnalysis::document() const {
  const auto& ev = evaluation;
  const auto& u = uncertainty;
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
    return nlohmann::json{{"gantry_position", s.gantry_position}, {"holes", s.holes},
                          {"mean_dP_um", vec(s.mean_dp_um)},      {"mean_norm_um", s.mean_norm_um},
                          {"max_norm_um", s.max_norm_um},         {"rms_norm_um", s.rms_norm_um},
                          {"mean_perp_um", s.mean_perp_um},       {"max_perp_um", s.max_perp_um},
                          {"rms_perp_um", s.rms_perp_um},         {"worst_hole", s.worst_hole}};
  };
  nlohmann::json per_position = nlohmann::json::array();
  for (std::size_t k = 1; k < ev.summaries.size(); ++k) per_position.push_back(summaryJson(ev.summaries[k]));
  const auto axisJson = [](const auto& axis) {
    return nlohmann::json{{"centre_mm", vec(axis.centre)},
                          {"direction", vec(axis.normal)},
                          {"radius_mm", axis.radius_mm},
                          {"radial_rms_um", axis.radial_rms_mm * 1000.0},
                          {"plane_rms_um", axis.plane_rms_mm * 1000.0}};
  };
  nlohmann::json j{{"schema_version", 1},
                   {"method", "CN106017326"},
                   {"target_fit", ev.target_fit},
                   {"tcp0_source", options.tcp0},
                   {"frame",
                    {{"xy_plane_rms_um", ev.xy_plane.rms_mm * 1000.0},
                     {"side_1_rms_um", ev.side_1_rms_um},
                     {"side_2_rms_um", ev.side_2_rms_um},
                     {"gantry_line_rms_um", ev.gantry_line_rms_um},
                     {"gantry_tilt_urad", ev.gantry_tilt_urad},
                     {"gantry_passes_spread_urad", ev.gantry_passes_spread_urad},
                     {"gantry_outliers", ev.gantry_outliers}}},
                   {"c_axis", axisJson(ev.c_axis)},
                   {"a_axis", axisJson(ev.a_axis)},
                   {"axes_offset_um", ev.axes.distance_mm * 1000.0},
                   {"axes_squareness_urad", ev.axes_squareness_urad},
                   {"wrist_centre_mm", vec(ev.wrist_centre_mm)},
                   {"tcp0_mm", vec(ev.tcp0_mm)},
                   {"tcp0_axes_minus_tool_point_um",
                    ev.tcp0_axes_minus_tool_point_um ? vec(*ev.tcp0_axes_minus_tool_point_um) : nlohmann::json()},
                   {"holes", holes},
                   {"summary", ev.summaries.empty() ? nlohmann::json() : summaryJson(ev.summaries[0])},
                   {"per_gantry_position", per_position},
                   {"notes", ev.notes}};
  if (u) {
    j["uncertainty"] = {{"trials", u->trials},
                        {"seed", options.seed},
                        {"tracker_mpe",
                         {{"distance_um", mpe.distance_um},
                          {"distance_um_per_m", mpe.distance_um_per_m},
                          {"transverse_um", mpe.transverse_um},
                          {"transverse_um_per_m", mpe.transverse_um_per_m}}},
                        {"tcp0_sigma_um", vec(u->tcp0_sigma_um)},
                        {"max_norm_u95_um", u->max_norm_u95_um},
                        {"max_perp_u95_um", u->max_perp_u95_um}};
  }
  if (run_id != 0) j["run_id"] = run_id;
  return j;
}

GantryAnalysis analyzeGantry(Session& session, storage::Id run_id, const GantryEvaluateOptions& options) {
  auto& store = session.store();
  const auto m = acquisition::loadGantryMeasurements(store, run_id);
  const auto run = store.run(run_id);
  const auto plan = acquisition::gantryPlanOfRun(run);
  const int trials = options.trials >= 0 ? options.trials : plan.monte_carlo_trials;
  auto a = evaluate(m, options, plan.mpe, trials, fmt::format("run {}: {} ({})", run_id, run.name, run.status));
  a.run_id = run_id;
  a.result_id =
      session
          .storeResult(
              run_id, "gantry-point-accuracy", kVersion,
              nlohmann::json{{"tcp0", options.tcp0}, {"fit", options.fit}, {"trials", trials}, {"seed", options.seed}}
                  .dump(),
              a.document().dump())
          .value_or(0);
  return a;
}

GantryAnalysis evaluateGantryFile(const std::string& path, const GantryEvaluateOptions& options) {
  const auto j = readJsonFile(path);
  const auto m = acquisition::measurementsFromJson(j, path);
  const processing::TrackerMpe mpe = j.contains("tracker_mpe")
                                         ? acquisition::trackerMpeFromJson(j["tracker_mpe"], path, "tracker_mpe")
                                         : processing::TrackerMpe{};
  return evaluate(m, options, mpe, options.trials >= 0 ? options.trials : 200, path);
}

std::size_t exportGantry(Session& session, storage::Id run_id, const std::string& path) {
  auto& store = session.store();
  const auto m = acquisition::loadGantryMeasurements(store, run_id);
  auto j = acquisition::measurementsToJson(m);
  j["tracker_mpe"] = acquisition::gantryPlanOfRun(store.run(run_id)).toJson()["tracker_mpe"];
  std::ostringstream text;
  writeReadable(text, j, 0);
  text << "\n";
  writeTextFile(path, text.str());
  return m.holes.size();
}

nlohmann::json GantryRunResult::document() const {
  nlohmann::json j =
      analysis ? analysis->document() : nlohmann::json{{"schema_version", 1}, {"run_id", run_id}, {"reason", reason}};
  j["status"] = status;
  j["points"] = points;
  return j;
}

namespace {

/// Where a gantry run is measured: the simulated gantry (its machine), or a real one (its kinematics).
struct GantryRig {
  const mocks::VirtualMachineConfig* simulated = nullptr;
  const processing::MultibodyModel* real_kinematics = nullptr;
};

/// A simulated run can only put the reflector where the simulated machine has a nest or face:
/// refused before the run starts (an unknown place mid-run would interrupt it for good).
void requirePlacesOnTheMachine(const GantryRunRequest& request, const std::vector<std::string>& places) {
  for (const auto& place : request.plan.reflectorPlaces()) {
    if (std::find(places.begin(), places.end(), place) != places.end()) continue;
    throw InputError(
        fmt::format("{}: the plan puts the reflector on '{}', which the simulated machine has no "
                    "place for (it has: {})",
                    request.plan_path, place, fmt::join(places, ", ")));
  }
}

/// Runs a plan into the campaign `campaign` gives, or resumes `resume_run`, and evaluates it.
GantryRunResult acquireGantry(Session& session, const GantryRunRequest& request, const GantryRig& rig,
                              const std::function<storage::Id()>& campaign, std::optional<storage::Id> resume_run) {
  const auto& plan = request.plan;
  acquisition::GantryRunOptions options;
  options.software_version = kVersion;
  options.stop_requested = session.stopRequested();
  options.resume_run = resume_run;
  std::optional<ProgressClock> clock;  // from the first feature, when the run knows how many there are
  options.on_progress = [&](std::size_t done, std::size_t total, const std::string& what) {
    if (!clock) clock.emplace(total, done);
    session.observer().onProgress(clock->at(done, what));
  };
  acquisition::GantryRunResult run;
  if (rig.simulated) {
    const auto& machine = *rig.simulated;
    Simulation sim(machine, demoInterferometer(), request.simulation.time_scale);
    requirePlacesOnTheMachine(request, sim.world.tracker().places());
    auto tracker = sim.registry.openAs<drivers::tracker::TrackerDevice>(request.device_uri);
    auto& store = session.store(Access::kRecord);
    const storage::Id campaign_id = resume_run ? 0 : campaign();
    options.instrument_id = session.instrument(tracker->info());
    options.place_reflector = [&sim](const std::string& place) { sim.world.tracker().placeReflector(place); };
    options.run_clock = &sim.run_clock;
    // The operator reads the air at the machine into the tracker.
    options.environment =
        drivers::tracker::Environment{machine.air_temp_c, machine.air_pressure_pa / 100.0, machine.humidity_pct};
    run = acquisition::runGantryTest(store, campaign_id, *tracker, sim.controller, plan, sim.world.machine.kinematics(),
                                     options);
  } else {
    drivers::Registry registry;
    drivers::registerBuiltInDrivers(registry);
    auto tracker = registry.openAs<drivers::tracker::TrackerDevice>(request.device_uri);
    Operator& person = session.person("a real machine's NC program is run, and the reflector placed, by the operator");
    auto& store = session.store(Access::kRecord);
    const storage::Id campaign_id = resume_run ? 0 : campaign();
    options.instrument_id = session.instrument(tracker->info());
    options.place_reflector = [&](const std::string& place) { person.confirm("put the reflector on " + place); };
    options.confirm_in_position = [&](const std::string& what) {
      person.confirm("NC program (" + request.plan_path + "): " + what);
    };
    OperatorRunsTheProgram controller;
    run = acquisition::runGantryTest(store, campaign_id, *tracker, controller, plan, *rig.real_kinematics, options);
  }
  if (clock && run.outcome == acquisition::RunOutcome::kCompleted) {
    session.observer().onProgress(clock->at(clock->total(), "all features measured"));
  }
  GantryRunResult r;
  r.run_id = run.run_id;
  r.reason = run.reason;
  r.points = session.store().trackerPointCount(r.run_id);
  if (r.run_id != 0 && !resume_run) session.recordRun(r.run_id, {});
  if (run.outcome == acquisition::RunOutcome::kInterrupted) {
    r.status = storage::run_status::kInterrupted;
    return r;
  }
  r.status = storage::run_status::kCompleted;
  r.analysis = analyzeGantry(session, r.run_id, request.evaluation);
  return r;
}

}  // namespace

GantryRunResult runGantry(Session& session, const GantryRunRequest& request) {
  const auto& plan = request.plan;
  const auto& sim_options = request.simulation;
  if (sim_options.machine_file.empty()) {
    throw InputError(
        "gantry runs need the machine: --machine-config FILE (examples/machines/gantry-drilling.json for the "
        "simulated gantry; for a real one its machine file or kinematic description, *.model.json)");
  }
  if (drivers::DeviceUri::parse(request.device_uri).scheme == "mock") {
    const auto machine = simulatedMachine(sim_options);
    checkPlanInTravel(request, machine.config);  // before anything moves
    return acquireGantry(
        session, request, {&machine.config, nullptr},
        [&] { return simulatedCampaign(session.store(Access::kRecord), machine, plan.name); }, std::nullopt);
  }
  const auto kinematics = machineKinematics(sim_options.machine_file);
  return acquireGantry(
      session, request, {nullptr, &kinematics},
      [&] { return realCampaign(session.store(Access::kRecord), kinematics.name(), plan.name); }, std::nullopt);
}

GantryRunResult resumeGantry(Session& session, storage::Id run_id, const SimulationOptions& simulation) {
  const auto rig = storedRig(session.store(), run_id);
  GantryRunRequest request;
  request.plan = acquisition::gantryPlanOfRun(rig.run);
  request.plan_path = fmt::format("run {}'s plan", run_id);
  request.device_uri = rig.uriOf("measuring");
  request.simulation = simulation;
  if (rig.simulation) return acquireGantry(session, request, {&*rig.simulation, nullptr}, {}, run_id);
  if (simulation.machine_file.empty()) {
    throw InputError(fmt::format(
        "run {} was measured on a real machine: give its kinematics to resume it (--machine-config FILE, its machine "
        "file or kinematic description)",
        run_id));
  }
  const auto kinematics = machineKinematics(simulation.machine_file);
  return acquireGantry(session, request, {nullptr, &kinematics}, {}, run_id);
}

}  // namespace mtcal::services
