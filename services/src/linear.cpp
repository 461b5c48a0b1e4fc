#include "mtcal/services/linear.h"

#include <fmt/format.h>

#include <cmath>
#include <filesystem>
#include <functional>

#include "imported_file.h"
#include "mtcal/acquisition/linear_run.h"
#include "mtcal/error.h"
#include "mtcal/mocks/gcode_player.h"
#include "mtcal/mocks/virtual_machine.h"
#include "mtcal/mocks/world_clock.h"
#include "mtcal/services/compensate.h"
#include "mtcal/services/version.h"

namespace mtcal::services {

namespace ifm = drivers::interferometer;

namespace {

nlohmann::json opt(const std::optional<double>& v) { return v ? nlohmann::json(*v) : nlohmann::json(nullptr); }

processing::Iso230Result evaluateTargets(const std::vector<storage::TargetRecord>& targets) {
  std::vector<processing::PositionDeviation> deviations;
  deviations.reserve(targets.size());
  for (const auto& t : targets) {
    deviations.push_back({t.target_mm, t.direction > 0 ? processing::Direction::kUp : processing::Direction::kDown,
                          t.cycle, t.deviation_um});
  }
  return processing::evaluateIso230_2(deviations);
}

SimulationCheck simulationCheck(const processing::Iso230Result& result, const Simulation& sim,
                                const acquisition::LinearPlan& plan) {
  const auto& machine = sim.world.machine;
  const auto& offset = plan.reflector_offset_mm;
  const auto axis = mocks::parseAxis(plan.axis);
  const double datum_um = machine.staticErrorUm(axis, offset, plan.datum_mm, +1);
  std::vector<double> diffs;
  for (const auto& p : result.positions) {
    if (p.mean_up_um)
      diffs.push_back(*p.mean_up_um - (machine.staticErrorUm(axis, offset, p.target_mm, +1) - datum_um));
    if (p.mean_down_um)
      diffs.push_back(*p.mean_down_um - (machine.staticErrorUm(axis, offset, p.target_mm, -1) - datum_um));
  }
  SimulationCheck check;
  check.compared_means = diffs.size();
  if (diffs.empty()) return check;
  for (double d : diffs) check.datum_offset_um += d;
  check.datum_offset_um /= static_cast<double>(diffs.size());
  double ss = 0.0;
  for (double d : diffs) {
    check.max_abs_um = std::max(check.max_abs_um, std::abs(d - check.datum_offset_um));
    ss += (d - check.datum_offset_um) * (d - check.datum_offset_um);
  }
  check.rms_um = std::sqrt(ss / static_cast<double>(diffs.size()));
  return check;
}

/// Every move of every plan inside the machine's travel, before anything moves (a run stopped
/// half-way by a move it could never make is a run lost).
void checkTravel(const std::vector<acquisition::LinearPlan>& plans, const std::string& plan_path,
                 const mocks::VirtualMachineConfig& machine) {
  for (const auto& plan : plans) {
    const auto where = fmt::format("{}: '{}'", plan_path.empty() ? "the demo plan" : plan_path, plan.name);
    const auto axis = mocks::parseAxis(plan.axis);
    for (const auto& move : acquisition::linearMoves(plan))
      requireInTravel(machine, axis, move.position_mm, where + " (targets start_mm..end_mm with overrun_mm)");
    // The datum, approached from below, and the measured line's other axes: taken before the first target.
    for (double position_mm : {plan.datum_mm - plan.overrun_mm, plan.datum_mm})
      requireInTravel(machine, axis, position_mm, where + " (datum_mm, approached from overrun_mm below it)");
    for (const auto& [other, position_mm] : plan.line_position_mm)
      requireInTravel(machine, mocks::parseAxis(other), position_mm, where + " (line_position_mm)");
  }
}

/// Where a linear run is measured: the instrument, the machine moving (or its program), the
/// clock of the world (simulated) and what happens at cycle start.
struct LinearRig {
  const drivers::Registry& registry;
  acquisition::MachineController* controller = nullptr;  ///< none: the machine runs the part program
  acquisition::RunClock* run_clock = nullptr;            ///< none: real time
  std::function<void()> on_waiting_for_program;
  std::string compensation_json = "{}";  ///< the tables the controller applies (stored with the run)
};

/// Runs (a plan into the campaign `campaign` gives) or resumes (`resume_id`) a linear run and
/// reports how it ended. The archive is touched once the instrument is open: a device that
/// cannot be opened leaves no archive behind.
LinearRunResult acquire(Session& session, const LinearRig& rig, const acquisition::LinearPlan& plan,
                        const std::string& device_uri, const std::function<storage::Id()>& campaign,
                        std::optional<storage::Id> resume_id, const Simulation* sim) {
  auto device = rig.registry.openAs<ifm::InterferometerDevice>(device_uri);
  auto& store = session.store(Access::kRecord);
  const auto info = device->info();
  const storage::Id instrument_id =
      store.ensureInstrument({info.kind, info.model, info.serial, info.firmware, device_uri});
  const std::size_t total = acquisition::linearTargets(plan).size();
  const std::size_t done_before = resume_id ? store.targets(*resume_id).size() : 0;
  const ProgressClock clock(total, done_before);
  acquisition::LinearRunOptions options;
  options.stop_requested = session.stopRequested();
  options.software_version = kVersion;
  options.compensation_json = rig.compensation_json;
  options.on_waiting_for_program = rig.on_waiting_for_program;
  options.run_clock = rig.run_clock;
  options.on_progress = [&](const acquisition::LinearProgress& p) {
    session.observer().onProgress(clock.at(
        p.done, fmt::format("{:>8.3f} mm {:<4} c{} {:+7.2f} {}", p.target_mm, p.direction > 0 ? "up" : "down", p.cycle,
                            p.deviation_um, acquisition::measuredComponent(plan) >= 3 ? "urad" : "um")));
  };
  acquisition::LinearRun run(store, *device, rig.controller, options);
  LinearRunResult r;
  if (resume_id) {
    run.resume(*resume_id);
    r.run_id = *resume_id;
  } else {
    r.run_id = run.start(plan, campaign(), instrument_id);
    session.recordRun(r.run_id, {});
  }
  const auto stored = store.run(r.run_id);
  r.campaign_id = stored.campaign_id;
  r.name = stored.name;
  r.status = stored.status;
  r.targets = stored.target_count;
  r.measures = acquisition::measuredError(plan);
  r.unit = stored.value_unit;
  if (run.outcome() == acquisition::RunOutcome::kCompleted && acquisition::measuresPositioning(plan)) {
    r.iso230_2 = analyzeIso230_2(session, r.run_id);
    if (sim) r.simulation_check = simulationCheck(r.iso230_2->result, *sim, plan);
  }
  return r;
}

}  // namespace

nlohmann::json Iso230Analysis::document() const {
  const auto& r = result;
  nlohmann::json positions = nlohmann::json::array();
  for (const auto& p : r.positions) {
    positions.push_back({{"target_mm", p.target_mm},
                         {"cycles_up", p.cycles_up},
                         {"cycles_down", p.cycles_down},
                         {"mean_up_um", opt(p.mean_up_um)},
                         {"mean_down_um", opt(p.mean_down_um)},
                         {"mean_um", opt(p.mean_um)},
                         {"s_up_um", opt(p.s_up_um)},
                         {"s_down_um", opt(p.s_down_um)},
                         {"B_i_um", opt(p.reversal_um)},
                         {"R_up_i_um", opt(p.repeatability_up_um)},
                         {"R_down_i_um", opt(p.repeatability_down_um)},
                         {"R_i_um", opt(p.repeatability_um)}});
  }
  return {{"schema_version", 1},           {"standard", "ISO 230-2:2014"}, {"run_id", run_id},
          {"targets", r.positions.size()}, {"min_cycles", r.min_cycles},   {"B_um", opt(r.B_um)},
          {"B_mean_um", opt(r.B_mean_um)}, {"R_up_um", opt(r.R_up_um)},    {"R_down_um", opt(r.R_down_um)},
          {"R_um", opt(r.R_um)},           {"E_up_um", opt(r.E_up_um)},    {"E_down_um", opt(r.E_down_um)},
          {"E_um", opt(r.E_um)},           {"M_um", opt(r.M_um)},          {"A_up_um", opt(r.A_up_um)},
          {"A_down_um", opt(r.A_down_um)}, {"A_um", opt(r.A_um)},          {"positions", positions},
          {"warnings", warnings}};
}

nlohmann::json SimulationCheck::document() const {
  return {{"datum_offset_um", datum_offset_um},
          {"max_abs_um", max_abs_um},
          {"rms_um", rms_um},
          {"compared_means", compared_means}};
}

nlohmann::json LinearCampaignResult::document() const {
  nlohmann::json list = nlohmann::json::array();
  for (const auto& r : runs) list.push_back(r.document());
  return {{"schema_version", 1}, {"campaign_id", campaign_id}, {"runs", list}};
}

nlohmann::json LinearRunResult::document() const {
  nlohmann::json j = {{"schema_version", 1},
                      {"run_id", run_id},
                      {"campaign_id", campaign_id},
                      {"status", status},
                      {"targets", targets}};
  if (status != "completed") return j;
  if (!iso230_2) {
    j["measures"] = measures;
    j["unit"] = unit;
    return j;
  }
  j["iso230_2"] = iso230_2->document();
  if (simulation_check) j["simulation_check"] = simulation_check->document();
  return j;
}

Iso230Analysis analyzeIso230_2(Session& session, storage::Id run_id) {
  auto& store = session.store();
  const auto run = store.run(run_id);
  if (run.kind != storage::run_kind::kLinear)
    throw InputError(
        fmt::format("run {} is {}, not a linear positioning run", run_id, storage::run_kind::aRunOf(run.kind)));
  const auto plan = nlohmann::json::parse(run.plan_json, nullptr, false);
  if (!plan.is_discarded() && plan.contains("measures") && plan["measures"] != "E" + run.axis + run.axis) {
    throw InputError(fmt::format("run {} measures {}, not positioning: ISO 230-2 evaluates positioning runs (E{}{})",
                                 run_id, plan["measures"].get<std::string>(), run.axis, run.axis));
  }
  const auto targets = store.targets(run_id);
  if (targets.empty()) throw InputError(fmt::format("run {} has no captured targets", run_id));
  Iso230Analysis a;
  a.run_id = run_id;
  a.axis = run.axis;
  a.run_name = run.name;
  a.result = evaluateTargets(targets);
  if (run.status != storage::run_status::kCompleted && run.status != storage::run_status::kImported) {
    const bool recording = run.status == storage::run_status::kRunning && !run.stale;
    a.warnings.push_back(fmt::format("run {} is {}: {} targets measured, part of its plan ({})", run_id,
                                     run.stale ? "interrupted" : run.status, run.target_count,
                                     recording ? "still recording" : fmt::format("mtcal resume {}", run_id)));
  }
  if (a.result.min_cycles < 5) {
    a.warnings.push_back(
        fmt::format("only {} cycle(s) at some target: the standards ask for at least 5", a.result.min_cycles));
  }
  a.result_id =
      session
          .storeResult(run_id, "iso230-2", "ISO 230-2:2014 / mtcal " + std::string(kVersion), "{}", a.document().dump())
          .value_or(0);
  return a;
}

namespace {

/// ISO 230-2's E and M of the simulated machine itself at a run's targets; none for a real one,
/// nor for readings imported from a file (of a machine named like a simulated one, say a
/// simulated run exported and imported again: the file's origin is not known).
std::pair<std::optional<double>, std::optional<double>> truthFigures(storage::Store& store, const storage::RunInfo& run,
                                                                     const processing::Iso230Result& result) {
  if (run.status == storage::run_status::kImported) return {};
  auto machine = simulationFromDescription(store.machineDescriptionOfRun(run.id));
  if (!machine) return {};
  applyCompensation(run.compensation_json, *machine);
  const auto plan = acquisition::LinearPlan::fromJson(nlohmann::json::parse(run.plan_json), "stored plan");
  mocks::WorldClock clock;
  mocks::VirtualMachine vm(*machine, clock);
  for (const auto& [other, position_mm] : plan.line_position_mm) vm.moveTo(mocks::parseAxis(other), position_mm);
  const auto axis = mocks::parseAxis(plan.axis);
  double high = -INFINITY, low = INFINITY, mean_high = -INFINITY, mean_low = INFINITY;
  for (const auto& p : result.positions) {
    const double up = vm.staticErrorUm(axis, plan.reflector_offset_mm, p.target_mm, +1);
    const double down = vm.staticErrorUm(axis, plan.reflector_offset_mm, p.target_mm, -1);
    high = std::max({high, up, down}), low = std::min({low, up, down});
    mean_high = std::max(mean_high, (up + down) / 2.0), mean_low = std::min(mean_low, (up + down) / 2.0);
  }
  return {high - low, mean_high - mean_low};
}

}  // namespace

nlohmann::json PositioningAnalysis::document() const {
  nlohmann::json figures = nlohmann::json::array();
  for (const auto& f : evaluation.figures)
    figures.push_back({{"symbol", f.symbol}, {"name", f.name}, {"value_um", f.value_um}});
  nlohmann::json means = nlohmann::json::array();
  for (const auto& p : iso230_2.result.positions)
    means.push_back(
        {{"target_mm", p.target_mm}, {"mean_up_um", opt(p.mean_up_um)}, {"mean_down_um", opt(p.mean_down_um)}});
  nlohmann::json d{{"schema_version", 1},
                   {"run_id", iso230_2.run_id},
                   {"axis", iso230_2.axis},
                   {"standard", evaluation.standard},
                   {"title", evaluation.title},
                   {"definitions_verified", evaluation.definitions_verified},
                   {"note", evaluation.note},
                   {"figures", figures},
                   {"means", means},
                   {"warnings", iso230_2.warnings}};
  if (truth_E_um) d["simulation_truth"] = {{"E_um", *truth_E_um}, {"M_um", *truth_M_um}};
  return d;
}

PositioningAnalysis analyzeLinear(Session& session, storage::Id run_id, const std::string& standard) {
  PositioningAnalysis a;
  a.iso230_2 = analyzeIso230_2(session, run_id);
  a.evaluation = processing::evaluateStandard(a.iso230_2.result, standard);
  const auto run = session.store().run(run_id);
  std::tie(a.truth_E_um, a.truth_M_um) = truthFigures(session.store(), run, a.iso230_2.result);
  session.storeResult(run_id, "positioning", a.evaluation.title + " / mtcal " + std::string(kVersion),
                      nlohmann::json{{"standard", standard}}.dump(), a.document().dump());
  return a;
}

nlohmann::json RunComparison::document() const {
  nlohmann::json figures = nlohmann::json::array();
  for (const auto& f : before.evaluation.figures) {
    const double after_um = after.evaluation.value(f.symbol);
    nlohmann::json row{{"symbol", f.symbol},
                       {"name", f.name},
                       {"before_um", f.value_um},
                       {"after_um", after_um},
                       {"change_um", after_um - f.value_um}};
    // A percentage of a range (not of a signed mean such as B mean).
    row["change_pct"] = f.value_um > 0.0 && after_um >= 0.0
                            ? nlohmann::json(100.0 * (after_um - f.value_um) / f.value_um)
                            : nlohmann::json(nullptr);
    figures.push_back(row);
  }
  return {{"schema_version", 1},
          {"axis", before.iso230_2.axis},
          {"standard", before.evaluation.standard},
          {"title", before.evaluation.title},
          {"figures", figures},
          {"before", before.document()},
          {"after", after.document()},
          {"warnings", warnings}};
}

RunComparison compareRuns(Session& session, storage::Id before, storage::Id after, const std::string& standard) {
  RunComparison c{analyzeLinear(session, before, standard), analyzeLinear(session, after, standard), {}};
  if (c.before.iso230_2.axis != c.after.iso230_2.axis) {
    throw InputError(fmt::format("run {} measured axis {} and run {} axis {}: compare runs of one axis", before,
                                 c.before.iso230_2.axis, after, c.after.iso230_2.axis));
  }
  if (before == after) c.warnings.push_back(fmt::format("run {} compared with itself", before));
  const auto machine_before = session.store().run(before).machine_name,
             machine_after = session.store().run(after).machine_name;
  if (machine_before != machine_after) {
    c.warnings.push_back(
        fmt::format("the runs measured different machines: '{}' and '{}'", machine_before, machine_after));
  }
  const auto& b = c.before.iso230_2.result.positions;
  const auto& a = c.after.iso230_2.result.positions;
  const double tolerance_mm =
      0.5 * std::min(b.back().target_mm - b.front().target_mm, a.back().target_mm - a.front().target_mm) /
      static_cast<double>(std::max(b.size(), a.size()));
  if (std::abs(b.front().target_mm - a.front().target_mm) > tolerance_mm ||
      std::abs(b.back().target_mm - a.back().target_mm) > tolerance_mm) {
    c.warnings.push_back(fmt::format("the runs measured different ranges: {:g} to {:g} mm and {:g} to {:g} mm",
                                     b.front().target_mm, b.back().target_mm, a.front().target_mm, a.back().target_mm));
  }
  for (const auto& f : c.before.evaluation.figures) {
    bool found = false;
    for (const auto& g : c.after.evaluation.figures) found = found || g.symbol == f.symbol;
    if (!found)
      throw InputError(
          fmt::format("run {} has no {} ({}): was it measured in one direction only?", after, f.symbol, f.name));
  }
  return c;
}

nlohmann::json AirIndex::document() const {
  return {{"schema_version", 1}, {"n", n}, {"model", model}, {"wavelength_air_nm", wavelength_air_nm}};
}

AirIndex airIndex(const std::string& model, const processing::AirState& air, double vacuum_wavelength_nm) {
  processing::AirIndexModel m;
  if (model == "edlen") {
    m = processing::AirIndexModel::kEdlen;
  } else if (model == "ciddor") {
    m = processing::AirIndexModel::kCiddor;
  } else {
    throw InputError("--model must be edlen or ciddor, got '" + model + "'");
  }
  AirIndex a;
  a.model = model;
  a.n = processing::airIndex(m, air, vacuum_wavelength_nm);
  a.wavelength_air_nm = vacuum_wavelength_nm / a.n;
  return a;
}

LinearCampaignResult runLinear(Session& session, const LinearRunRequest& request) {
  std::vector<acquisition::LinearPlan> plans = request.plans;
  if (plans.empty()) plans.push_back(acquisition::LinearPlan::demo());
  const auto& plan = plans.front();
  const auto uri = drivers::DeviceUri::parse(request.device_uri);
  if (plans.size() > 1 && (uri.scheme != "mock" || request.triggered)) {
    throw InputError(
        "a machine runs one part program at a time: give one plan per run with --triggered or a real device");
  }
  const std::string campaign_name =
      plans.size() == 1 ? plan.name
                        : fmt::format("{} plans, from '{}' to '{}'", plans.size(), plan.name, plans.back().name);
  LinearCampaignResult out;
  if (uri.scheme != "mock" && !request.simulation.compensation.empty()) {
    throw InputError(
        "--compensation: the simulated machine's controller applies tables (mock:// devices); a real "
        "machine's table is loaded into its own controller");
  }
  if (uri.scheme != "mock") {
    // A real instrument on a real machine: the CNC runs the plan's part program.
    Operator& person = session.person("a real machine runs the plan's part program when the operator starts it");
    drivers::Registry registry;
    drivers::registerBuiltInDrivers(registry);
    const LinearRig rig{registry, nullptr, nullptr, [&] {
                          person.tell(fmt::format(
                              "Ready: start the part program of this plan on the machine now (mtcal plan gcode {}). "
                              "It approaches the datum at {} mm; each target is captured while the machine holds it.",
                              request.plan_path, plan.datum_mm));
                        }};
    const auto campaign = [&] {
      return out.campaign_id = realCampaign(session.store(Access::kRecord), request.machine, plan.name);
    };
    out.runs.push_back(acquire(session, rig, plan, request.device_uri, campaign, std::nullopt, nullptr));
    return out;
  }
  SimulationOptions simulation = request.simulation;
  simulation.records_tables = true;
  for (auto& t : simulation.compensation)
    if (t.axis.empty()) t.axis = plan.axis;  // a table without an axis is the plan's
  auto machine = simulatedMachine(simulation);
  // Each session on the simulated machine draws its own per-approach scatter, numbered by the
  // runs the archive holds (the same archive history, the same draw): a verification run does
  // not repeat the scatter of the run its table came from.
  if (std::filesystem::exists(session.options().db_path)) machine.config.session = session.store().listRuns().size();
  if (!(request.simulation.time_scale > 0.0)) throw InputError("--time-scale must be > 0");
  checkTravel(plans, request.plan_path, machine.config);
  Simulation sim(machine.config, demoInterferometer(), request.simulation.time_scale);
  // One campaign for the plans, created with the first run.
  const auto campaign = [&] {
    if (out.campaign_id == 0)
      out.campaign_id = simulatedCampaign(session.store(Access::kRecord), machine, campaign_name);
    return out.campaign_id;
  };
  if (!request.triggered) {
    // One campaign on one virtual machine: the simulated operator sets up the optics for each plan.
    const LinearRig rig{sim.registry, &sim.controller, &sim.run_clock, {}, machine.compensation_json};
    for (const auto& p : plans) {
      sim.setUpFor(p);
      out.runs.push_back(acquire(session, rig, p, request.device_uri, campaign, std::nullopt, &sim));
      if (out.interrupted()) break;
    }
    return out;
  }
  // Rehearsal of the real-machine workflow: the virtual CNC runs the generated program.
  sim.setUpFor(plan);
  const auto program = mocks::parseGcode(acquisition::linearGcode(plan));
  std::optional<mocks::CncProgramRun> cnc;
  const LinearRig rig{sim.registry, nullptr, &sim.run_clock, [&] { cnc.emplace(sim.world.machine, program); },
                      machine.compensation_json};  // cycle start
  out.runs.push_back(acquire(session, rig, plan, request.device_uri, campaign, std::nullopt, &sim));
  if (cnc) cnc->finish();  // the program's error, if any
  return out;
}

LinearRunResult resumeLinear(Session& session, storage::Id run_id, double time_scale) {
  const auto rig = storedRig(session.store(), run_id);
  const auto plan = acquisition::LinearPlan::fromJson(nlohmann::json::parse(rig.run.plan_json), "stored plan");
  if (!rig.simulation) {
    throw InputError(fmt::format(
        "run {} was measured on a real machine, triggered by its part program: resuming it needs a program for the "
        "remaining targets; measure the axis again with a new run (mtcal run linear PLAN --device ...)",
        run_id));
  }
  if (!(time_scale > 0.0)) throw InputError("--time-scale must be > 0");
  Simulation sim(*rig.simulation, demoInterferometer(), time_scale);
  sim.setUpFor(plan);
  const LinearRig linear_rig{sim.registry, &sim.controller, &sim.run_clock, {}};
  return acquire(session, linear_rig, plan, rig.uriOf("measuring"), {}, run_id, &sim);
}

acquisition::LinearImport importLinear(Session& session, const std::string& path,
                                       acquisition::LinearImportOptions options) {
  options.software_version = kVersion;
  acquisition::checkLinearImportOptions(options, "import linear");  // before a file (or a pipe) is read whole
  auto file = detail::readImportedFile(path);
  options.source_sha256 = file.sha256;
  auto imported = acquisition::importLinearCsv(detail::storeWhenNeeded(session), file.bytes, path, options);
  auto& store = session.store(Access::kCreate);
  for (const auto id : imported.run_ids) session.recordRun(id, {});
  for (auto& warning : detail::importedBefore(store, options.source_sha256, path, imported.run_ids))
    imported.warnings.push_back(std::move(warning));
  for (const auto& warning : imported.warnings) session.observer().onMessage("warning", warning);
  return imported;
}

acquisition::CampaignImport importCampaign(Session& session, const std::string& manifest_path,
                                           acquisition::CampaignImportOptions options) {
  options.software_version = kVersion;
  const auto imported = acquisition::importLinearCampaign(detail::storeWhenNeeded(session), manifest_path, options);
  for (const auto id : imported.run_ids) session.recordRun(id, {});
  for (const auto& warning : imported.warnings) session.observer().onMessage("warning", warning);
  return imported;
}

}  // namespace mtcal::services
