#include "mtcal/archive/plant_archive.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstring>
#include <functional>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>

#include "mtcal/archive/plant_schema.h"
#include "mtcal/archive/run_content.h"
#include "mtcal/error.h"
#include "mtcal/storage/run_owner.h"

namespace mtcal::archive {
namespace {

using storage::Id;
using storage::Statement;

/// A read transaction on the local store: every read inside sees one state of it, while runs
/// go on being recorded by other processes.
class ReadSnapshot {
 public:
  explicit ReadSnapshot(storage::Database& db) : db_(db) { db_.exec("BEGIN DEFERRED"); }
  ~ReadSnapshot() {
    try {
      db_.exec("COMMIT");
    } catch (...) {  // reads only: nothing to lose
    }
  }
  ReadSnapshot(const ReadSnapshot&) = delete;
  ReadSnapshot& operator=(const ReadSnapshot&) = delete;

 private:
  storage::Database& db_;
};

std::string storeUuid(storage::Database& db) {
  Statement st(db, "SELECT uuid FROM store_identity");
  if (!st.step()) throw StorageError(db.path() + ": the store has no identity (store_identity is empty)");
  return st.getText(0);
}

/// A model's provenance with the runs it names renumbered by `number` (none: a run not held
/// where the provenance goes): the runs it was identified from ("runs", its base versions'
/// through "base_provenance"; one not held is left out and counted in "runs_not_held"), the run
/// a version was diagnosed on and each extension's ("diagnosed_run", "found_in_run"; 0 when not
/// held: not recorded). The archive's copy is numbered as the archive numbers its runs and says
/// so (kArchiveRunNumbers); a store's as the store does. A model's name keeps the making store's.
constexpr const char* kArchiveRunNumbers = "run_numbers";
std::string renumberedProvenance(const std::string& provenance_json,
                                 const std::function<std::optional<Id>(Id)>& number) {
  auto provenance = nlohmann::json::parse(provenance_json.empty() ? "{}" : provenance_json, nullptr, false);
  if (!provenance.is_object()) return provenance_json;
  const auto one = [&](nlohmann::json& object, const char* key) {
    if (object.contains(key) && object[key].is_number_integer())
      object[key] = number(object[key].get<Id>()).value_or(0);
  };
  for (auto* at = &provenance; at != nullptr && at->is_object();) {
    if (at->contains("runs") && at->at("runs").is_array()) {
      nlohmann::json runs = nlohmann::json::array();
      int not_held = 0;
      for (const auto& id : at->at("runs")) {
        const auto renumbered = id.is_number_integer() ? number(id.get<Id>()) : std::nullopt;
        if (renumbered)
          runs.push_back(*renumbered);
        else
          ++not_held;
      }
      (*at)["runs"] = runs;
      if (not_held > 0) (*at)["runs_not_held"] = at->value("runs_not_held", 0) + not_held;
    }
    one(*at, "diagnosed_run");
    if (at->contains("extensions") && at->at("extensions").is_array())
      for (auto& extension : (*at)["extensions"])
        if (extension.is_object()) one(extension, "found_in_run");
    at = at->contains("base_provenance") ? &(*at)["base_provenance"] : nullptr;
  }
  return provenance.dump();
}

/// Comma-separated "$first, $first+1, ..." for `n` parameters.
std::string placeholders(int first, int n) {
  std::string out;
  for (int i = 0; i < n; ++i) out += (i ? ", $" : "$") + std::to_string(first + i);
  return out;
}

/// The rows of the local store that the run refers to (its machine, campaign, instruments),
/// added to the archive unless there.
void sendIdentities(storage::Database& db, Connection& c, Id run_id, const std::string& station) {
  Statement m(db,
              "SELECT m.uuid, m.name, m.description, m.config_json, m.created_at, c.uuid, c.name, c.created_at"
              " FROM runs r JOIN campaigns c ON c.id = r.campaign_id JOIN machines m ON m.id = c.machine_id"
              " WHERE r.id = ?");
  m.bind(1, run_id);
  if (!m.step()) throw InputError("run " + std::to_string(run_id) + " does not exist");
  c.query(
      "INSERT INTO machines(uuid, name, description, config_json, created_at, station) VALUES ($1, $2, $3, $4, $5, $6)"
      " ON CONFLICT DO NOTHING",
      {m.getText(0), m.getText(1), m.getOptionalText(2), m.getOptionalText(3), m.getText(4), station});
  c.query(
      "INSERT INTO campaigns(uuid, machine_uuid, name, created_at, station) SELECT $1, $2, $3, $4, $5"
      " WHERE NOT EXISTS (SELECT 1 FROM campaigns WHERE uuid = $1)",
      {m.getText(5), m.getText(0), m.getText(6), m.getText(7), station});
  Statement i(db,
              "SELECT DISTINCT i.uuid, i.kind, i.model, i.serial, i.firmware, i.driver_uri, i.created_at"
              " FROM instruments i WHERE i.id IN (SELECT instrument_id FROM runs WHERE id = ?1"
              " UNION SELECT instrument_id FROM run_instruments WHERE run_id = ?1)");
  i.bind(1, run_id);
  while (i.step())
    c.query(
        "INSERT INTO instruments(uuid, kind, model, serial, firmware, driver_uri, created_at, station)"
        " VALUES ($1, $2, $3, $4, $5, $6, $7, $8) ON CONFLICT DO NOTHING",
        {i.getText(0), i.getText(1), i.getText(2), i.getText(3), i.getOptionalText(4), i.getText(5), i.getText(6),
         station});
}

struct LatestVersion {
  int version = 0;
  std::string sha256;
  bool tombstone = false;
  nlohmann::json parts = nlohmann::json::object();
};

std::optional<LatestVersion> latestVersion(Connection& c, const std::string& uuid) {
  auto rows = c.query(
      "SELECT version, content_sha256, tombstone, parts FROM run_versions WHERE run_uuid = $1"
      " ORDER BY version DESC LIMIT 1",
      {uuid});
  if (rows.empty()) return std::nullopt;
  LatestVersion v;
  v.version = std::stoi(*rows[0][0]);
  v.sha256 = *rows[0][1];
  v.tombstone = *rows[0][2] == "t";
  v.parts = nlohmann::json::parse(*rows[0][3]);
  return v;
}

/// The run's month (its partition of samples): the first day of the month it started.
std::string runMonth(const std::string& started_at) {
  if (started_at.size() < 7) throw StorageError("a run's start '" + started_at + "' is not a date");
  return started_at.substr(0, 7) + "-01";
}

/// Who pushes, from which store, to which archive.
struct Pusher {
  std::string station, store_uuid, archive_uuid, software_version;
  bool station_role = false;  ///< logged in as a station's role (not the administrator)
  std::string role_plants;    ///< a station role's plants, ", "-separated (empty: none)
};

/// The archive's version of a run this store last pushed or pulled (none: never).
std::optional<int> versionSeen(storage::Database& db, const std::string& archive_uuid, const std::string& run_uuid) {
  Statement st(db, "SELECT version FROM archive_versions WHERE archive_uuid = ? AND run_uuid = ?");
  st.bind(1, archive_uuid).bind(2, run_uuid);
  if (!st.step()) return std::nullopt;
  return static_cast<int>(st.getInt(0));
}

/// The archive's number of a run it holds.
std::int64_t archivedRunNumber(Connection& c, const std::string& uuid) {
  return std::stoll(c.scalar("SELECT id FROM runs WHERE uuid = $1", {uuid}).value_or("0"));
}

/// Why the store's run may not become the archive's next version (empty: it may).
std::string conflict(Connection& c, const Pusher& p, const std::string& uuid, const LatestVersion& latest,
                     std::optional<int> seen) {
  const auto owner = c.scalar("SELECT station FROM runs WHERE uuid = $1", {uuid}).value_or("");
  if (p.station_role && owner != p.station)
    return "run first pushed by station " + owner + ": only " + owner + " adds its versions";
  if (seen == latest.version) return "";
  const auto by = c.scalar(
                       "SELECT station || ', ' || to_char(pushed_at AT TIME ZONE 'UTC', 'YYYY-MM-DD HH24:MI')"
                       " FROM run_versions WHERE run_uuid = $1 AND version = $2",
                       {uuid, std::to_string(latest.version)})
                      .value_or("");
  return fmt::format(
      "the archive's version {} ({}{}) is not the one this store last pushed or pulled ({}): pushing would overwrite "
      "it; pull the run into another store to compare",
      latest.version, latest.tombstone ? "deleted by " : "by ", by, seen ? "version " + std::to_string(*seen) : "none");
}

PushedRun pushRun(storage::Store& store, Connection& c, Id run_id, const Pusher& p) {
  auto& db = store.database();
  ReadSnapshot snapshot(db);
  const auto metadata = runMetadata(store, run_id);
  PushedRun out;
  out.local_id = run_id;
  out.uuid = metadata.uuid;
  std::vector<PartDigest> digests;
  for (const auto& part : runParts()) digests.push_back(forEachPartLine(db, part, run_id, [](std::string_view) {}));
  out.sha256 = runDigest(metadata, digests);

  PgTransaction tx(c);
  // One client at a time adds versions of a run: two pushes of it queue here.
  c.query("SELECT pg_advisory_xact_lock(hashtextextended($1, 0))", {metadata.uuid});
  const auto latest = latestVersion(c, metadata.uuid);
  const auto archiveNumber = [&] { out.archive_id = archivedRunNumber(c, metadata.uuid); };
  if (latest && !latest->tombstone && latest->sha256 == out.sha256) {
    out.outcome = "unchanged";
    out.version = latest->version;
    archiveNumber();
    return out;
  }
  if (latest) {
    out.note = conflict(c, p, metadata.uuid, *latest, versionSeen(db, p.archive_uuid, metadata.uuid));
    if (!out.note.empty()) {
      out.outcome = "conflict";
      out.version = latest->version;
      archiveNumber();
      return out;
    }
  }
  out.outcome = latest ? "changed" : "new";
  out.version = latest ? latest->version + 1 : 1;
  sendIdentities(db, c, run_id, p.station);
  // Not by ON CONFLICT: a refused insert would use up a number of the archive's.
  c.query(
      "INSERT INTO runs(uuid, station, store_uuid, campaign_uuid) SELECT $1, $2, $3, $4"
      " WHERE NOT EXISTS (SELECT 1 FROM runs WHERE uuid = $1)",
      {metadata.uuid, p.station, p.store_uuid, metadata.campaign_uuid});
  archiveNumber();

  // A part unchanged since the last version stays where it is; the new version points at it.
  nlohmann::json parts = nlohmann::json::object();
  std::vector<const RunPart*> to_send;
  for (std::size_t i = 0; i < runParts().size(); ++i) {
    const auto& part = runParts()[i];
    const auto& previous = latest ? latest->parts.value(part.name, nlohmann::json()) : nlohmann::json();
    if (!previous.is_null() && previous.value("sha256", "") == digests[i].sha256) {
      parts[part.name] = previous;
      continue;
    }
    parts[part.name] = {{"sha256", digests[i].sha256}, {"rows", digests[i].rows}, {"version", out.version}};
    if (digests[i].rows > 0) to_send.push_back(&part);
  }
  std::vector<Value> params = {metadata.uuid, std::to_string(out.version), p.station,
                               p.store_uuid,  p.software_version,          out.sha256,
                               parts.dump()};
  params.insert(params.end(), metadata.values.begin(), metadata.values.end());
  c.query(fmt::format("INSERT INTO run_versions(run_uuid, version, station, store_uuid, pushed_with, content_sha256,"
                      " parts, {}) VALUES ({})",
                      kRunColumns, placeholders(1, static_cast<int>(params.size()))),
          params);

  const std::string started_at = *metadata.values[10];  // kRunColumns' started_at
  for (const RunPart* part : to_send) {
    std::string prefix = metadata.uuid + '\t' + std::to_string(out.version) + '\t' + p.station + '\t';
    std::string columns = std::string("run_uuid, version, station, ") + part->columns;
    if (part->by_month) {
      const std::string month = runMonth(started_at);
      c.query("SELECT mtcal_samples_partition($1)", {month});
      prefix = month + '\t' + prefix;
      columns = "run_month, " + columns;
    }
    std::string line;
    c.copyIn(fmt::format("COPY {} ({}) FROM STDIN", part->name, columns), [&](Connection::CopyIn& sink) {
      forEachPartLine(db, *part, run_id, [&](std::string_view row) {
        line.assign(prefix);
        line.append(row);
        sink.write(line);
        ++out.rows_sent;
      });
    });
  }
  tx.commit();
  return out;
}

/// Tombstones for the runs this store deleted, where the archive holds them as this store
/// last saw them.
std::vector<PushedRun> pushDeletions(storage::Database& db, Connection& c, const Pusher& p) {
  std::vector<std::string> deleted;
  {
    // A run deleted, then pulled back, is not deleted.
    Statement st(db, "SELECT uuid FROM deleted_runs WHERE uuid NOT IN (SELECT uuid FROM runs) ORDER BY deleted_at");
    while (st.step()) deleted.push_back(st.getText(0));
  }
  std::vector<PushedRun> out;
  for (const auto& uuid : deleted) {
    PgTransaction tx(c);
    c.query("SELECT pg_advisory_xact_lock(hashtextextended($1, 0))", {uuid});
    const auto latest = latestVersion(c, uuid);
    if (!latest || latest->tombstone) continue;
    PushedRun d;
    d.uuid = uuid;
    d.archive_id = archivedRunNumber(c, uuid);
    d.version = latest->version;
    d.note = conflict(c, p, uuid, *latest, versionSeen(db, p.archive_uuid, uuid));
    if (!d.note.empty()) {
      d.outcome = "conflict";
      d.note = "deleted here, but " + d.note;
      out.push_back(std::move(d));
      continue;
    }
    c.query(fmt::format("INSERT INTO run_versions(run_uuid, version, station, store_uuid, pushed_with, tombstone,"
                        " content_sha256, parts, {0}) SELECT run_uuid, version + 1, $2, $3, $4, true, '', '{{}}', {0}"
                        " FROM run_versions WHERE run_uuid = $1 AND version = $5",
                        kRunColumns),
            {uuid, p.station, p.store_uuid, p.software_version, std::to_string(latest->version)});
    tx.commit();
    d.outcome = "deleted";
    d.version = latest->version + 1;
    out.push_back(std::move(d));
  }
  return out;
}

/// Records in the store which version of a run it now holds as the archive does.
void recordVersion(storage::Store& store, const std::string& archive_uuid, const std::string& run_uuid, int version,
                   const std::string& sha256) {
  if (store.readOnly()) return;  // a write-protected store: its next push compares by content only
  Statement st(store.database(),
               "INSERT OR REPLACE INTO archive_versions(archive_uuid, run_uuid, version, sha256) VALUES (?, ?, ?, ?)");
  st.bind(1, archive_uuid).bind(2, run_uuid).bind(3, version).bind(4, sha256).run();
}

/// The store's models the archive does not have, each with its error functions in one transaction.
std::vector<std::string> pushModels(storage::Database& db, Connection& c, const std::string& station,
                                    const std::string& store_uuid) {
  std::set<std::string> archived;
  for (const auto& row : c.query("SELECT uuid FROM models")) archived.insert(*row[0]);
  std::vector<std::string> sent;
  Statement models(db,
                   "SELECT id, uuid, name, machine_json, method, provenance_json, software_version, created_at"
                   " FROM models ORDER BY id");
  while (models.step()) {
    const std::string uuid = models.getText(1);
    if (archived.count(uuid) > 0) continue;
    // The runs it names, as the archive numbers them (a run not pushed: left out).
    auto provenance = nlohmann::json::parse(renumberedProvenance(models.getText(5), [&](Id local) -> std::optional<Id> {
      Statement run(db, "SELECT uuid FROM runs WHERE id = ?");
      run.bind(1, local);
      if (!run.step()) return std::nullopt;
      const auto rows = c.query("SELECT id FROM runs WHERE uuid = $1", {run.getText(0)});
      if (rows.empty()) return std::nullopt;
      return std::stoll(*rows[0][0]);
    }));
    if (provenance.is_object()) provenance[kArchiveRunNumbers] = "archive";
    PgTransaction tx(c);
    c.query(
        "INSERT INTO models(uuid, station, store_uuid, name, machine_json, method, provenance_json, software_version,"
        " created_at) SELECT $1, $2, $3, $4, $5, $6, $7, $8, $9 WHERE NOT EXISTS (SELECT 1 FROM models WHERE uuid = "
        "$1)",
        {uuid, station, store_uuid, models.getText(2), models.getText(3), models.getText(4),
         provenance.is_object() ? provenance.dump() : models.getText(5), models.getText(6), models.getText(7)});
    Statement errors(db, "SELECT name, function_json FROM model_errors WHERE model_id = ? ORDER BY name");
    errors.bind(1, models.getInt(0));
    while (errors.step())
      c.query(
          "INSERT INTO model_errors(model_uuid, station, name, function_json) VALUES ($1, $2, $3, $4)"
          " ON CONFLICT DO NOTHING",
          {uuid, station, errors.getText(0), errors.getText(1)});
    tx.commit();
    sent.push_back(uuid);
  }
  return sent;
}

/// The station a push adds rows as, into `p`: a station's role is its name; another role (the
/// administrator's, a single user's) names it, by default the host's name.
void pushingStation(Connection& c, const std::string& given, Pusher& p) {
  const auto role = c.scalar("SELECT current_user").value_or("");
  // A superuser counts as a member of every role: it is no station.
  p.station_role = c.scalar(
                       "SELECT pg_has_role(current_user, 'mtcal_station', 'MEMBER') AND NOT rolsuper"
                       " FROM pg_roles WHERE rolname = current_user") == "t";
  if (p.station_role && !given.empty() && given != role)
    throw InputError("connected to the archive as station " + role + ": it pushes as " + role + ", not as station '" +
                     given + "' (leave --station out, or log in as that station)");
  p.station = p.station_role ? role : given.empty() ? storage::thisProcess().host : given;
  if (p.station_role) {
    p.role_plants = c.scalar("SELECT array_to_string(mtcal_plants_of(current_user), ', ')").value_or("");
    const auto& plants = p.role_plants;
    if (plants.find(',') != std::string::npos)
      throw InputError("station " + role + " is a member of the plants " + plants +
                       ": a station belongs to one plant (the administrator revokes all but one: REVOKE PLANT FROM " +
                       role + ")");
  }
}

}  // namespace

PushSummary push(storage::Store& store, Connection& c, const PushOptions& options) {
  migratePlant(c);
  if (c.scalar("SELECT has_table_privilege('run_versions', 'INSERT')") != "t")
    throw InputError("role " + c.scalar("SELECT current_user").value_or("") + " may not add to the archive " +
                     c.where() +
                     ": it is neither a station's role (mtcal_station) nor the administrator's; a quality engineer's "
                     "role reads (docs/archive.md)");
  PushSummary summary;
  Pusher p;
  pushingStation(c, options.station, p);
  summary.station = p.station;
  p.store_uuid = storeUuid(store.database());
  p.archive_uuid = archiveUuid(c);
  p.software_version = options.software_version;
  c.query("INSERT INTO stations(name) SELECT $1 WHERE NOT EXISTS (SELECT 1 FROM stations WHERE name = $1)",
          {summary.station});
  summary.plant = c.scalar("SELECT plant FROM stations WHERE name = $1", {summary.station}).value_or("");
  if (p.station_role) {  // the plant recorded at its first push, against its role's plants now
    const auto& plants = p.role_plants;
    if (plants != summary.plant)
      summary.warnings.push_back(fmt::format(
          "station {0} is recorded in the archive {1} (so {2}), but its role is in {3}: the administrator makes them "
          "agree, by the record (UPDATE stations SET plant = 'PLANT' WHERE name = '{0}') or by the role (GRANT or "
          "REVOKE of the plant's role; docs/archive.md)",
          p.station, summary.plant.empty() ? "in no plant" : "in plant " + summary.plant,
          summary.plant.empty() ? "every reader sees its runs" : "it reads, and is read by, that plant",
          plants.empty() ? "no plant" : "plant " + plants));
    else if (plants.empty() && c.scalar("SELECT EXISTS (SELECT 1 FROM mtcal_plants())") == "t")
      summary.warnings.push_back(fmt::format(
          "station {0} is in no plant while the archive has plants: every reader sees its runs (the administrator "
          "gives it one: GRANT PLANT TO {0}, and UPDATE stations SET plant = 'PLANT' WHERE name = '{0}')",
          p.station));
  }
  const auto runs = store.listRuns();
  std::size_t done = 0;
  for (const auto& run : runs) {
    PushedRun pushed;
    if (run.status == storage::run_status::kRunning) {  // live: its process still records it
      pushed.local_id = run.id;
      pushed.uuid = run.uuid;
      pushed.outcome = "recording";
    } else {
      pushed = pushRun(store, c, run.id, p);
      if (pushed.outcome != "conflict")
        recordVersion(store, p.archive_uuid, pushed.uuid, pushed.version, pushed.sha256);
    }
    summary.rows_sent += pushed.rows_sent;
    if (options.progress) options.progress(++done, runs.size(), fmt::format("run {} {}", run.id, pushed.outcome));
    summary.runs.push_back(std::move(pushed));
  }
  for (auto& deleted : pushDeletions(store.database(), c, p)) summary.runs.push_back(std::move(deleted));
  summary.models = pushModels(store.database(), c, summary.station, p.store_uuid);
  return summary;
}

namespace {

constexpr const char* kArchivedRunColumns =
    "SELECT r.id, r.uuid, m.name, c.name, c.id, v.kind, coalesce(v.axis, ''), v.name, v.status, v.station,"
    " to_char(v.pushed_at AT TIME ZONE 'UTC', 'YYYY-MM-DD\"T\"HH24:MI:SS\"Z\"'), v.started_at, v.content_sha256,"
    " v.version, v.tombstone, v.pushed_by, v.parts, r.station"
    " FROM runs r JOIN campaigns c ON c.uuid = r.campaign_uuid JOIN machines m ON m.uuid = c.machine_uuid";
/// Each run's newest version, or every version.
constexpr const char* kNewestVersion =
    " JOIN LATERAL (SELECT * FROM run_versions x WHERE x.run_uuid = r.uuid ORDER BY x.version DESC LIMIT 1) v"
    " ON true";
constexpr const char* kEveryVersion = " JOIN run_versions v ON v.run_uuid = r.uuid";

ArchivedRun archivedRun(const Row& row) {
  ArchivedRun r;
  r.id = std::stoll(*row[0]);
  r.uuid = *row[1];
  r.machine = *row[2];
  r.campaign = *row[3];
  r.campaign_id = std::stoll(*row[4]);
  r.kind = *row[5];
  r.axis = *row[6];
  r.name = *row[7];
  r.status = *row[8];
  r.station = *row[9];
  r.pushed_at = *row[10];
  r.started_at = *row[11];
  r.sha256 = *row[12];
  r.version = std::stoi(*row[13]);
  r.deleted = *row[14] == "t";
  r.pushed_by = *row[15];
  r.first_station = *row[17];
  const auto parts = nlohmann::json::parse(*row[16]);  // kept: items() does not keep its object alive
  for (const auto& [name, part] : parts.items())
    if (part.value("version", 0) == r.version && part.value("rows", 0) > 0) r.parts_sent.push_back(name);
  return r;
}

std::vector<ArchivedRun> archivedRuns(Connection& c, const std::string& where, const std::vector<Value>& params,
                                      bool every_version = false) {
  std::vector<ArchivedRun> out;
  for (const auto& row : c.query(std::string(kArchivedRunColumns) + (every_version ? kEveryVersion : kNewestVersion) +
                                     " " + where + " ORDER BY r.id, v.version",
                                 params))
    out.push_back(archivedRun(row));
  return out;
}

bool allDigits(std::string_view text) {
  return !text.empty() && std::all_of(text.begin(), text.end(), [](char ch) { return std::isdigit(ch) != 0; });
}

/// An archive's number (of a run, campaign or model): digits that fit its bigint.
bool archiveNumber(std::string_view text) { return text.size() <= 18 && allDigits(text); }

/// "12@3": run 12's version 3. @return the run's text and the version (none without @)
std::pair<std::string, std::optional<int>> versionOf(const std::string& what) {
  const auto at = what.find('@');
  if (at == std::string::npos) return {what, std::nullopt};
  const std::string version = what.substr(at + 1);
  if (version.size() > 9 || !allDigits(version))
    throw InputError("'" + what + "': after @ comes a version number (12@2)");
  return {what.substr(0, at), std::stoi(version)};
}

/// The runs `what` names (its number or uuid), newest version, every version, or the one after @.
/// Every version: for `archive history`, which takes a run only; else for `archive pull`.
std::vector<ArchivedRun> namedRun(Connection& c, const std::string& what, bool every_version) {
  const auto [run, version] = versionOf(what);
  std::string where;
  if (archiveNumber(run))
    where = "WHERE r.id = $1";
  else if (run.size() == 36 && std::count(run.begin(), run.end(), '-') == 4)
    where = "WHERE r.uuid = $1::uuid";
  else
    throw InputError(
        "'" + what + "' names no run of the archive: give its number (12)" +
        (every_version ? " or its uuid" : ", its uuid, a version (12@2), a campaign (c3) or a model (m2)"));
  std::vector<Value> params = {run};
  if (version) {
    where += " AND v.version = $2";
    params.push_back(std::to_string(*version));
  }
  auto runs = archivedRuns(c, where, params, every_version || version.has_value());
  if (runs.empty())
    throw InputError("the archive " + c.where() + " has no run " + run +
                     (version ? " with a version " + std::to_string(*version) : ""));
  return runs;
}

/// The local machine and campaign of a pulled run: the store's own when it has them (by
/// uuid; a machine also by name), added otherwise (as campaign `id` when given).
Id localCampaign(storage::Database& db, Connection& c, const std::string& campaign_uuid, std::optional<Id> id) {
  {
    Statement st(db, "SELECT id FROM campaigns WHERE uuid = ?");
    st.bind(1, campaign_uuid);
    if (st.step()) return st.getInt(0);
  }
  const auto rows = c.query(
      "SELECT m.uuid, m.name, m.description, m.config_json, m.created_at, c.name, c.created_at FROM campaigns c"
      " JOIN machines m ON m.uuid = c.machine_uuid WHERE c.uuid = $1",
      {campaign_uuid});
  if (rows.empty()) throw StorageError("archive " + c.where() + ": campaign " + campaign_uuid + " is missing");
  const auto& r = rows[0];
  Id machine_id = 0;
  {
    Statement st(db, "SELECT id FROM machines WHERE uuid = ?1 OR name = ?2 ORDER BY uuid = ?1 DESC");
    st.bind(1, *r[0]).bind(2, *r[1]);
    if (st.step()) machine_id = st.getInt(0);
  }
  if (machine_id == 0) {
    Statement st(db, "INSERT INTO machines(uuid, name, description, config_json, created_at) VALUES (?, ?, ?, ?, ?)");
    st.bind(1, *r[0]).bind(2, *r[1]).bind(3, r[2]).bind(4, r[3]).bind(5, *r[4]);
    st.run();
    machine_id = db.lastInsertId();
  }
  Statement st(db, "INSERT INTO campaigns(uuid, machine_id, name, created_at, id) VALUES (?, ?, ?, ?, ?)");
  st.bind(1, campaign_uuid).bind(2, machine_id).bind(3, *r[5]).bind(4, *r[6]).bind(5, id);
  st.run();
  return db.lastInsertId();
}

/// The instruments a pulled run names, added to the store unless there (by kind, model, serial).
void localInstruments(storage::Database& db, Connection& c, const std::string& uuid, int version,
                      int instruments_version) {
  const auto rows = c.query(
      "SELECT i.uuid, i.kind, i.model, i.serial, i.firmware, i.driver_uri, i.created_at FROM instruments i"
      " WHERE (i.kind, i.model, i.serial) IN (SELECT instrument_kind, instrument_model, instrument_serial"
      " FROM visible_run_instruments WHERE run_uuid = $1 AND version = $3"
      " UNION SELECT instrument_kind, instrument_model, instrument_serial FROM run_versions"
      " WHERE run_uuid = $1 AND version = $2)",
      {uuid, std::to_string(version), std::to_string(instruments_version)});
  for (const auto& r : rows) {
    Statement st(db,
                 "INSERT INTO instruments(uuid, kind, model, serial, firmware, driver_uri, created_at)"
                 " VALUES (?, ?, ?, ?, ?, ?, ?) ON CONFLICT DO NOTHING");
    st.bind(1, *r[0]).bind(2, *r[1]).bind(3, *r[2]).bind(4, *r[3]).bind(5, r[4]).bind(6, *r[5]).bind(7, *r[6]);
    st.run();
  }
}

void bindTyped(Statement& st, int index, char type, const Value& value, const std::string& where) {
  if (!value) {
    st.bindNull(index);
  } else if (type == 'i' || type == 'n' || type == 'k') {
    std::int64_t v = 0;
    const auto [end, ec] = std::from_chars(value->data(), value->data() + value->size(), v);
    if (ec != std::errc() || end != value->data() + value->size())
      throw StorageError(where + ": '" + *value + "' is not an integer");
    st.bind(index, v);
  } else if (type == 'r') {
    double v = 0.0;
    const auto [end, ec] = std::from_chars(value->data(), value->data() + value->size(), v);
    if (ec != std::errc() || end != value->data() + value->size()) {
      if (*value == "NaN" || *value == "Infinity" || *value == "-Infinity")
        v = *value == "NaN" ? std::nan("") : (*value == "Infinity" ? HUGE_VAL : -HUGE_VAL);
      else
        throw StorageError(where + ": '" + *value + "' is not a number");
    }
    st.bind(index, v);
  } else {
    st.bind(index, std::string_view(*value));
  }
}

/// `archive_numbers`: the run and its campaign keep the archive's numbers (a mirror).
PulledRun pullRun(storage::Store& store, Connection& c, const ArchivedRun& archived, bool archive_numbers = false) {
  auto& db = store.database();
  PulledRun out;
  out.archived = archived;
  {
    Statement st(db, "SELECT id FROM runs WHERE uuid = ?");
    st.bind(1, archived.uuid);
    if (st.step()) {
      out.local_id = st.getInt(0);
      std::vector<PartDigest> digests;
      const auto metadata = runMetadata(store, out.local_id);
      for (const auto& part : runParts())
        digests.push_back(forEachPartLine(db, part, out.local_id, [](std::string_view) {}));
      if (runDigest(metadata, digests) != archived.sha256)
        throw InputError(
            fmt::format("archive run {} is run {} of {} in another version: delete it there first, or "
                        "pull into another store",
                        archived.id, out.local_id, db.path()));
      out.already_here = true;
      return out;
    }
  }
  const auto version_rows = c.query(fmt::format("SELECT runs.campaign_uuid, parts, {} FROM run_versions v JOIN runs"
                                                " ON runs.uuid = v.run_uuid WHERE run_uuid = $1 AND version = $2",
                                                kRunColumns),
                                    {archived.uuid, std::to_string(archived.version)});
  if (version_rows.empty()) throw StorageError("archive " + c.where() + ": run " + archived.uuid + " vanished");
  const auto& v = version_rows[0];
  const auto parts = nlohmann::json::parse(*v[1]);
  const auto part_version = [&](const char* name) { return parts.at(name).at("version").get<int>(); };

  storage::Transaction tx(db);
  const Id campaign_id =
      localCampaign(db, c, *v[0], archive_numbers ? std::optional<Id>(archived.campaign_id) : std::nullopt);
  localInstruments(db, c, archived.uuid, archived.version, part_version("run_instruments"));
  {
    Statement st(db,
                 "INSERT INTO runs(uuid, campaign_id, instrument_id, kind, axis, name, plan_json, status, source,"
                 " software_version, started_at, finished_at, value_unit, operator_name, compensation_json, id)"
                 " VALUES (?1, ?2, (SELECT id FROM instruments WHERE kind = ?3 AND model = ?4 AND serial = ?5), ?6, ?7,"
                 " ?8, ?9, ?10, ?11, ?12, ?13, ?14, ?15, ?16, ?17, ?18)");
    st.bind(1, archived.uuid)
        .bind(2, campaign_id)
        .bind(18, archive_numbers ? std::optional<Id>(archived.id) : std::nullopt);
    for (int i = 0; i < 15; ++i) st.bind(3 + i, v[static_cast<std::size_t>(2 + i)]);
    st.run();
    out.local_id = db.lastInsertId();
  }
  std::optional<std::int64_t> first_sample;
  for (const auto& part : runParts()) {
    if (parts.at(part.name).at("rows").get<std::int64_t>() == 0) continue;
    Statement insert(db, part.insert);
    insert.bind(1, out.local_id).bind(2, first_sample);
    const std::string_view types(part.types);
    const std::string where = fmt::format("archive {}: {} of run {}", c.where(), part.name, archived.id);
    std::int64_t rows = 0;
    // The month narrows a partitioned part to one partition.
    const std::string month = part.by_month ? fmt::format(" AND run_month = '{}'", runMonth(*v[12])) : "";
    // A part's rows are read through its view, which shows the reader's plants only.
    c.copyOut(
        fmt::format("COPY (SELECT {} FROM visible_{} WHERE run_uuid = '{}' AND version = {}{} ORDER BY {}) TO STDOUT",
                    part.columns, part.name, archived.uuid, part_version(part.name), month, part.columns),
        [&](std::string_view line) {
          const auto row = splitCopyLine(line);
          if (row.size() != types.size())
            throw StorageError(where + ": a row has " + std::to_string(row.size()) + " values, not " +
                               std::to_string(types.size()));
          for (std::size_t i = 0; i < row.size(); ++i)
            bindTyped(insert, 3 + static_cast<int>(i), types[i], row[i], where);
          insert.run();
          if (std::string_view(part.name) == "samples" && rows == 0) first_sample = db.lastInsertId();
          ++rows;
        });
    if (std::string_view(part.name) == "samples" && db.lastInsertId() != *first_sample + rows - 1)
      throw StorageError(where + ": the samples did not get consecutive row ids");
  }
  // What arrived is what was pushed: the run's digest in this store is the archive's.
  std::vector<PartDigest> digests;
  for (const auto& part : runParts())
    digests.push_back(forEachPartLine(db, part, out.local_id, [](std::string_view) {}));
  const auto digest = runDigest(runMetadata(store, out.local_id), digests);
  if (digest != archived.sha256)
    throw StorageError(fmt::format(
        "archive {}: run {} arrived altered: its rows hash to SHA-256 {}, the archive recorded {} when it was "
        "pushed; it was changed in the archive since, nothing of it was written",
        c.where(), archived.id, digest, archived.sha256));
  tx.commit();
  return out;
}

/// A model of the archive in the store (unless there), with its error functions; `archive_number`:
/// numbered as in the archive (a mirror).
PulledModel pullModel(storage::Database& db, Connection& c, std::int64_t id, bool archive_number = false) {
  const auto rows = c.query(
      "SELECT id, uuid, name, station, machine_json, method, provenance_json, software_version, created_at"
      " FROM models WHERE id = $1",
      {std::to_string(id)});
  if (rows.empty()) throw InputError("the archive " + c.where() + " has no model m" + std::to_string(id));
  const auto& r = rows[0];
  PulledModel out{id, *r[1], *r[2], *r[3], 0, false};
  {
    Statement st(db, "SELECT id FROM models WHERE uuid = ?");
    st.bind(1, out.uuid);
    if (st.step()) {
      out.local_id = st.getInt(0);
      out.already_here = true;
      return out;
    }
  }
  // The runs it names, as this store numbers them: those it holds. A model pushed by an mtcal
  // that sent the making store's numbers names runs this store cannot know: none is kept.
  auto archived_provenance = nlohmann::json::parse(*r[6], nullptr, false);
  const bool archive_numbers =
      archived_provenance.is_object() && archived_provenance.value(kArchiveRunNumbers, "") == "archive";
  if (archived_provenance.is_object()) archived_provenance.erase(kArchiveRunNumbers);
  const auto provenance = renumberedProvenance(archived_provenance.dump(), [&](Id archived) -> std::optional<Id> {
    if (!archive_numbers) return std::nullopt;
    const auto rows = c.query("SELECT uuid FROM runs WHERE id = $1", {std::to_string(archived)});
    if (rows.empty()) return std::nullopt;
    Statement here(db, "SELECT id FROM runs WHERE uuid = ?");
    here.bind(1, *rows[0][0]);
    return here.step() ? std::optional<Id>(here.getInt(0)) : std::nullopt;
  });
  storage::Transaction tx(db);
  Statement ins(db,
                "INSERT INTO models(uuid, name, machine_json, method, provenance_json, software_version, created_at,"
                " id) VALUES (?, ?, ?, ?, ?, ?, ?, ?)");
  ins.bind(1, out.uuid)
      .bind(2, out.name)
      .bind(3, *r[4])
      .bind(4, *r[5])
      .bind(5, provenance)
      .bind(6, *r[7])
      .bind(7, *r[8]);
  ins.bind(8, archive_number ? std::optional<Id>(id) : std::nullopt).run();
  out.local_id = db.lastInsertId();
  Statement term(db, "INSERT INTO model_errors(model_id, name, function_json) VALUES (?, ?, ?)");
  for (const auto& e :
       c.query("SELECT name, function_json FROM model_errors WHERE model_uuid = $1 ORDER BY name", {out.uuid}))
    term.bind(1, out.local_id).bind(2, *e[0]).bind(3, *e[1]).run();
  tx.commit();
  return out;
}

}  // namespace

std::vector<ArchivedRun> listArchive(Connection& c, const std::string& machine) {
  requirePlantSchema(c);
  if (machine.empty()) return archivedRuns(c, "", {});
  return archivedRuns(c, "WHERE strpos(m.name, $1) > 0", {machine});
}

PullResult pull(const std::function<storage::Store&()>& open_store, Connection& c, const std::string& what) {
  requirePlantSchema(c);
  PullResult result;
  if (what.starts_with('m') && archiveNumber(std::string_view(what).substr(1))) {
    const auto rows = c.query("SELECT id FROM models WHERE id = $1", {what.substr(1)});
    if (rows.empty()) throw InputError("the archive " + c.where() + " has no model " + what);
    result.models.push_back(pullModel(open_store().database(), c, std::stoll(what.substr(1))));
    return result;
  }
  std::vector<ArchivedRun> runs;
  const bool campaign = what.starts_with('c') && archiveNumber(std::string_view(what).substr(1));
  if (campaign) {
    runs = archivedRuns(c, "WHERE c.id = $1", {what.substr(1)});
    if (runs.empty()) throw InputError("the archive " + c.where() + " has no campaign " + what);
    std::erase_if(runs, [](const ArchivedRun& r) { return r.deleted; });
    if (runs.empty())
      throw InputError("every run of campaign " + what + " of the archive " + c.where() +
                       " was deleted; their earlier versions stay in the archive");
  } else {
    runs = namedRun(c, what, false);
  }
  if (!campaign) {
    if (runs.front().deleted)
      throw InputError(
          fmt::format("archive run {} was deleted (version {}, by station {}, {}); its earlier versions "
                      "stay in the archive (mtcal archive pull {}@{} brings back the last one)",
                      what, runs.front().version, runs.front().station, runs.front().pushed_at, runs.front().id,
                      runs.front().version - 1));
  }
  const auto archive_uuid = archiveUuid(c);
  auto& store = open_store();
  for (const auto& run : runs) {
    result.runs.push_back(pullRun(store, c, run));
    recordVersion(store, archive_uuid, run.uuid, run.version, run.sha256);
  }
  return result;
}

std::vector<ArchivedRun> runHistory(Connection& c, const std::string& run) {
  requirePlantSchema(c);
  return namedRun(c, run, true);
}

MirrorSummary mirror(storage::Store& store, Connection& c) {
  requirePlantSchema(c);
  auto& db = store.database();
  // Which version of each run the mirror holds.
  db.exec(
      "CREATE TABLE IF NOT EXISTS plant_mirror (run_id INTEGER PRIMARY KEY, version INTEGER NOT NULL,"
      " sha256 TEXT NOT NULL)");
  std::map<Id, std::string> held;
  {
    Statement st(db, "SELECT run_id, sha256 FROM plant_mirror");
    while (st.step()) held[st.getInt(0)] = st.getText(1);
  }
  const auto forget = [&](Id run_id) {
    storage::Transaction tx(db);
    store.deleteRun(run_id);
    Statement st(db, "DELETE FROM plant_mirror WHERE run_id = ?");
    st.bind(1, run_id).run();
    tx.commit();
  };
  MirrorSummary summary;
  for (const auto& run : archivedRuns(c, "", {})) {
    const auto it = held.find(run.id);
    const bool current = it != held.end() && it->second == run.sha256 && !run.deleted;
    if (it != held.end()) held.erase(it);
    if (current) continue;
    bool older = false;  // an older version of it, or a run numbered so before the archive was made again
    {
      Statement st(db, "SELECT 1 FROM runs WHERE id = ?");
      st.bind(1, run.id);
      older = st.step();
    }
    if (older) forget(run.id);
    if (run.deleted) continue;
    try {
      storage::Transaction tx(db);
      pullRun(store, c, run, true);
      Statement st(db, "INSERT OR REPLACE INTO plant_mirror(run_id, version, sha256) VALUES (?, ?, ?)");
      st.bind(1, run.id).bind(2, run.version).bind(3, run.sha256).run();
      tx.commit();
      ++summary.runs_copied;
    } catch (const StorageError& e) {  // altered in the archive: left out, the others read
      summary.refused.push_back(e.what());
    }
  }
  for (const auto& [run_id, sha] : held) forget(run_id);  // gone from the archive
  for (const auto& row : c.query("SELECT id FROM models ORDER BY id")) {
    const auto model = pullModel(db, c, std::stoll(*row[0]), true);
    if (!model.already_here) ++summary.models_copied;
  }
  summary.runs = store.listRuns().size();
  return summary;
}

}  // namespace mtcal::archive
