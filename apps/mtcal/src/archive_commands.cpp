// The archive's commands: the runs listed (mtcal runs), one run shown whole (mtcal show), an
// interrupted run of any kind continued (mtcal resume) and the instruments the drivers find
// (mtcal devices).

#include <fmt/format.h>

#include <nlohmann/json.hpp>
#include <type_traits>
#include <variant>

#include "cli_session.h"
#include "commands.h"
#include "mtcal/services/archive.h"
#include "mtcal/services/plans.h"
#include "mtcal/services/resume.h"

namespace mtcal::app {
namespace {

int listRuns(const Globals& g) {
  CliSession cli(g);
  const auto runs = services::listRuns(cli.session);
  if (jsonPrinted(g, services::runListDocument(runs))) return 0;
  if (runs.empty()) {
    *g.out << "no runs in " << g.db << "\n";
    return 0;
  }
  *g.out << fmt::format("{:>4} {:>5}  {:<24} {:<11} {:<8} {:<5} {:>20}  {:<26} {}\n", "id", "camp.", "started (UTC)",
                        "status", "kind", "axis", "measured", "machine", "name");
  for (const auto& r : runs) {
    *g.out << fmt::format("{:>4} {:>5}  {:<24} {:<11} {:<8} {:<5} {:>20}  {:<26} {}\n", r.id,
                          fmt::format("c{}", r.campaign_id), r.started_at, r.status, r.kind, r.axis,
                          fmt::format("{} {}", r.measurement_count, storage::measurementUnit(r.kind)), r.machine_name,
                          r.name);
  }
  return 0;
}

int showRun(const Globals& g, storage::Id run_id) {
  CliSession cli(g);
  const auto d = services::showRun(cli.session, run_id);
  if (jsonPrinted(g, d.document())) return 0;
  const auto& run = d.run;
  *g.out << fmt::format("run {}: {}\n", run.id, run.name);
  *g.out << fmt::format("  kind {}  axis {}  status {}  source {}\n", run.kind, run.axis, run.status, run.source);
  if (run.stale) *g.out << "  " << services::staleNote(run) << "\n";
  *g.out << fmt::format("  machine {}  campaign c{} ({})\n", run.machine_name, run.campaign_id, run.campaign_name);
  *g.out << fmt::format("  started {}  finished {}  mtcal {}  operator {}\n", run.started_at,
                        run.finished_at.value_or("-"), run.software_version,
                        run.operator_name.empty() ? "-" : run.operator_name);
  for (const auto& i : d.instruments) {
    *g.out << fmt::format("  instrument{}: {} {} serial {}{}\n", i.role == "measuring" ? "" : " (" + i.role + ")",
                          i.info.kind, i.info.model, i.info.serial,
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
  if (!d.results.empty()) {
    *g.out << "results:\n";
    for (const auto& r : d.results)
      *g.out << fmt::format("  {:>5}  {}  {:<18} {}\n", r.id, r.created_at, r.processor, r.processor_version);
  }
  if (!d.events.empty()) {
    *g.out << "events:\n";
    for (const auto& e : d.events) *g.out << fmt::format("  {} {:<7} {}\n", e.created_at, e.level, e.message);
  }
  return 0;
}

int resumeRun(const Globals& g, storage::Id run_id, const SimulationOptions& sim) {
  CliSession cli(g);
  const auto resumed = services::resumeRun(cli.session, run_id, sim);
  cli.observer.finish();
  return std::visit(
      [&](const auto& r) {
        using Result = std::decay_t<decltype(r)>;
        if constexpr (std::is_same_v<Result, services::LinearRunResult>) {
          return printLinearRun(g, r, r.name);
        } else if constexpr (std::is_same_v<Result, services::CircleRunResult>) {
          return printCircleRun(g, r);
        } else if constexpr (std::is_same_v<Result, services::EstRunResult>) {
          return printEstRun(g, r);
        } else if constexpr (std::is_same_v<Result, services::GantryRunResult>) {
          return printGantryRun(g, r);
        } else {
          return printThermalRun(g, r);
        }
      },
      resumed);
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

}  // namespace

void registerArchiveCommands(CliContext& c) {
  auto* runs_cmd = c.app->add_subcommand("runs", "list the runs in the database");
  c.on(runs_cmd, [&c] { return listRuns(c.g); });
  auto run_id = std::make_shared<storage::Id>(0);
  auto* show_cmd = c.app->add_subcommand("show", "show one run: metadata, instruments, plan, events");
  show_cmd->add_option("RUN", *run_id, "run id")->required();
  c.on(show_cmd, [&c, run_id] { return showRun(c.g, *run_id); });
  auto* resume_cmd = c.app->add_subcommand(
      "resume", "continue an interrupted run of any kind (its plan, instruments and machine; what it stored is kept)");
  resume_cmd->add_option("RUN", *run_id, "run id")->required();
  resume_cmd->add_option("--time-scale", c.sim.time_scale, "simulated seconds per wall-clock second")
      ->capture_default_str()
      ->check(positive());
  resume_cmd->add_option("--machine-config", c.sim.machine_file,
                         "a real gantry run: the machine's kinematics (machine file or *.model.json)");
  c.on(resume_cmd, [&c, run_id] { return resumeRun(c.g, *run_id, c.sim); });
  auto* devices_cmd = c.app->add_subcommand("devices", "list the instruments the drivers can find");
  addSimulationOptions(devices_cmd, c, "");
  c.on(devices_cmd, [&c] { return listDevices(c.g, c.sim); });
}

}  // namespace mtcal::app
