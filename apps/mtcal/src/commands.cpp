#include "commands.h"
#include "mtcal/acquisition/thermal_run.h"
#include "mtcal/acquisition/gantry_test.h"

#include <fmt/format.h>

#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <functional>
#include <thread>

#include "mtcal/acquisition/linear_run.h"
#include "mtcal/app/version.h"
#include "mtcal/error.h"
#include "mtcal/mocks/gcode_player.h"
#include "mtcal/processing/air_index.h"
#include "report.h"
#include "mtcal/services/workshop.h"

namespace mtcal::app {
namespace {

namespace ifm = drivers::interferometer;


// Evaluates a finished run, stores the result and prints it. Shared by demo, run and resume.
processing::Iso230Result evaluateAndStore(const Globals& g, storage::Store& store, storage::Id run_id, nlohmann::json& j) {
  const auto result = evaluateRun(store.targets(run_id));
  j = iso230Json(result);
  j["run_id"] = run_id;
  store.addResult(run_id, "iso230-2", "ISO 230-2:2014 / mtcal " + std::string(kVersion), "{}", j.dump());
  if (!g.json) printIso230Table(*g.out, result);
  return result;
}

// Differences between what the demo measured and the simulated truth, after removing the
// common offset of the datum capture (ISO 230-2 values are all ranges and differences).
nlohmann::json simulationCheck(const processing::Iso230Result& result, const Simulation& sim,
                               const acquisition::LinearPlan& plan) {
  const auto& machine = sim.world.machine;
  const auto& offset = plan.reflector_offset_mm;
  const auto axis = mocks::parseAxis(plan.axis);
  const double datum_um = machine.staticErrorUm(axis, offset, plan.datum_mm, +1);
  std::vector<double> diffs;
  for (const auto& p : result.positions) {
    if (p.mean_up_um) diffs.push_back(*p.mean_up_um - (machine.staticErrorUm(axis, offset, p.target_mm, +1) - datum_um));
    if (p.mean_down_um) {
      diffs.push_back(*p.mean_down_um - (machine.staticErrorUm(axis, offset, p.target_mm, -1) - datum_um));
    }
  }
  double mean = 0.0;
  for (double d : diffs) mean += d;
  mean /= static_cast<double>(diffs.size());
  double max_abs = 0.0, ss = 0.0;
  for (double d : diffs) {
    max_abs = std::max(max_abs, std::abs(d - mean));
    ss += (d - mean) * (d - mean);
  }
  return {{"datum_offset_um", mean}, {"max_abs_um", max_abs}, {"rms_um", std::sqrt(ss / static_cast<double>(diffs.size()))},
          {"compared_means", diffs.size()}};
}

struct Acquired {
  storage::Id run_id = 0;
  acquisition::RunOutcome outcome = acquisition::RunOutcome::kCompleted;
};

// Runs (or resumes) a linear plan: with a controller the scheduler moves the machine,
// without one the machine runs the plan's part program and targets are captured when the
// reading holds still at them.
Acquired acquireLinear(const Globals& g, storage::Store& store, const drivers::Registry& registry,
                       acquisition::MachineController* controller, acquisition::RunClock* run_clock,
                       const acquisition::LinearPlan& plan, const std::string& device_uri, std::optional<storage::Id> campaign_id,
                       std::optional<storage::Id> resume_id, std::function<void()> on_waiting_for_program = {}) {
  auto device = registry.openAs<ifm::InterferometerDevice>(device_uri);
  const auto info = device->info();
  const storage::Id instrument_id =
      store.ensureInstrument({info.kind, info.model, info.serial, info.firmware, device_uri});
  ProgressBar bar(*g.err, g.terminal);
  acquisition::LinearRunOptions options;
  options.stop_requested = g.stop;
  options.software_version = kVersion;
  options.on_waiting_for_program = std::move(on_waiting_for_program);
  options.run_clock = run_clock;
  if (!g.json) {
    options.on_progress = [&bar](const acquisition::LinearProgress& p) {
      bar.update(p.done, p.total,
                 fmt::format("{:>8.3f} mm {:<4} c{} {:+7.2f} um", p.target_mm, p.direction > 0 ? "up" : "down",
                             p.cycle, p.deviation_um));
    };
  }
  acquisition::LinearRun run(store, *device, controller, options);
  Acquired a;
  try {
    if (resume_id) {
      run.resume(*resume_id);
      a.run_id = *resume_id;
    } else {
      a.run_id = run.start(plan, *campaign_id, instrument_id);
    }
  } catch (...) {
    bar.finish();
    throw;
  }
  bar.finish();
  a.outcome = run.outcome();
  return a;
}

int reportAcquired(const Globals& g, storage::Store& store, const Acquired& a, const Simulation* sim,
                   const acquisition::LinearPlan& plan) {
  if (a.outcome == acquisition::RunOutcome::kInterrupted) {
    const auto info = store.run(a.run_id);
    if (g.json) {
      *g.out << nlohmann::json{{"run_id", a.run_id}, {"status", info.status}, {"targets", info.target_count}}.dump()
             << "\n";
    } else {
      *g.out << fmt::format("run {} interrupted after {} targets; continue it with: mtcal resume {}\n", a.run_id,
                            info.target_count, a.run_id);
    }
    return 1;
  }
  if (!acquisition::measuresPositioning(plan)) {
    // Straightness and angular runs are not ISO 230-2 material: they feed the error model.
    const auto info = store.run(a.run_id);
    const std::string measures = acquisition::measuredError(plan);
    if (g.json) {
      *g.out << nlohmann::json{{"run_id", a.run_id}, {"status", "completed"}, {"measures", measures},
                               {"unit", info.value_unit}, {"targets", info.target_count}}
                    .dump()
             << "\n";
    } else {
      *g.out << fmt::format("run {} completed: {} ({}), {} targets. Identify it with: mtcal model identify {} --machine ...\n",
                            a.run_id, measures, info.value_unit, info.target_count, a.run_id);
    }
    return 0;
  }
  if (!g.json) *g.out << fmt::format("run {} completed: {}\n\n", a.run_id, plan.name);
  nlohmann::json iso;
  const auto result = evaluateAndStore(g, store, a.run_id, iso);
  nlohmann::json out = {{"run_id", a.run_id}, {"status", "completed"}, {"iso230_2", iso}};
  if (sim) {
    const auto check = simulationCheck(result, *sim, plan);
    out["simulation_check"] = check;
    if (!g.json) {
      *g.out << fmt::format(
          "\nSimulation check: the measured mean deviations match the virtual machine's true errors\n"
          "within {:.2f} um (RMS {:.2f} um), after removing the common datum offset of {:+.2f} um.\n",
          check["max_abs_um"].get<double>(), check["rms_um"].get<double>(), check["datum_offset_um"].get<double>());
    }
  }
  if (g.json) {
    *g.out << out.dump() << "\n";
  } else {
    *g.out << fmt::format("Stored in {} as run {}. See it again with: mtcal analyze iso230-2 {}\n", g.db, a.run_id,
                          a.run_id);
  }
  return 0;
}

}  // namespace

int runLinear(const Globals& g, const std::vector<std::string>& plan_paths, const std::string& device_uri,
              const SimulationOptions& sim_options, const RunOptions& run_options) {
  std::vector<acquisition::LinearPlan> plans;
  for (const auto& path : plan_paths) plans.push_back(acquisition::LinearPlan::load(path));  // all valid before any run
  if (plans.empty()) plans.push_back(acquisition::LinearPlan::demo());
  const auto& plan = plans.front();
  const std::string plan_path = plan_paths.empty() ? "" : plan_paths.front();
  const auto uri = drivers::DeviceUri::parse(device_uri);
  if (plans.size() > 1 && (uri.scheme != "mock" || run_options.triggered)) {
    throw InputError("a machine runs one part program at a time: give one plan per run with --triggered or a real device");
  }
  const std::string campaign_name =
      plans.size() == 1 ? plan.name : fmt::format("{} plans, from '{}' to '{}'", plans.size(), plan.name, plans.back().name);
  if (uri.scheme != "mock") {
    // A real instrument on a real machine: the CNC runs the plan's part program.
    drivers::Registry registry;
    drivers::registerBuiltInDrivers(registry);
    storage::Store store(g.db);
    const storage::Id machine_id = store.ensureMachine(run_options.machine, "", "{}");
    const storage::Id campaign_id = store.addCampaign(machine_id, plan.name);
    const Acquired a = acquireLinear(g, store, registry, nullptr, nullptr, plan, device_uri, campaign_id, std::nullopt, [&] {
      *g.err << "Ready: start the part program of this plan on the machine now (mtcal plan gcode " << plan_path
             << "). It approaches the datum at " << plan.datum_mm << " mm; each target is captured while the "
             << "machine holds it.\n";
    });
    return reportAcquired(g, store, a, nullptr, plan);
  }
  std::string file_json;
  const auto config = machineConfig(sim_options, &file_json);
  if (!(sim_options.time_scale > 0.0)) throw InputError("--time-scale must be > 0");
  Simulation sim(config, demoInterferometer(), sim_options.time_scale);
  sim.setUpFor(plan);
  storage::Store store(g.db);
  const storage::Id machine_id = store.ensureMachine(machineName(config, !file_json.empty()), "simulated machine",
                                                     simulationDescription(config, file_json));
  const storage::Id campaign_id = store.addCampaign(machine_id, campaign_name);
  if (!run_options.triggered) {
    // One campaign on one virtual machine: the operator sets up the optics for each plan.
    for (const auto& p : plans) {
      sim.setUpFor(p);
      const Acquired a = acquireLinear(g, store, sim.registry, &sim.controller, &sim.run_clock, p, device_uri, campaign_id, std::nullopt);
      if (const int code = reportAcquired(g, store, a, &sim, p); code != 0) return code;  // interrupted: stop here
    }
    return 0;
  }
  // Rehearsal of the real-machine workflow: the virtual CNC runs the generated program.
  const auto program = mocks::parseGcode(acquisition::linearGcode(plan));
  std::optional<mocks::CncProgramRun> cnc;
  const Acquired a = acquireLinear(g, store, sim.registry, nullptr, &sim.run_clock, plan, device_uri, campaign_id, std::nullopt,
                                   [&] { cnc.emplace(sim.world.machine, program); });  // cycle start
  if (cnc) cnc->finish();  // the program's error, if any
  return reportAcquired(g, store, a, &sim, plan);
}

int demo(const Globals& g, const SimulationOptions& sim) {
  if (!g.json) {
    *g.out << "mtcal demo: ISO 230-2 calibration of the X axis of a simulated 3-axis machine\n"
           << "  laser interferometer: mock://interferometer through the real USB protocol driver\n"
           << "  plan: X 50 to 600 mm, a node every 20 mm, 9 cycles, both directions\n"
           << "  database: " << g.db << "\n\n";
  }
  return runLinear(g, {}, "mock://interferometer", sim, RunOptions{});  // no plan file: the demo plan
}

int resumeRun(const Globals& g, storage::Id run_id, double time_scale) {
  storage::Store store(g.db);
  const auto info = store.run(run_id);
  if (!info.instrument_id) throw InputError(fmt::format("run {} has no instrument: it was imported", run_id));
  storage::Statement q(store.database(),
                       "SELECT i.driver_uri, m.config_json FROM runs r JOIN instruments i ON i.id = r.instrument_id"
                       " JOIN campaigns c ON c.id = r.campaign_id JOIN machines m ON m.id = c.machine_id WHERE r.id = ?");
  q.bind(1, run_id);
  q.step();
  const std::string uri = q.getText(0);
  const auto config = simulationFromDescription(q.getText(1));
  const auto plan = acquisition::LinearPlan::fromJson(nlohmann::json::parse(info.plan_json), "stored plan");
  Simulation sim(config, demoInterferometer(), time_scale);
  sim.setUpFor(plan);
  const Acquired a = acquireLinear(g, store, sim.registry, &sim.controller, &sim.run_clock, plan, uri, std::nullopt, run_id);
  return reportAcquired(g, store, a, &sim, plan);
}

int listRuns(const Globals& g) {
  storage::Store store(g.db);
  const auto runs = store.listRuns();
  if (g.json) {
    nlohmann::json list = nlohmann::json::array();
    for (const auto& r : runs) list.push_back(runJson(r));
    *g.out << nlohmann::json{{"runs", list}}.dump() << "\n";
    return 0;
  }
  if (runs.empty()) {
    *g.out << "no runs in " << g.db << "\n";
    return 0;
  }
  *g.out << fmt::format("{:>4}  {:<24} {:<11} {:<8} {:<4} {:>7}  {:<26} {}\n", "id", "started (UTC)", "status", "kind",
                        "axis", "targets", "machine", "name");
  for (const auto& r : runs) {
    *g.out << fmt::format("{:>4}  {:<24} {:<11} {:<8} {:<4} {:>7}  {:<26} {}\n", r.id, r.started_at, r.status, r.kind,
                          r.axis, r.target_count, r.machine_name, r.name);
  }
  return 0;
}

int showRun(const Globals& g, storage::Id run_id) {
  storage::Store store(g.db);
  const auto run = store.run(run_id);
  const auto targets = store.targets(run_id);
  const auto events = store.events(run_id);
  const auto channels = store.channelNames(run_id);
  if (g.json) {
    nlohmann::json j = runJson(run);
    j["plan"] = nlohmann::json::parse(run.plan_json);
    j["channels"] = channels;
    nlohmann::json t = nlohmann::json::array();
    for (const auto& r : targets) {
      t.push_back({{"seq", r.seq},
                   {"target_mm", r.target_mm},
                   {"direction", r.direction > 0 ? "up" : "down"},
                   {"cycle", r.cycle},
                   {"measured_mm", r.measured_mm},
                   {"deviation_um", r.deviation_um},
                   {"samples", r.sample_count}});
    }
    j["target_values"] = t;
    if (run.kind == "gantry") j["tracker_points"] = store.trackerPointCount(run_id);
    if (run.kind == "thermal") {
      j["thermal_samples"] = store.thermalSampleCount(run_id);
      nlohmann::json c = nlohmann::json::array();
      for (const auto& ch : store.thermalChannels(run_id)) c.push_back({{"name", ch.name}, {"kind", ch.kind}, {"unit", ch.unit}});
      j["thermal_channels"] = c;
    }
    nlohmann::json e = nlohmann::json::array();
    for (const auto& ev : events) e.push_back({{"level", ev.level}, {"message", ev.message}, {"time", ev.created_at}});
    j["events"] = e;
    *g.out << j.dump() << "\n";
    return 0;
  }
  *g.out << fmt::format("run {}: {}\n", run.id, run.name);
  *g.out << fmt::format("  kind {}  axis {}  status {}  source {}\n", run.kind, run.axis, run.status, run.source);
  *g.out << fmt::format("  machine {}  campaign {}\n", run.machine_name, run.campaign_name);
  *g.out << fmt::format("  started {}  finished {}  mtcal {}\n", run.started_at, run.finished_at.value_or("-"),
                        run.software_version);
  *g.out << fmt::format("  {} targets captured", targets.size());
  if (run.source == "acquired") *g.out << fmt::format(", {} raw samples", store.sampleCount(run_id));
  if (run.kind == "gantry") *g.out << fmt::format(", {} tracker points", store.trackerPointCount(run_id));
  if (run.kind == "thermal") *g.out << fmt::format(", {} thermal samples", store.thermalSampleCount(run_id));
  *g.out << "\n";
  if (run.kind == "thermal") {
    std::vector<std::string> names;
    for (const auto& ch : store.thermalChannels(run_id)) names.push_back(fmt::format("{} ({})", ch.name, ch.unit));
    *g.out << "  thermal channels: " << fmt::format("{}", fmt::join(names, ", ")) << "\n";
  }
  if (!channels.empty()) *g.out << "  auxiliary channels: " << fmt::format("{}", fmt::join(channels, ", ")) << "\n";
  *g.out << "  plan: " << run.plan_json << "\n";
  if (!events.empty()) {
    *g.out << "events:\n";
    for (const auto& e : events) *g.out << fmt::format("  {} {:<7} {}\n", e.created_at, e.level, e.message);
  }
  return 0;
}

int importLinear(const Globals& g, const std::string& path, acquisition::LinearImportOptions options) {
  options.software_version = kVersion;
  storage::Store store(g.db);
  const storage::Id id = acquisition::importLinearCsv(store, path, options);
  if (g.json) {
    *g.out << nlohmann::json{{"run_id", id}}.dump() << "\n";
  } else {
    *g.out << id << "\n";
  }
  return 0;
}

int analyzeIso230(const Globals& g, storage::Id run_id) {
  storage::Store store(g.db);
  const auto run = store.run(run_id);
  if (run.kind != "linear") throw InputError(fmt::format("run {} is a {} run, not a linear positioning run", run_id, run.kind));
  const auto plan = nlohmann::json::parse(run.plan_json, nullptr, false);
  if (!plan.is_discarded() && plan.contains("measures") && plan["measures"] != "E" + run.axis + run.axis) {
    throw InputError(fmt::format("run {} measures {}, not positioning: ISO 230-2 evaluates positioning runs (E{}{})",
                                 run_id, plan["measures"].get<std::string>(), run.axis, run.axis));
  }
  const auto targets = store.targets(run_id);
  if (targets.empty()) throw InputError(fmt::format("run {} has no captured targets", run_id));
  if (!g.json) *g.out << fmt::format("run {} ({} axis, {}): ISO 230-2 evaluation\n\n", run_id, run.axis, run.name);
  nlohmann::json j;
  evaluateAndStore(g, store, run_id, j);
  if (g.json) *g.out << j.dump() << "\n";
  return 0;
}

int airIndex(const Globals& g, const std::string& model, double temp_c, double pressure_pa, double humidity_pct,
             double co2_ppm, double wavelength_nm) {
  processing::AirIndexModel m;
  if (model == "edlen") {
    m = processing::AirIndexModel::kEdlen;
  } else if (model == "ciddor") {
    m = processing::AirIndexModel::kCiddor;
  } else {
    throw InputError("--model must be edlen or ciddor, got '" + model + "'");
  }
  const double n = processing::airIndex(m, {temp_c, pressure_pa, humidity_pct, co2_ppm}, wavelength_nm);
  if (g.json) {
    *g.out << nlohmann::json{{"n", n}, {"model", model}, {"wavelength_air_nm", wavelength_nm / n}}.dump(-1, ' ', false) << "\n";
  } else {
    *g.out << fmt::format("{:.10f}\n", n);
  }
  return 0;
}

int planGcode(const Globals& g, const std::string& plan_path, const std::string& output_path, const std::string& machine_file) {
  const auto j = nlohmann::json::parse(readTextFile(plan_path), nullptr, false);
  const std::string type = j.is_object() ? j.value("type", "") : "";
  std::string program;
  std::size_t targets = 0;
  if (type == "circle") {
    program = acquisition::circleGcode(acquisition::CirclePlan::fromJson(j, plan_path));
  } else if (type == "thermal") {
    program = acquisition::thermalGcode(acquisition::ThermalPlan::fromJson(j, plan_path));
  } else if (type == "gantry") {
    if (machine_file.empty()) throw InputError("a gantry plan's NC program needs the machine's kinematics: --machine-config FILE");
    const auto plan = acquisition::GantryPlan::fromJson(j, plan_path);
    std::string file_json;
    const auto holes = acquisition::planHoles(plan, machineConfig({1, 1.0, machine_file}, &file_json).kinematics());
    program = acquisition::gantryGcode(plan, holes);
    targets = holes.size();
  } else {
    const auto plan = acquisition::LinearPlan::load(plan_path);
    program = acquisition::linearGcode(plan);
    targets = acquisition::linearTargets(plan).size();
  }
  if (output_path.empty() || output_path == "-") {
    *g.out << program;
    return 0;
  }
  std::ofstream out(output_path);
  if (!out) throw InputError(output_path + ": cannot write");
  out << program;
  if (!out.flush()) throw InputError(output_path + ": write failed");
  if (g.json) {
    *g.out << nlohmann::json{{"program", output_path}, {"targets", targets}}.dump() << "\n";
  }
  return 0;
}

int listDevices(const Globals& g, const SimulationOptions& sim_options) {
  Simulation sim(mocks::VirtualMachineConfig::demo(sim_options.seed), demoInterferometer(), sim_options.time_scale);
  const auto found = sim.registry.scan();
  if (g.json) {
    nlohmann::json list = nlohmann::json::array();
    for (const auto& d : found) list.push_back({{"driver", d.driver}, {"uri", d.uri}});
    *g.out << nlohmann::json{{"devices", list}}.dump() << "\n";
  } else {
    for (const auto& d : found) *g.out << fmt::format("{:<28} {}\n", d.uri, d.driver);
  }
  return 0;
}

}  // namespace mtcal::app
