#include "commands.h"

#include <fmt/format.h>

#include <fstream>

#include "cli_session.h"
#include "mtcal/error.h"
#include "mtcal/services/archive.h"
#include "mtcal/services/plans.h"
#include "report.h"

namespace mtcal::app {
namespace {

// Prints how a linear run ended: the interruption, a run that feeds the error model, or the
// ISO 230-2 evaluation with the simulation's check. @return the exit code
int printLinearRun(const Globals& g, const services::LinearRunResult& r, const std::string& plan_name) {
  if (g.json) {
    *g.out << r.document().dump() << "\n";
    return r.status == "completed" ? 0 : 1;
  }
  if (r.status != "completed") {
    *g.out << fmt::format("run {} interrupted after {} targets; continue it with: mtcal resume {}\n", r.run_id, r.targets, r.run_id);
    return 1;
  }
  if (!r.iso230_2) {
    // Straightness and angular runs are not ISO 230-2 material: they feed the error model.
    *g.out << fmt::format("run {} completed: {} ({}), {} targets. Identify it with: mtcal model identify {} --machine ...\n", r.run_id,
                          r.measures, r.unit, r.targets, r.run_id);
    return 0;
  }
  *g.out << fmt::format("run {} completed: {}\n\n", r.run_id, plan_name);
  printIso230Table(*g.out, r.iso230_2->result);
  if (r.simulation_check) {
    *g.out << fmt::format(
        "\nSimulation check: the measured mean deviations match the virtual machine's true errors\n"
        "within {:.2f} um (RMS {:.2f} um), after removing the common datum offset of {:+.2f} um.\n",
        r.simulation_check->max_abs_um, r.simulation_check->rms_um, r.simulation_check->datum_offset_um);
  }
  *g.out << fmt::format("Stored in {} as run {}. See it again with: mtcal analyze iso230-2 {}\n", g.db, r.run_id, r.run_id);
  return 0;
}

}  // namespace

int runLinear(const Globals& g, const std::vector<std::string>& plan_paths, const std::string& device_uri,
              const SimulationOptions& sim_options, const RunOptions& run_options) {
  services::LinearRunRequest request;
  for (const auto& path : plan_paths) request.plans.push_back(acquisition::LinearPlan::load(path));  // all valid before any run
  request.plan_path = plan_paths.empty() ? "" : plan_paths.front();
  request.device_uri = device_uri;
  request.simulation = sim_options;
  request.triggered = run_options.triggered;
  request.machine = run_options.machine;
  CliSession cli(g);
  const auto campaign = services::runLinear(cli.session, request);
  cli.observer.finish();
  const auto plans = request.plans.empty() ? std::vector{acquisition::LinearPlan::demo()} : request.plans;
  for (std::size_t i = 0; i < campaign.runs.size(); ++i) {
    if (const int code = printLinearRun(g, campaign.runs[i], plans[i].name); code != 0) return code;  // interrupted: stop here
  }
  return 0;
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
  CliSession cli(g);
  const auto r = services::resumeLinear(cli.session, run_id, time_scale);
  cli.observer.finish();
  return printLinearRun(g, r, cli.session.store().run(run_id).name);
}

int listRuns(const Globals& g) {
  CliSession cli(g);
  const auto runs = services::listRuns(cli.session);
  if (g.json) {
    nlohmann::json list = nlohmann::json::array();
    for (const auto& r : runs) list.push_back(services::runDocument(r));
    *g.out << nlohmann::json{{"runs", list}}.dump() << "\n";
    return 0;
  }
  if (runs.empty()) {
    *g.out << "no runs in " << g.db << "\n";
    return 0;
  }
  *g.out << fmt::format("{:>4} {:>5}  {:<24} {:<11} {:<8} {:<5} {:>20}  {:<26} {}\n", "id", "camp.", "started (UTC)", "status", "kind",
                        "axis", "measured", "machine", "name");
  for (const auto& r : runs) {
    *g.out << fmt::format("{:>4} {:>5}  {:<24} {:<11} {:<8} {:<5} {:>20}  {:<26} {}\n", r.id, fmt::format("c{}", r.campaign_id),
                          r.started_at, r.status, r.kind, r.axis,
                          fmt::format("{} {}", r.measurement_count, storage::measurementUnit(r.kind)), r.machine_name, r.name);
  }
  return 0;
}

int showRun(const Globals& g, storage::Id run_id) {
  CliSession cli(g);
  const auto d = services::showRun(cli.session, run_id);
  if (g.json) {
    *g.out << d.document().dump() << "\n";
    return 0;
  }
  const auto& run = d.run;
  *g.out << fmt::format("run {}: {}\n", run.id, run.name);
  *g.out << fmt::format("  kind {}  axis {}  status {}  source {}\n", run.kind, run.axis, run.status, run.source);
  *g.out << fmt::format("  machine {}  campaign c{} ({})\n", run.machine_name, run.campaign_id, run.campaign_name);
  *g.out << fmt::format("  started {}  finished {}  mtcal {}  operator {}\n", run.started_at, run.finished_at.value_or("-"),
                        run.software_version, run.operator_name.empty() ? "-" : run.operator_name);
  for (const auto& i : d.instruments) {
    *g.out << fmt::format("  instrument ({}): {} {} serial {}{}\n", i.role, i.info.kind, i.info.model, i.info.serial,
                          i.info.firmware.empty() ? "" : ", firmware " + i.info.firmware);
  }
  if (run.kind == storage::run_kind::kLinear) {
    *g.out << fmt::format("  {} targets captured", run.measurement_count);
    if (run.source == "acquired") *g.out << fmt::format(", {} raw samples", d.raw_samples);
  } else {
    *g.out << fmt::format("  {}, {} {}", run.source, run.measurement_count, storage::measurementUnit(run.kind));
  }
  *g.out << "\n";
  if (run.kind == storage::run_kind::kThermal) {
    std::vector<std::string> names;
    for (const auto& ch : d.thermal_channels) names.push_back(fmt::format("{} ({})", ch.name, ch.unit));
    *g.out << "  thermal channels: " << fmt::format("{}", fmt::join(names, ", ")) << "\n";
  }
  if (!d.channels.empty()) *g.out << "  auxiliary channels: " << fmt::format("{}", fmt::join(d.channels, ", ")) << "\n";
  *g.out << "  plan: " << run.plan_json << "\n";
  if (!d.events.empty()) {
    *g.out << "events:\n";
    for (const auto& e : d.events) *g.out << fmt::format("  {} {:<7} {}\n", e.created_at, e.level, e.message);
  }
  return 0;
}

int importLinear(const Globals& g, const std::string& path, acquisition::LinearImportOptions options) {
  CliSession cli(g);
  const storage::Id id = services::importLinear(cli.session, path, std::move(options));
  if (g.json) {
    *g.out << nlohmann::json{{"run_id", id}}.dump() << "\n";
  } else {
    *g.out << id << "\n";
  }
  return 0;
}

int analyzeIso230(const Globals& g, storage::Id run_id) {
  CliSession cli(g);
  const auto a = services::analyzeIso230_2(cli.session, run_id);
  if (g.json) {
    *g.out << a.document().dump() << "\n";
    return 0;
  }
  const auto run = cli.session.store().run(run_id);
  *g.out << fmt::format("run {} ({} axis, {}): ISO 230-2 evaluation\n\n", run_id, run.axis, run.name);
  printIso230Table(*g.out, a.result);
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
  const auto p = services::partProgram(plan_path, machine_file);
  if (output_path.empty() || output_path == "-") {
    *g.out << p.program;
    return 0;
  }
  std::ofstream out(output_path);
  if (!out) throw InputError(output_path + ": cannot write");
  out << p.program;
  if (!out.flush()) throw InputError(output_path + ": write failed");
  if (g.json) *g.out << nlohmann::json{{"program", output_path}, {"targets", p.targets}}.dump() << "\n";
  return 0;
}

int listDevices(const Globals& g, const SimulationOptions& sim_options) {
  const auto found = services::scanDevices(sim_options);
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
