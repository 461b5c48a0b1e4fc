#include "mtcal/services/circle.h"

#include <fmt/format.h>

#include <cmath>
#include <functional>
#include <memory>
#include <numbers>
#include <set>

#include "imported_file.h"
#include "mtcal/error.h"
#include "mtcal/mocks/gcode_player.h"
#include "mtcal/services/version.h"

namespace mtcal::services {

namespace {

nlohmann::json optionalNumber(const std::optional<double>& v) {
  return v ? nlohmann::json(*v) : nlohmann::json(nullptr);
}

/// A stored test: its setting, whether the bar was zeroed and its points.
struct StoredCircle {
  CircleSetting setting;
  bool bar_zeroed = true;
  bool timed_from_feed_in = false;  ///< captured from the part program
  std::vector<processing::CirclePoint> points;
  std::optional<std::string> feed_note;  ///< the feed was not given at import
};

StoredCircle loadCircle(storage::Store& store, storage::Id run_id) {
  const auto info = store.run(run_id);
  if (info.kind != storage::run_kind::kCircle)
    throw InputError(fmt::format("run {} is {}, not a circular test", run_id, storage::run_kind::aRunOf(info.kind)));
  const auto plan = nlohmann::json::parse(info.plan_json);
  StoredCircle c;
  c.setting.radius_mm = plan.at("radius_mm").get<double>();
  c.setting.feed_mm_per_min = plan.value("feed_mm_per_min", acquisition::kAssumedFeedMmPerMin);
  c.feed_note = acquisition::feedAssumedNote(plan);
  c.setting.plane = processing::parsePlane(plan.value("plane", "XY"));
  // Acquired tests say whether the bar was zeroed; imported data are taken as calibrated.
  c.bar_zeroed = !plan.contains("calibrator_length_mm") || !plan["calibrator_length_mm"].is_null();
  c.timed_from_feed_in = plan.value("capture", "") == "part program";
  c.points = acquisition::toCirclePoints(store.circlePoints(run_id));
  if (c.points.empty()) throw InputError(fmt::format("run {} has no circle points stored", run_id));
  return c;
}

/// The plane's axes in lower case: XY -> x, y; YZ -> y, z; ZX -> z, x.
std::pair<std::string, std::string> axisLetters(processing::Plane plane) {
  const auto a = processing::planeAxes(plane);
  const char* names = "xyz";
  return {std::string(1, names[a.first]), std::string(1, names[a.second])};
}

nlohmann::json settingDocument(storage::Id run_id, const CircleSetting& s) {
  return {{"schema_version", 1},
          {"run_id", run_id},
          {"plane", processing::planeName(s.plane)},
          {"radius_mm", s.radius_mm},
          {"feed_mm_per_min", s.feed_mm_per_min}};
}

}  // namespace

nlohmann::json Iso230_4Analysis::document() const {
  const auto [first, second] = axisLetters(setting.plane);
  const auto& r = result;
  nlohmann::json j = settingDocument(run_id, setting);
  j["G_ccw_um"] = r.ccw ? nlohmann::json(r.ccw->g_um) : nlohmann::json(nullptr);
  j["G_cw_um"] = r.cw ? nlohmann::json(r.cw->g_um) : nlohmann::json(nullptr);
  j["G_um"] = r.g_b_um ? *r.g_b_um : (r.ccw ? r.ccw->g_um : r.cw->g_um);
  j["H_um"] = optionalNumber(r.h_um);
  j["centre_" + first + "_um"] = r.centre_first_um;
  j["centre_" + second + "_um"] = r.centre_second_um;
  for (const auto& [path, name] : {std::pair{&r.ccw, "ccw"}, std::pair{&r.cw, "cw"}}) {
    if (!*path) continue;
    const auto& p = **path;
    j[name] = {{"points", p.points},
               {"angle_span_deg", p.angle_span_deg},
               {"G_um", p.g_um},
               {"radius_deviation_um", p.radius_deviation_um},
               {"centre_" + first + "_um", p.centre_first_um},
               {"centre_" + second + "_um", p.centre_second_um},
               {"rms_um", p.rms_um}};
  }
  return j;
}

nlohmann::json BallbarAnalysis::document() const {
  const auto [first, second] = axisLetters(setting.plane);
  const auto& d = diagnosis;
  const std::string cyclic_axis = d.cyclic_axis == 0 ? first : d.cyclic_axis == 1 ? second : "";
  nlohmann::json j = settingDocument(run_id, setting);
  j["diagnosis"] = {{"squareness_urad", optionalNumber(d.squareness_urad)},
                    {"servo_mismatch_ms", optionalNumber(d.servo_mismatch_ms)},
                    {"scale_mismatch_" + first + "_ppm", optionalNumber(d.scale_mismatch_first_ppm)},
                    {"scale_mismatch_" + second + "_ppm", optionalNumber(d.scale_mismatch_second_ppm)},
                    {"backlash_" + first + "_um", optionalNumber(d.backlash_first_um)},
                    {"backlash_" + second + "_um", optionalNumber(d.backlash_second_um)},
                    {"reversal_spike_" + first + "_um", optionalNumber(d.reversal_spike_first_um)},
                    {"reversal_spike_" + second + "_um", optionalNumber(d.reversal_spike_second_um)},
                    {"straightness_" + first + "_um", optionalNumber(d.straightness_first_um)},
                    {"straightness_" + second + "_um", optionalNumber(d.straightness_second_um)},
                    {"cyclic_amplitude_um", optionalNumber(d.cyclic_amplitude_um)},
                    {"cyclic_period_mm", optionalNumber(d.cyclic_period_mm)},
                    {"cyclic_axis", cyclic_axis.empty() ? nlohmann::json(nullptr) : nlohmann::json(cyclic_axis)}};
  j["rms_before_um"] = d.rms_before_um;
  j["rms_after_um"] = d.rms_after_um;
  j["notes"] = d.notes;
  return j;
}

Iso230_4Analysis analyzeIso230_4(Session& session, storage::Id run_id) {
  auto& store = session.store();
  const auto c = loadCircle(store, run_id);
  Iso230_4Analysis a{run_id, 0, c.setting, processing::evaluateCircularTest(c.setting.radius_mm, c.points), c.points};
  a.result_id = session.storeResult(run_id, "iso230-4", kVersion, "{}", a.document().dump()).value_or(0);
  return a;
}

BallbarAnalysis analyzeBallbar(Session& session, storage::Id run_id) {
  auto& store = session.store();
  const auto c = loadCircle(store, run_id);
  BallbarAnalysis a{run_id, 0, c.setting,
                    processing::diagnoseBallbar(c.setting.radius_mm, c.points,
                                                {c.setting.feed_mm_per_min, c.bar_zeroed, 6.0, c.timed_from_feed_in})};
  if (c.feed_note) a.diagnosis.notes.push_back(*c.feed_note);
  a.result_id = session.storeResult(run_id, "ballbar-diagnosis", kVersion, "{}", a.document().dump()).value_or(0);
  return a;
}

CircleImport importCircle(Session& session, const std::string& path, acquisition::CircleImportOptions options) {
  options.software_version = kVersion;
  acquisition::checkCircleImportOptions(options);  // before a file (or a pipe) is read whole
  auto file = detail::readImportedFile(path);
  options.source_sha256 = file.sha256;
  const storage::Id id = acquisition::importCircleCsv(detail::storeWhenNeeded(session), file.bytes, path, options);
  auto& store = session.store(Access::kCreate);
  session.recordRun(id, {});
  CircleImport out{id, store.circlePoints(id).size(), {}};
  // The stored plan's note, from what was given (the feed taken is the assumed one).
  if (!options.feed_mm_per_min) out.warnings.push_back(*acquisition::feedAssumedNote({{"feed_assumed", true}}));
  for (auto& warning : detail::importedBefore(store, options.source_sha256, path, {id}))
    out.warnings.push_back(std::move(warning));
  for (const auto& warning : out.warnings) session.observer().onMessage("warning", warning);
  return out;
}

nlohmann::json CircleRunResult::document() const {
  nlohmann::json j = {{"schema_version", 1}, {"run_id", run_id},   {"status", status},
                      {"points", points},    {"samples", samples}, {"lost_samples", lost_samples}};
  if (!reason.empty()) j["reason"] = reason;
  if (resumed) j["resumed"] = true;
  if (iso230_4) j["iso230_4"] = iso230_4->document();
  if (ballbar) j["ballbar"] = ballbar->document();
  return j;
}

namespace {

/// Reports a test's directions as they are stored; the first call, before any, says how many
/// the run stored before (a resumed run), from which the time left is counted.
std::function<void(std::size_t, std::size_t, std::size_t)> directionProgress(Session& session) {
  auto clock = std::make_shared<std::optional<ProgressClock>>();
  return [&session, clock](std::size_t done, std::size_t total, std::size_t points) {
    if (!*clock) {
      clock->emplace(total, done);
      return;
    }
    session.observer().onProgress((*clock)->at(done, fmt::format("direction {}: {} points", done, points)));
  };
}

/// What a front end shows of a run: its outcome, and its evaluation when it completed.
CircleRunResult circleResult(Session& session, const acquisition::CircleRunResult& run, bool resumed) {
  CircleRunResult r;
  r.run_id = run.run_id;
  if (r.run_id != 0 && !resumed) session.recordRun(r.run_id, {});
  r.status = run.outcome == acquisition::RunOutcome::kCompleted ? "completed" : "interrupted";
  r.reason = run.reason;
  r.points = run.points;
  r.samples = run.stats.samples;
  r.lost_samples = run.stats.lost_samples;
  r.resumed = resumed;
  if (run.outcome == acquisition::RunOutcome::kCompleted) {
    r.iso230_4 = analyzeIso230_4(session, r.run_id);
    r.ballbar = analyzeBallbar(session, r.run_id);
  }
  return r;
}

/// Runs a test on the simulated machine `machine` into the campaign `campaign` gives, or resumes
/// `resume_run`; evaluates it when it completes.
CircleRunResult acquireCircle(Session& session, const acquisition::CirclePlan& plan, const std::string& device_uri,
                              const mocks::VirtualMachineConfig& machine, double time_scale,
                              const std::function<storage::Id()>& campaign, std::optional<storage::Id> resume_run) {
  Simulation sim(machine, demoInterferometer(), time_scale);
  sim.setUpFor(plan);
  auto bar = sim.registry.openAs<drivers::ballbar::BallbarDevice>(device_uri);
  auto& store = session.store(Access::kRecord);
  const storage::Id campaign_id = resume_run ? 0 : campaign();
  acquisition::CircleRunOptions options;
  options.software_version = kVersion;
  options.stop_requested = session.stopRequested();
  options.mount_bar = [&sim] { sim.world.ballbar->mountOnMachine(); };
  options.run_clock = &sim.run_clock;
  options.resume_run = resume_run;
  options.on_progress = directionProgress(session);
  const auto run = acquisition::runCircleTest(store, campaign_id, *bar, sim.controller, plan, options);
  return circleResult(session, run, resume_run.has_value());
}

/// A test captured from a part program the machine runs by itself (acquisition::runTriggeredCircleTest),
/// into the campaign `campaign` gives; evaluated when it completes.
CircleRunResult capturedCircle(Session& session, const acquisition::CirclePlan& plan,
                               drivers::ballbar::BallbarDevice& bar, acquisition::CircleRunOptions options,
                               const std::function<storage::Id()>& campaign) {
  auto& store = session.store(Access::kRecord);
  options.software_version = kVersion;
  options.stop_requested = session.stopRequested();
  options.on_progress = directionProgress(session);
  const auto run = acquisition::runTriggeredCircleTest(store, campaign(), bar, plan, options);
  return circleResult(session, run, false);
}

}  // namespace

namespace {

/// Every place the circle takes the machine inside its travel, before anything moves (a run
/// stopped half-way by a move it could never make cannot be resumed either): the centre, and
/// the arc with its overshoot at the radius plus the feed-in.
void checkCircleInTravel(const acquisition::CirclePlan& plan, const std::string& plan_path,
                         const mocks::VirtualMachineConfig& machine) {
  const auto what = fmt::format("{}: the circle (centre_mm, radius_mm, arc and overshoot, feed_in_mm)",
                                plan_path.empty() ? "plan '" + plan.name + "'" : plan_path);
  for (int a = 0; a < 3; ++a) requireInTravel(machine, static_cast<mocks::Axis>(a), plan.centre_mm(a), what);
  const auto axes = processing::planeAxes(plan.plane);
  const double reach_mm = plan.radius_mm + plan.feed_in_mm;
  const double from_deg = plan.start_angle_deg - plan.overshoot_deg,
               sweep_deg = plan.arc_deg + 2.0 * plan.overshoot_deg;
  const int steps = static_cast<int>(std::ceil(sweep_deg * 10.0));  // every 0.1 deg: 0.04 um short of a peak at 100 mm
  for (int k = 0; k <= steps; ++k) {
    const double angle = (from_deg + sweep_deg * k / steps) * std::numbers::pi / 180.0;
    requireInTravel(machine, static_cast<mocks::Axis>(axes.first),
                    plan.centre_mm(axes.first) + reach_mm * std::cos(angle), what);
    requireInTravel(machine, static_cast<mocks::Axis>(axes.second),
                    plan.centre_mm(axes.second) + reach_mm * std::sin(angle), what);
  }
}

}  // namespace

CircleRunResult runCircle(Session& session, const CircleRunRequest& request) {
  const auto& plan = request.plan;
  if (drivers::DeviceUri::parse(request.device_uri).scheme != "mock") {
    // A real ballbar on a real machine: the CNC runs the plan's part program.
    Operator& person =
        session.person("a real machine runs the circular test's part program when the operator starts it");
    drivers::Registry registry;
    drivers::registerBuiltInDrivers(registry);
    auto bar = registry.openAs<drivers::ballbar::BallbarDevice>(request.device_uri);
    acquisition::CircleRunOptions options;
    options.mount_bar = [&] {
      person.confirm(
          fmt::format("Set the centre ball at X{:.3f} Y{:.3f} Z{:.3f} and mount the bar ({} mm), then "
                      "press Enter",
                      plan.centre_mm.x(), plan.centre_mm.y(), plan.centre_mm.z(), plan.radius_mm));
    };
    options.on_waiting_for_program = [&] {
      person.tell(
          fmt::format("Ready: start the part program of this plan on the machine now (mtcal plan gcode {}). "
                      "Each direction is found by its feed-in and feed-out.",
                      request.plan_path));
    };
    return capturedCircle(session, plan, *bar, options,
                          [&] { return realCampaign(session.store(Access::kRecord), request.machine, plan.name); });
  }
  const auto machine = simulatedMachine(request.simulation);
  checkCircleInTravel(plan, request.plan_path, machine.config);
  const auto campaign = [&] { return simulatedCampaign(session.store(Access::kRecord), machine, plan.name); };
  if (!request.triggered) {
    return acquireCircle(session, plan, request.device_uri, machine.config, request.simulation.time_scale, campaign,
                         std::nullopt);
  }
  // Rehearsal of the real-machine workflow: the virtual CNC runs the plan's part program.
  Simulation sim(machine.config, demoInterferometer(), request.simulation.time_scale);
  sim.setUpFor(plan);
  auto bar = sim.registry.openAs<drivers::ballbar::BallbarDevice>(request.device_uri);
  const auto program = mocks::parseGcode(acquisition::circleGcode(plan));
  std::optional<mocks::CncProgramRun> cnc;
  acquisition::CircleRunOptions options;
  options.run_clock = &sim.run_clock;
  options.mount_bar = [&] {
    // The simulated operator jogs to the centre, sets the ball there and mounts the bar.
    const auto a = processing::planeAxes(plan.plane);
    std::optional<double> at_centre_s;
    for (int i : {a.normal, a.first, a.second})
      at_centre_s = sim.controller.moveTo(std::string(1, "XYZ"[i]), plan.centre_mm(i));
    if (at_centre_s) sim.run_clock.advanceTo(*at_centre_s + plan.settle_s);
    sim.world.ballbar->mountOnMachine();
  };
  options.on_waiting_for_program = [&] { cnc.emplace(sim.world.machine, program); };  // cycle start
  auto r = capturedCircle(session, plan, *bar, options, campaign);
  if (cnc) cnc->finish();  // the program's error, if any
  return r;
}

CircleRunResult resumeCircle(Session& session, storage::Id run_id, double time_scale) {
  const auto rig = storedRig(session.store(), run_id);
  if (!rig.simulation) {
    throw InputError(fmt::format("run {} was not measured on the simulated machine: it cannot be resumed", run_id));
  }
  const auto plan =
      acquisition::CirclePlan::fromJson(nlohmann::json::parse(rig.run.plan_json), fmt::format("run {} plan", run_id));
  return acquireCircle(session, plan, rig.uriOf("measuring"), *rig.simulation, time_scale, {}, run_id);
}

}  // namespace mtcal::services
