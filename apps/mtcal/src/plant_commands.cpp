// The plant archive's commands: mtcal archive init, push, runs, history and pull (docs/archive.md).

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <memory>

#include "cli_session.h"
#include "commands.h"
#include "mtcal/services/plant.h"

namespace mtcal::app {
namespace {

/// "1 run", "2 runs".
std::string counted(std::size_t n, const char* one, const char* many) {
  return fmt::format("{} {}", n, n == 1 ? one : many);
}

int init(const Globals& g, const std::string& address) {
  const auto r = services::initPlant(address);
  if (jsonPrinted(g, r.document())) return 0;
  const std::string what = r.schema_version_before == 0 ? "made now"
                           : r.schema_version_before == r.schema_version
                               ? "already at this mtcal's version"
                               : fmt::format("migrated from v{}", r.schema_version_before);
  *g.out << fmt::format("archive {}: schema v{} ({}), archive uuid {}\n", r.archive, r.schema_version, what,
                        r.archive_uuid);
  return 0;
}

int push(const Globals& g, const services::PlantPushRequest& request) {
  CliSession cli(g);
  const auto r = services::pushToPlant(cli.session, request);
  cli.observer.finish();
  const auto conflicts = r.count("conflict");
  for (const auto& run : r.summary.runs)
    if (run.outcome == "conflict")
      *g.err << fmt::format("mtcal: run {} ({}, archive run {}) not pushed: {}\n", run.local_id, run.uuid,
                            run.archive_id, run.note);
  if (!jsonPrinted(g, r.document())) {
    for (const auto& run : r.summary.runs) {
      if (run.outcome == "unchanged" || run.outcome == "conflict") continue;
      const std::string local = run.local_id != 0 ? fmt::format("run {}", run.local_id) : "a deleted run";
      if (run.outcome == "recording") {
        *g.out << fmt::format("{:<14} {} is being recorded: pushed once it ends\n", local, run.uuid);
      } else {
        *g.out << fmt::format("{:<14} {} {}: archive run {}, version {}, {} sent\n", local, run.uuid, run.outcome,
                              run.archive_id, run.version,
                              counted(static_cast<std::size_t>(run.rows_sent), "row", "rows"));
      }
    }
    *g.out << fmt::format(
        "{} as station {}{}: {} new, {} changed, {} unchanged, {} deleted, {} still recording, {} in conflict; {}; {} "
        "sent\n",
        r.archive, r.station, r.summary.plant.empty() ? "" : " of plant " + r.summary.plant, r.count("new"),
        r.count("changed"), r.count("unchanged"), r.count("deleted"), r.count("recording"), conflicts,
        counted(r.summary.models.size(), "model", "models"),
        counted(static_cast<std::size_t>(r.summary.rows_sent), "row", "rows"));
  }
  return conflicts > 0 ? 1 : 0;
}

int list(const Globals& g, const std::string& address, const std::string& machine) {
  const auto list = services::listPlant(address, machine);
  if (jsonPrinted(g, list.document())) return 0;
  if (list.runs.empty()) {
    *g.out << "no runs in " << list.archive << (machine.empty() ? "" : " of machine " + machine) << "\n";
    return 0;
  }
  *g.out << fmt::format("{:>5} {:>5}  {:<24} {:<11} {:<8} {:<5} {:>3}  {:<12} {:<24} {}\n", "id", "camp.",
                        "started (UTC)", "status", "kind", "axis", "v.", "station", "machine", "name");
  for (const auto& r : list.runs)
    *g.out << fmt::format("{:>5} {:>5}  {:<24} {:<11} {:<8} {:<5} {:>3}  {:<12} {:<24} {}\n", r.id,
                          fmt::format("c{}", r.campaign_id), r.started_at, r.deleted ? "deleted" : r.status, r.kind,
                          r.axis, r.version, r.first_station, r.machine, r.name);
  return 0;
}

int history(const Globals& g, const std::string& address, const std::string& run) {
  const auto h = services::plantRunHistory(address, run);
  if (jsonPrinted(g, h.document())) return 0;
  const auto& first = h.runs.front();
  *g.out << fmt::format("archive run {} ({}), {} {} on {}, campaign c{}:\n", first.id, first.uuid, first.kind,
                        first.axis, first.machine, first.campaign_id);
  *g.out << fmt::format("{:>3}  {:<20}  {:<12} {:<12} {:<11} {:<16} {}\n", "v.", "pushed (UTC)", "station", "by",
                        "status", "SHA-256", "parts sent, name");
  for (const auto& v : h.runs)
    *g.out << fmt::format("{:>3}  {:<20}  {:<12} {:<12} {:<11} {:<16} {}{}\n", v.version, v.pushed_at, v.station,
                          v.pushed_by, v.deleted ? "deleted" : v.status,
                          v.deleted ? "-" : v.sha256.substr(0, 12) + "...",
                          v.parts_sent.empty() ? "-" : fmt::format("{}", fmt::join(v.parts_sent, ", ")),
                          v.deleted ? "" : ", '" + v.name + "'");
  return 0;
}

int pull(const Globals& g, const std::string& address, const std::string& what) {
  CliSession cli(g);
  const auto r = services::pullFromPlant(cli.session, address, what);
  if (jsonPrinted(g, r.document())) return 0;
  for (const auto& run : r.runs) {
    const auto& a = run.archived;
    *g.out << fmt::format("archive run {} (version {}): {} {}{}'{}' {} run {} of {}\n", a.id, a.version, a.kind, a.axis,
                          a.axis.empty() ? "" : " ", a.name, run.already_here ? "is already" : "is now", run.local_id,
                          g.db);
  }
  for (const auto& m : r.models)
    *g.out << fmt::format("archive model m{} ('{}', from station {}) {} model m{} of {}\n", m.id, m.name, m.station,
                          m.already_here ? "is already" : "is now", m.local_id, g.db);
  return 0;
}

}  // namespace

void registerPlantCommands(CliContext& c) {
  auto* archive = c.app->add_subcommand("archive", "the plant archive on PostgreSQL: push runs, list, pull them back")
                      ->require_subcommand(1);
  auto request = std::make_shared<services::PlantPushRequest>();
  auto* init_cmd = archive->add_subcommand(
      "init", "make the plant archive's schema in an empty database, or migrate it (the administrator)");
  init_cmd->add_option("--to", request->archive, "the archive (as for push --to)")->required();
  c.on(init_cmd, [&c, request] { return init(c.g, request->archive); });
  auto* push_cmd = archive->add_subcommand(
      "push", "send every finished or interrupted run of --db (and its deletions) to the plant archive");
  push_cmd->add_option("--to", request->archive, "the archive: postgresql://HOST/DB?sslmode=... or service=NAME")
      ->required();
  push_cmd->add_option("--station", request->station, "this station's name (default: the host name)");
  c.on(push_cmd, [&c, request] { return push(c.g, *request); });

  auto machine = std::make_shared<std::string>();
  auto* runs_cmd = archive->add_subcommand("runs", "list the runs of the plant archive (newest version of each)");
  runs_cmd->add_option("--from", request->archive, "the archive (as for push --to)")->required();
  runs_cmd->add_option("--machine", *machine, "runs of machines whose name contains this");
  c.on(runs_cmd, [&c, request, machine] { return list(c.g, request->archive, *machine); });

  auto what = std::make_shared<std::string>();
  auto* history_cmd =
      archive->add_subcommand("history", "every version of a run of the plant archive: who, when, what");
  history_cmd->add_option("RUN", *what, "the archive's run number (12) or its uuid")->required();
  history_cmd->add_option("--from", request->archive, "the archive (as for push --to)")->required();
  c.on(history_cmd, [&c, request, what] { return history(c.g, request->archive, *what); });

  auto* pull_cmd = archive->add_subcommand("pull", "bring runs of the plant archive into --db for re-analysis");
  pull_cmd
      ->add_option(
          "RUN", *what,
          "the archive's run number (12), its uuid, one of its versions (12@2), a campaign (c3) or a model (m2)")
      ->required();
  pull_cmd->add_option("--from", request->archive, "the archive (as for push --to)")->required();
  c.on(pull_cmd, [&c, request, what] { return pull(c.g, request->archive, *what); });
}

}  // namespace mtcal::app
