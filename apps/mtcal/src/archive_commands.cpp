// The archive's commands: the runs listed (mtcal runs), one run shown whole (mtcal show), an
// interrupted run of any kind continued (mtcal resume) and the instruments the drivers find
// (mtcal devices).

#include <fmt/format.h>

#include <istream>
#include <nlohmann/json.hpp>
#include <type_traits>
#include <variant>

#include "cli_session.h"
#include "commands.h"
#include "mtcal/error.h"
#include "mtcal/services/archive.h"
#include "mtcal/services/compensate.h"
#include "mtcal/services/export.h"
#include "mtcal/services/plans.h"
#include "mtcal/services/resume.h"

namespace mtcal::app {
namespace {

int listRuns(const Globals& g, const services::RunFilter& filter) {
  CliSession cli(g);
  const auto runs = services::listRuns(cli.session, filter);
  if (jsonPrinted(g, services::runListDocument(runs))) return 0;
  if (runs.empty()) {
    *g.out << "no runs in " << g.db << (filter.filters() ? " that match" : "") << "\n";
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
  const auto tables = services::appliedTables(run.compensation_json);
  for (std::size_t a = 0; a < tables.size(); ++a) {
    if (!tables[a]) continue;
    const auto& t = tables[a]->table;
    *g.out << fmt::format("  compensation {}: {} table {}, {} entries from {:g} to {:g} mm\n", "XYZ"[a],
                          tables[a] -> controller, tables[a] -> file, t.position.size(), t.position.front(),
                          t.position.back());
  }
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
  for (const auto& n : d.notes)
    *g.out << fmt::format("  note {} {}: {}\n", n.created_at, n.author.empty() ? "-" : n.author, n.text);
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

int deleteRuns(const Globals& g, const std::string& target, bool yes) {
  CliSession cli(g);
  const auto what = services::ArchiveItem::parse(target);
  const auto runs = services::runsOf(cli.session, what);
  if (!yes) {
    if (!g.in || g.json)
      throw InputError("delete " + target + ": confirm with --yes (nobody to ask" + (g.json ? " under --json)" : ")"));
    *g.err << fmt::format("delete {} and everything measured and computed in it:\n", target);
    for (const auto& r : runs) {
      *g.err << fmt::format("  run {} {} ({}, {} {})\n", r.id, r.name, r.kind, r.measurement_count,
                            storage::measurementUnit(r.kind));
    }
    *g.err << "type yes to delete: ";
    std::string answer;
    if (!std::getline(*g.in, answer) || answer != "yes") {
      *g.err << "nothing deleted\n";
      return 1;
    }
  }
  services::deleteRuns(cli.session, what);
  nlohmann::json ids = nlohmann::json::array();
  for (const auto& r : runs) ids.push_back(r.id);
  if (!jsonPrinted(g, {{"schema_version", 1}, {"deleted_runs", ids}}))
    *g.out << (what.run ? fmt::format("deleted run {}\n", *what.run)
                        : fmt::format("deleted campaign {} ({} run(s))\n", *what.campaign, runs.size()));
  return 0;
}

int exportRuns(const Globals& g, const std::string& what, const std::string& dir) {
  CliSession cli(g);
  const auto item = services::ArchiveItem::parse(what, "rc");
  if (item.run) {
    const auto e = services::exportRun(cli.session, *item.run, dir);
    if (jsonPrinted(g, e.document())) return 0;
    for (const auto& f : e.files) *g.out << fmt::format("{}  {}\n", f.path, f.what);
    if (!e.import_command.empty()) *g.out << "read back with: " << e.import_command << "\n";
    return 0;
  }
  const auto e = services::exportCampaign(cli.session, *item.campaign, dir);
  if (jsonPrinted(g, e.document())) return 0;
  std::size_t files = 0;
  for (const auto& r : e.runs) files += r.files.size();
  *g.out << fmt::format("{} run(s) of campaign c{}: {} files in {}\n", e.runs.size(), e.campaign_id, files, dir);
  *g.out << fmt::format("{}  the campaign manifest of its linear runs\n", e.manifest);
  *g.out << "read back with: " << e.import_command << "\n";
  return 0;
}

int checkArchive(const Globals& g) {
  CliSession cli(g);
  const auto problems = services::checkArchive(cli.session);
  if (!jsonPrinted(g, {{"schema_version", 1}, {"sound", problems.empty()}, {"problems", problems}})) {
    if (problems.empty()) *g.out << g.db << ": sound (integrity, foreign keys, no orphan rows)\n";
    for (const auto& p : problems) *g.out << p << "\n";
  }
  return problems.empty() ? 0 : 1;
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
  auto filter = std::make_shared<services::RunFilter>();
  auto campaign = std::make_shared<std::string>();
  auto* runs_cmd = c.app->add_subcommand("runs", "list the runs in the database (filtered, sorted)");
  runs_cmd->add_option("--machine", filter->machine, "runs of machines whose name contains this");
  runs_cmd->add_option("--kind", filter->kind, "linear, circle, est, gantry or thermal")
      ->check(CLI::IsMember({"linear", "circle", "est", "gantry", "thermal"}));
  runs_cmd->add_option("--axis", filter->axis, "axis (X ...) or plane (XY ...)");
  runs_cmd->add_option("--campaign", *campaign, "campaign (c3 or 3)");
  runs_cmd->add_option("--status", filter->status, "running, interrupted, completed, failed or imported")
      ->check(CLI::IsMember({"running", "interrupted", "completed", "failed", "imported"}));
  runs_cmd->add_option("--since", filter->since, "started on or after (UTC: 2026-11-24 or 2026-11-24T08:00)");
  runs_cmd->add_option("--until", filter->until, "started on or before (UTC; a date takes its whole day)");
  runs_cmd->add_option("--sort", filter->sort, "id, started, machine, kind, axis, status or name")
      ->capture_default_str();
  runs_cmd->add_flag("--descending", filter->descending, "newest (or last) first");
  c.on(runs_cmd, [&c, filter, campaign] {
    if (!campaign->empty()) {
      const auto what = services::ArchiveItem::parse(campaign->front() == 'c' ? *campaign : "c" + *campaign, "c");
      filter->campaign = what.campaign;
    }
    return listRuns(c.g, *filter);
  });

  struct Edit {
    std::string target, text;
    bool yes = false;
  };
  auto edit = std::make_shared<Edit>();
  auto* delete_cmd = c.app->add_subcommand("delete", "delete a run or a campaign with all it holds (asks, or --yes)");
  delete_cmd->add_option("RUN", edit->target, "run id (12) or campaign (c3)")->required();
  delete_cmd->add_flag("--yes", edit->yes, "do not ask");
  c.on(delete_cmd, [&c, edit] { return deleteRuns(c.g, edit->target, edit->yes); });
  auto edit_id = std::make_shared<storage::Id>(0);
  auto* rename_cmd = c.app->add_subcommand("rename", "give a run another name");
  rename_cmd->add_option("RUN", *edit_id, "run id")->required();
  rename_cmd->add_option("NAME", edit->text, "new name")->required();
  c.on(rename_cmd, [&c, edit, edit_id] {
    CliSession cli(c.g);
    services::renameRun(cli.session, *edit_id, edit->text);
    jsonPrinted(c.g, {{"schema_version", 1}, {"run_id", *edit_id}, {"name", edit->text}});
    return 0;
  });
  auto* note_cmd = c.app->add_subcommand("note", "add a note to a run (shown by mtcal show; by --operator)");
  note_cmd->add_option("RUN", *edit_id, "run id")->required();
  note_cmd->add_option("TEXT", edit->text, "the note")->required();
  c.on(note_cmd, [&c, edit, edit_id] {
    CliSession cli(c.g);
    services::noteRun(cli.session, *edit_id, edit->text);
    jsonPrinted(c.g, {{"schema_version", 1}, {"run_id", *edit_id}, {"note", edit->text}});
    return 0;
  });
  auto* backup_cmd = c.app->add_subcommand("backup", "a consistent copy of the store (also while a run records)");
  backup_cmd->add_option("FILE", edit->target, "the copy (a new file)")->required();
  c.on(
      backup_cmd,
      [&c, edit] {
        CliSession cli(c.g);
        services::backupArchive(cli.session, edit->target);
        if (!jsonPrinted(c.g, {{"schema_version", 1}, {"backup", edit->target}}))
          *c.g.out << fmt::format("{} copied to {}\n", c.g.db, edit->target);
        return 0;
      },
      OnSignal::kStopAndWait);
  auto export_what = std::make_shared<std::string>();
  auto* export_cmd = c.app->add_subcommand(
      "export",
      "write a run or a campaign as files: measurements in the import format of their kind, samples, results, "
      "and a campaign's manifest");
  export_cmd->add_option("RUN", *export_what, "run id, or cN for every run of campaign N")->required();
  export_cmd->add_option("--csv", edit->target, "folder to write into (created when missing)")
      ->required()
      ->check(notEmpty("a folder", "DIR"));
  c.on(export_cmd, [&c, edit, export_what] { return exportRuns(c.g, *export_what, edit->target); });
  auto* check_cmd = c.app->add_subcommand("check", "check the store: integrity, foreign keys, orphan rows");
  c.on(check_cmd, [&c] { return checkArchive(c.g); });

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
  c.on(
      resume_cmd, [&c, run_id] { return resumeRun(c.g, *run_id, c.sim); }, OnSignal::kStopAndWait);
  auto* devices_cmd = c.app->add_subcommand("devices", "list the instruments the drivers can find");
  addSimulationOptions(devices_cmd, c, "");
  c.on(devices_cmd, [&c] { return listDevices(c.g, c.sim); });
}

}  // namespace mtcal::app
