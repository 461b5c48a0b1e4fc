#include "mtcal/storage/store.h"

#include <fmt/format.h>

#include <algorithm>
#include <filesystem>

#include "mtcal/error.h"
#include "mtcal/storage/schema.h"

namespace mtcal::storage {

namespace {
/// The longest name of a run, a machine or a campaign (bytes of UTF-8): it heads tables and reports.
constexpr std::size_t kLongestLabel = 256;

/// A name of a run, a machine or a campaign (`what`: "a run's name"): one line of text, at most
/// kLongestLabel long. @throws InputError naming the character or the length
void checkLabel(const std::string& text, const std::string& what) {
  const auto control = std::find_if(text.begin(), text.end(), [](unsigned char c) { return c < 0x20 || c == 0x7F; });
  if (control != text.end()) {
    throw InputError(fmt::format("{} is one line of text: character {} is 0x{:02X}, a control character", what,
                                 control - text.begin() + 1, static_cast<unsigned char>(*control)));
  }
  if (text.size() > kLongestLabel)
    throw InputError(fmt::format("{} is {} bytes long: at most {}", what, text.size(), kLongestLabel));
}

std::string sampleInsertSql(int rows) {
  std::string sql = "INSERT INTO samples(run_id, device_seq, device_time_ns, value, signal_pct) VALUES (?,?,?,?,?)";
  for (int i = 1; i < rows; ++i) sql += ",(?,?,?,?,?)";
  return sql;
}
}  // namespace

Store::Store(const std::string& path, Open open)
    : db_(path, open), archive_(std::filesystem::weakly_canonical(path).string()) {
  migrate(db_, open == Open::kCreate);
  insert_sample_ = std::make_unique<Statement>(db_, sampleInsertSql(1));
  insert_samples_batch_ = std::make_unique<Statement>(db_, sampleInsertSql(kSampleRowsPerStatement));
  insert_target_ = std::make_unique<Statement>(
      db_,
      "INSERT INTO targets(run_id, seq, target_mm, direction, cycle, measured_mm, deviation_um, time_s,"
      " sample_count, sample_stddev_um, air_temp_c, air_pressure_pa, humidity_pct, material_temp_c, air_index,"
      " first_sample_rowid, last_sample_rowid) VALUES (?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?)");
}

Store::~Store() = default;

Id Store::ensureMachine(const std::string& name, const std::string& description, const std::string& config_json) {
  checkLabel(name, "a machine's name");
  Statement find(db_, "SELECT id FROM machines WHERE name = ?");
  find.bind(1, name);
  if (find.step()) return find.getInt(0);
  Statement ins(db_, "INSERT INTO machines(name, description, config_json) VALUES (?,?,?)");
  ins.bind(1, name).bind(2, description).bind(3, config_json).run();
  return db_.lastInsertId();
}

Id Store::ensureInstrument(const InstrumentInfo& info) {
  Statement find(db_, "SELECT id FROM instruments WHERE kind = ? AND model = ? AND serial = ?");
  find.bind(1, info.kind).bind(2, info.model).bind(3, info.serial);
  if (find.step()) {
    const Id id = find.getInt(0);
    // The read ended before the write: a write from a read still open cannot wait for another
    // process' writer (SQLite answers busy at once when the read's snapshot is older than its
    // last commit), so a second mtcal on a store being recorded failed here instead of waiting.
    find.reset();
    Statement upd(db_, "UPDATE instruments SET firmware = ?, driver_uri = ? WHERE id = ?");
    upd.bind(1, info.firmware).bind(2, info.driver_uri).bind(3, id).run();
    return id;
  }
  Statement ins(db_, "INSERT INTO instruments(kind, model, serial, firmware, driver_uri) VALUES (?,?,?,?,?)");
  ins.bind(1, info.kind).bind(2, info.model).bind(3, info.serial).bind(4, info.firmware).bind(5, info.driver_uri).run();
  return db_.lastInsertId();
}

Id Store::addCampaign(Id machine_id, const std::string& name) {
  checkLabel(name, "a campaign's name");
  Statement ins(db_, "INSERT INTO campaigns(machine_id, name) VALUES (?,?)");
  ins.bind(1, machine_id).bind(2, name).run();
  return db_.lastInsertId();
}

Id Store::addRun(const NewRun& run) {
  checkLabel(run.name, "a run's name");
  Statement ins(db_,
                "INSERT INTO runs(campaign_id, instrument_id, kind, axis, name, plan_json, status, source,"
                " software_version, value_unit, operator_name, compensation_json) VALUES (?,?,?,?,?,?,?,?,?,?,?,?)");
  ins.bind(1, run.campaign_id)
      .bind(2, run.instrument_id)
      .bind(3, run.kind)
      .bind(4, run.axis)
      .bind(5, run.name)
      .bind(6, run.plan_json)
      .bind(7, run.status)
      .bind(8, run.source)
      .bind(9, run.software_version)
      .bind(10, run.value_unit)
      .bind(11, run.operator_name)
      .bind(12, run.compensation_json)
      .run();
  const Id id = db_.lastInsertId();
  if (run.instrument_id) addRunInstrument(id, *run.instrument_id, "measuring");
  if (run.status == run_status::kRunning) {
    const auto self = thisProcess();
    setOwner(id, self);
    setRecording(archive_, id, true);
    std::string with;
    for (const auto& i : runInstruments(id)) with += " with " + i.info.model + " serial " + i.info.serial;
    logEvent(id, "info", "run started" + with + " by " + describe(self));
  }
  return id;
}

void Store::addRunInstrument(Id run_id, Id instrument_id, const std::string& role) {
  Statement ins(db_, "INSERT OR IGNORE INTO run_instruments(run_id, instrument_id, role) VALUES (?,?,?)");
  ins.bind(1, run_id).bind(2, instrument_id).bind(3, role).run();
}

std::vector<RunInstrument> Store::runInstruments(Id run_id) {
  Statement st(
      db_,
      "SELECT i.id, ri.role, i.kind, i.model, i.serial, COALESCE(i.firmware, ''), i.driver_uri FROM run_instruments ri"
      " JOIN instruments i ON i.id = ri.instrument_id JOIN runs r ON r.id = ri.run_id WHERE ri.run_id = ?"
      " ORDER BY (i.id IS NOT r.instrument_id), i.id");
  st.bind(1, run_id);
  std::vector<RunInstrument> out;
  while (st.step()) {
    out.push_back(
        {st.getInt(0), st.getText(1), {st.getText(2), st.getText(3), st.getText(4), st.getText(5), st.getText(6)}});
  }
  return out;
}

void Store::setRunOperator(Id run_id, const std::string& operator_name) {
  Statement upd(db_, "UPDATE runs SET operator_name = ? WHERE id = ?");
  upd.bind(1, operator_name).bind(2, run_id).run();
  if (db_.changes() != 1) throw InputError("run " + std::to_string(run_id) + " does not exist");
}

std::string measurementUnit(const std::string& kind) {
  if (kind == run_kind::kCircle) return "circle points";
  if (kind == run_kind::kEst) return "probe steps";
  if (kind == run_kind::kGantry) return "tracker points";
  if (kind == run_kind::kThermal) return "thermal samples";
  return "targets";
}

void Store::setRunStatus(Id run_id, const std::string& status) {
  Statement upd(db_,
                "UPDATE runs SET status = ?, finished_at = CASE WHEN ? IN ('completed','failed','interrupted')"
                " THEN strftime('%Y-%m-%dT%H:%M:%fZ','now') ELSE NULL END WHERE id = ?");
  upd.bind(1, status).bind(2, status).bind(3, run_id).run();
  if (db_.changes() != 1) throw InputError("run " + std::to_string(run_id) + " does not exist");
  if (status == run_status::kCompleted) logEvent(run_id, "info", "run completed");
  setRecording(archive_, run_id, status == run_status::kRunning);
}

void Store::abandonRun(Id run_id) noexcept { setRecording(archive_, run_id, false); }

void Store::setOwner(Id run_id, const RunOwner& owner) {
  Statement upd(db_,
                "UPDATE runs SET owner_host = ?, owner_pid = ?, owner_start = ?,"
                " heartbeat_at = strftime('%Y-%m-%dT%H:%M:%fZ','now') WHERE id = ?");
  upd.bind(1, owner.host).bind(2, owner.pid).bind(3, owner.process_start).bind(4, run_id).run();
}

RunInfo Store::claimRun(Id run_id) {
  Transaction tx(db_);
  const RunInfo info = run(run_id);
  const std::string which = "run " + std::to_string(run_id);
  if (info.source != "acquired") {
    throw InputError(which + " was imported: there is nothing to resume (import the rest as another run)");
  }
  if (info.status == run_status::kCompleted) throw InputError(which + " is already completed");
  if (info.status == run_status::kRunning) {  // its owner is alive and recording it
    throw InputError(which + " is being recorded by " + describe(*info.owner) +
                     ": wait for it to finish or stop it there (Ctrl-C); a run is resumed once its process has ended");
  }
  if (info.stale) {
    logEvent(run_id, "warning",
             "interrupted: " + (info.owner ? describe(*info.owner) : std::string("its process")) +
                 " ended without closing the run");
  }
  const auto self = thisProcess();
  setRunStatus(run_id, run_status::kRunning);
  setOwner(run_id, self);
  logEvent(run_id, "info", "resumed by " + describe(self) + (operator_.empty() ? "" : " (operator " + operator_ + ")"));
  setRecording(archive_, run_id, true);
  tx.commit();
  return run(run_id);
}

void Store::insertSamples(Id run_id, std::span<const SampleRecord> samples) {
  auto insert = [run_id](Statement& st, std::span<const SampleRecord> rows) {
    int column = 1;
    for (const auto& s : rows) {
      st.bind(column, run_id)
          .bind(column + 1, s.device_seq)
          .bind(column + 2, s.device_time_ns)
          .bind(column + 3, s.value)
          .bind(column + 4, s.signal_pct);
      column += 5;
    }
    st.run();
  };
  std::size_t i = 0;
  for (; i + kSampleRowsPerStatement <= samples.size(); i += kSampleRowsPerStatement) {
    insert(*insert_samples_batch_, samples.subspan(i, kSampleRowsPerStatement));
  }
  for (; i < samples.size(); ++i) insert(*insert_sample_, samples.subspan(i, 1));
}

Id Store::insertTarget(Id run_id, const TargetRecord& t, std::optional<std::int64_t> first_rowid,
                       std::optional<std::int64_t> last_rowid) {
  Statement& st = *insert_target_;
  st.bind(1, run_id)
      .bind(2, t.seq)
      .bind(3, t.target_mm)
      .bind(4, t.direction)
      .bind(5, t.cycle)
      .bind(6, t.measured_mm)
      .bind(7, t.deviation_um)
      .bind(8, t.time_s)
      .bind(9, t.sample_count)
      .bind(10, t.sample_stddev_um)
      .bind(11, t.air_temp_c)
      .bind(12, t.air_pressure_pa)
      .bind(13, t.humidity_pct)
      .bind(14, t.material_temp_c)
      .bind(15, t.air_index)
      .bind(16, first_rowid)
      .bind(17, last_rowid);
  st.run();
  return db_.lastInsertId();
}

Id Store::addTarget(Id run_id, const TargetRecord& target, std::span<const SampleRecord> samples) {
  Transaction tx(db_);
  std::optional<std::int64_t> first, last;
  if (!samples.empty()) {
    insertSamples(run_id, samples);
    // Inside one transaction SQLite hands out consecutive rowids (max + 1 each).
    last = db_.lastInsertId();
    first = *last - static_cast<std::int64_t>(samples.size()) + 1;
  }
  Id id = insertTarget(run_id, target, first, last);
  tx.commit();
  return id;
}

void Store::appendSamples(Id run_id, std::span<const SampleRecord> samples) {
  Transaction tx(db_);
  insertSamples(run_id, samples);
  tx.commit();
}

void Store::addEnvironment(Id run_id, const EnvironmentRecord& env) {
  Statement ins(db_,
                "INSERT INTO environment(run_id, device_time_ns, air_temp_c, air_pressure_pa, humidity_pct,"
                " material_temp1_c, material_temp2_c, material_temp3_c) VALUES (?,?,?,?,?,?,?,?)");
  ins.bind(1, run_id)
      .bind(2, env.device_time_ns)
      .bind(3, env.air_temp_c)
      .bind(4, env.air_pressure_pa)
      .bind(5, env.humidity_pct)
      .bind(6, env.material_temp1_c)
      .bind(7, env.material_temp2_c)
      .bind(8, env.material_temp3_c)
      .run();
}

Id Store::importRun(const NewRun& run, const std::vector<TargetRecord>& targets,
                    const std::vector<std::string>& channel_names, const std::vector<ChannelRow>& channel_rows) {
  Transaction tx(db_);
  Id run_id = addRun(run);
  std::vector<Id> channel_ids;
  Statement add_channel(db_, "INSERT INTO channels(run_id, name) VALUES (?,?)");
  for (const auto& name : channel_names) {
    add_channel.bind(1, run_id).bind(2, name).run();
    channel_ids.push_back(db_.lastInsertId());
  }
  Statement add_value(db_, "INSERT INTO channel_values(channel_id, target_id, value) VALUES (?,?,?)");
  for (std::size_t i = 0; i < targets.size(); ++i) {
    Id target_id = insertTarget(run_id, targets[i], std::nullopt, std::nullopt);
    if (i < channel_rows.size()) {
      for (std::size_t c = 0; c < channel_ids.size() && c < channel_rows[i].size(); ++c) {
        if (channel_rows[i][c]) add_value.bind(1, channel_ids[c]).bind(2, target_id).bind(3, *channel_rows[i][c]).run();
      }
    }
  }
  tx.commit();
  return run_id;
}

namespace {
constexpr const char* kRunColumns =
    "SELECT r.id, r.campaign_id, c.name, m.name, r.instrument_id, r.kind, r.axis, r.name, r.plan_json, r.status,"
    " r.source, r.software_version, r.started_at, r.finished_at,"
    " (SELECT COUNT(*) FROM targets t WHERE t.run_id = r.id), r.value_unit, r.operator_name,"
    " CASE r.kind"
    "  WHEN 'circle' THEN (SELECT COUNT(*) FROM circle_points p WHERE p.run_id = r.id)"
    "  WHEN 'est' THEN (SELECT COUNT(*) FROM probe_steps p WHERE p.run_id = r.id AND p.channel = 1)"
    "  WHEN 'gantry' THEN (SELECT COUNT(*) FROM tracker_points p WHERE p.run_id = r.id)"
    "  WHEN 'thermal' THEN (SELECT COUNT(*) FROM thermal_samples p WHERE p.run_id = r.id)"
    "  ELSE (SELECT COUNT(*) FROM targets t WHERE t.run_id = r.id) END,"
    " r.owner_host, r.owner_pid, r.owner_start, (julianday('now') - julianday(r.heartbeat_at)) * 86400.0,"
    " r.compensation_json, r.uuid"
    " FROM runs r JOIN campaigns c ON c.id = r.campaign_id JOIN machines m ON m.id = c.machine_id";

RunInfo readRun(const Statement& st) {
  RunInfo r;
  r.id = st.getInt(0);
  r.campaign_id = st.getInt(1);
  r.campaign_name = st.getText(2);
  r.machine_name = st.getText(3);
  r.instrument_id = st.getOptionalInt(4);
  r.kind = st.getText(5);
  r.axis = st.getText(6);
  r.name = st.getText(7);
  r.plan_json = st.getText(8);
  r.status = st.getText(9);
  r.source = st.getText(10);
  r.software_version = st.getText(11);
  r.started_at = st.getText(12);
  r.finished_at = st.getOptionalText(13);
  r.target_count = st.getInt(14);
  r.value_unit = st.getText(15);
  r.operator_name = st.getText(16);
  r.measurement_count = st.getInt(17);
  if (const auto pid = st.getOptionalInt(19))
    r.owner = RunOwner{st.getText(18), *pid, st.getText(20), st.getOptionalDouble(21)};
  r.compensation_json = st.getText(22);
  r.uuid = st.getText(23);
  return r;
}
}  // namespace

RunInfo Store::withLiveness(RunInfo r) const {
  // Running without a live owner: the process died (or an mtcal older than owners left it),
  // or it stopped recording without storing the end.
  if (r.status == run_status::kRunning && !(r.owner && ownerAlive(*r.owner, archive_, r.id))) {
    r.stale = true;
    r.status = run_status::kInterrupted;
  }
  return r;
}

std::vector<RunInfo> Store::listRuns() {
  Statement st(db_, std::string(kRunColumns) + " ORDER BY r.id");
  std::vector<RunInfo> runs;
  while (st.step()) runs.push_back(withLiveness(readRun(st)));
  return runs;
}

std::vector<RunInfo> Store::runsWhosePlanHolds(const std::string& text) {
  Statement st(db_, std::string(kRunColumns) + " WHERE instr(r.plan_json, ?) > 0 ORDER BY r.id");
  st.bind(1, text);
  std::vector<RunInfo> runs;
  while (st.step()) runs.push_back(withLiveness(readRun(st)));
  return runs;
}

std::string Store::machineDescriptionOfRun(Id run_id) {
  Statement st(db_,
               "SELECT m.config_json FROM runs r JOIN campaigns c ON c.id = r.campaign_id"
               " JOIN machines m ON m.id = c.machine_id WHERE r.id = ?");
  st.bind(1, run_id);
  if (!st.step()) throw InputError("run " + std::to_string(run_id) + " does not exist in " + name());
  return st.getText(0);
}

RunInfo Store::run(Id run_id) {
  Statement st(db_, std::string(kRunColumns) + " WHERE r.id = ?");
  st.bind(1, run_id);
  if (!st.step()) throw InputError("run " + std::to_string(run_id) + " does not exist in " + name());
  return withLiveness(readRun(st));
}

std::vector<TargetRecord> Store::targets(Id run_id) {
  Statement st(db_,
               "SELECT seq, target_mm, direction, cycle, measured_mm, deviation_um, time_s, sample_count,"
               " sample_stddev_um, air_temp_c, air_pressure_pa, humidity_pct, material_temp_c, air_index"
               " FROM targets WHERE run_id = ? ORDER BY seq");
  st.bind(1, run_id);
  std::vector<TargetRecord> out;
  while (st.step()) {
    TargetRecord t;
    t.seq = st.getInt(0);
    t.target_mm = st.getDouble(1);
    t.direction = static_cast<int>(st.getInt(2));
    t.cycle = static_cast<int>(st.getInt(3));
    t.measured_mm = st.getDouble(4);
    t.deviation_um = st.getDouble(5);
    t.time_s = st.getOptionalDouble(6);
    t.sample_count = st.getInt(7);
    t.sample_stddev_um = st.getOptionalDouble(8);
    t.air_temp_c = st.getOptionalDouble(9);
    t.air_pressure_pa = st.getOptionalDouble(10);
    t.humidity_pct = st.getOptionalDouble(11);
    t.material_temp_c = st.getOptionalDouble(12);
    t.air_index = st.getOptionalDouble(13);
    out.push_back(t);
  }
  return out;
}

std::vector<SampleRecord> Store::samplesOfTarget(Id run_id, std::int64_t seq) {
  Statement st(db_,
               "SELECT s.device_seq, s.device_time_ns, s.value, s.signal_pct FROM targets t"
               " JOIN samples s ON s.rowid BETWEEN t.first_sample_rowid AND t.last_sample_rowid"
               " WHERE t.run_id = ? AND t.seq = ? ORDER BY s.rowid");
  st.bind(1, run_id).bind(2, seq);
  std::vector<SampleRecord> out;
  while (st.step()) {
    out.push_back({st.getInt(0), st.getInt(1), st.getDouble(2), static_cast<int>(st.getInt(3))});
  }
  return out;
}

void Store::forEachSample(Id run_id, const std::function<void(const SampleRecord&)>& visit) {
  Statement st(db_,
               "SELECT device_seq, device_time_ns, value, signal_pct FROM samples WHERE run_id = ? ORDER BY rowid");
  st.bind(1, run_id);
  while (st.step()) visit({st.getInt(0), st.getInt(1), st.getDouble(2), static_cast<int>(st.getInt(3))});
}

std::vector<EnvironmentRecord> Store::environment(Id run_id, std::size_t skip) {
  Statement st(db_,
               "SELECT device_time_ns, air_temp_c, air_pressure_pa, humidity_pct, material_temp1_c, material_temp2_c,"
               " material_temp3_c FROM environment WHERE run_id = ? ORDER BY id LIMIT -1 OFFSET ?");
  st.bind(1, run_id);
  st.bind(2, static_cast<std::int64_t>(skip));
  std::vector<EnvironmentRecord> out;
  while (st.step()) {
    out.push_back({st.getOptionalInt(0), st.getOptionalDouble(1), st.getOptionalDouble(2), st.getOptionalDouble(3),
                   st.getOptionalDouble(4), st.getOptionalDouble(5), st.getOptionalDouble(6)});
  }
  return out;
}

std::int64_t Store::rowsOfRun(const char* table, Id run_id) {
  Statement st(db_, std::string("SELECT COUNT(*) FROM ") + table + " WHERE run_id = ?");
  st.bind(1, run_id);
  st.step();
  return st.getInt(0);
}

std::int64_t Store::sampleCount(Id run_id) { return rowsOfRun("samples", run_id); }

SampleTail Store::sampleTail(Id run_id, std::int64_t after, std::size_t newest) {
  // Backwards from the newest row: a recording run's rows are at the table's end.
  Statement st(db_,
               "SELECT rowid, device_seq, device_time_ns, value, signal_pct FROM samples WHERE rowid > ? AND run_id = ?"
               " ORDER BY rowid DESC LIMIT ?");
  st.bind(1, after);
  st.bind(2, run_id);
  st.bind(3, static_cast<std::int64_t>(newest));
  SampleTail tail;
  tail.position = after;
  while (st.step()) {
    if (tail.samples.empty()) tail.position = st.getInt(0);
    tail.samples.push_back({st.getInt(1), st.getInt(2), st.getDouble(3), static_cast<int>(st.getInt(4))});
  }
  std::reverse(tail.samples.begin(), tail.samples.end());
  return tail;
}

std::vector<std::string> Store::channelNames(Id run_id) {
  Statement st(db_, "SELECT name FROM channels WHERE run_id = ? ORDER BY id");
  st.bind(1, run_id);
  std::vector<std::string> out;
  while (st.step()) out.push_back(st.getText(0));
  return out;
}

std::vector<ChannelRow> Store::channelRows(Id run_id) {
  const std::size_t channels = channelNames(run_id).size();
  std::vector<ChannelRow> rows;
  std::vector<std::int64_t> seqs;
  {
    Statement st(db_, "SELECT seq FROM targets WHERE run_id = ? ORDER BY seq");
    st.bind(1, run_id);
    while (st.step()) seqs.push_back(st.getInt(0));
  }
  rows.assign(seqs.size(), ChannelRow(channels));
  if (channels == 0) return rows;
  Statement st(db_,
               "SELECT t.seq, (SELECT COUNT(*) FROM channels c2 WHERE c2.run_id = c.run_id AND c2.id < c.id), cv.value"
               " FROM channel_values cv JOIN channels c ON c.id = cv.channel_id JOIN targets t ON t.id = cv.target_id"
               " WHERE c.run_id = ?");
  st.bind(1, run_id);
  while (st.step()) {
    const auto row = std::lower_bound(seqs.begin(), seqs.end(), st.getInt(0)) - seqs.begin();
    rows[static_cast<std::size_t>(row)][static_cast<std::size_t>(st.getInt(1))] = st.getDouble(2);
  }
  return rows;
}

Id Store::addModel(const ModelRecord& model) {
  Transaction tx(db_);
  Statement ins(db_,
                "INSERT INTO models(name, machine_json, method, provenance_json, software_version) VALUES (?,?,?,?,?)");
  ins.bind(1, model.name)
      .bind(2, model.machine_json)
      .bind(3, model.method)
      .bind(4, model.provenance_json)
      .bind(5, model.software_version)
      .run();
  const Id id = db_.lastInsertId();
  Statement term(db_, "INSERT INTO model_errors(model_id, name, function_json) VALUES (?,?,?)");
  for (const auto& [name, json] : model.error_functions) term.bind(1, id).bind(2, name).bind(3, json).run();
  tx.commit();
  return id;
}

ModelRecord Store::model(Id model_id) {
  Statement st(db_,
               "SELECT id, name, machine_json, method, provenance_json, software_version, created_at FROM models"
               " WHERE id = ?");
  st.bind(1, model_id);
  if (!st.step()) throw InputError("model " + std::to_string(model_id) + " does not exist in " + name());
  ModelRecord m{st.getInt(0),  st.getText(1), st.getText(2), st.getText(3),
                st.getText(4), st.getText(5), st.getText(6), {}};
  Statement terms(db_, "SELECT name, function_json FROM model_errors WHERE model_id = ? ORDER BY name");
  terms.bind(1, model_id);
  while (terms.step()) m.error_functions.emplace_back(terms.getText(0), terms.getText(1));
  return m;
}

std::vector<ModelRecord> Store::listModels() {
  Statement st(db_,
               "SELECT id, name, machine_json, method, provenance_json, software_version, created_at FROM models"
               " ORDER BY id");
  std::vector<ModelRecord> out;
  while (st.step()) {
    out.push_back(
        {st.getInt(0), st.getText(1), st.getText(2), st.getText(3), st.getText(4), st.getText(5), st.getText(6), {}});
  }
  return out;
}

std::optional<Id> Store::sameResult(Id run_id, const std::string& processor, const std::string& version,
                                    const std::string& parameters_json, const std::string& output_json) {
  Statement same(db_,
                 "SELECT id FROM results WHERE run_id = ? AND processor = ? AND processor_version = ?"
                 " AND parameters_json = ? AND output_json = ? ORDER BY id DESC LIMIT 1");
  same.bind(1, run_id).bind(2, processor).bind(3, version).bind(4, parameters_json).bind(5, output_json);
  if (same.step()) return same.getInt(0);
  return std::nullopt;
}

Id Store::addResult(Id run_id, const std::string& processor, const std::string& version,
                    const std::string& parameters_json, const std::string& output_json) {
  // The same analysis of the same data: the stored result stands. Anything else is a new version.
  if (const auto same = sameResult(run_id, processor, version, parameters_json, output_json)) return *same;
  Statement ins(db_,
                "INSERT INTO results(run_id, processor, processor_version, parameters_json, output_json)"
                " VALUES (?,?,?,?,?)");
  ins.bind(1, run_id).bind(2, processor).bind(3, version).bind(4, parameters_json).bind(5, output_json).run();
  return db_.lastInsertId();
}

void Store::addThermalChannels(Id run_id, const std::vector<ThermalChannel>& channels) {
  Transaction tx(db_);
  Statement ins(db_, "INSERT INTO thermal_channels(run_id, idx, name, kind, unit) VALUES (?,?,?,?,?)");
  for (std::size_t i = 0; i < channels.size(); ++i) {
    ins.bind(1, run_id).bind(2, static_cast<std::int64_t>(i)).bind(3, channels[i].name).bind(4, channels[i].kind);
    ins.bind(5, channels[i].unit).run();
  }
  tx.commit();
}

std::vector<ThermalChannel> Store::thermalChannels(Id run_id) {
  Statement st(db_, "SELECT name, kind, unit FROM thermal_channels WHERE run_id = ? ORDER BY idx");
  st.bind(1, run_id);
  std::vector<ThermalChannel> out;
  while (st.step()) out.push_back({st.getText(0), st.getText(1), st.getText(2)});
  return out;
}

void Store::addThermalSamples(Id run_id, std::span<const ThermalSample> samples) {
  const auto channels = static_cast<std::size_t>(rowsOfRun("thermal_channels", run_id));
  Transaction tx(db_);
  Statement add_sample(db_, "INSERT INTO thermal_samples(run_id, idx, time_s, segment) VALUES (?,?,?,?)");
  Statement add_value(db_, "INSERT INTO thermal_values(run_id, sample, channel, value) VALUES (?,?,?,?)");
  for (const auto& s : samples) {
    if (s.values.size() != channels) {
      throw InputError("thermal sample " + std::to_string(s.index) + " of run " + std::to_string(run_id) + " has " +
                       std::to_string(s.values.size()) + " values for " + std::to_string(channels) + " channels");
    }
    add_sample.bind(1, run_id).bind(2, s.index).bind(3, s.time_s).bind(4, s.segment).run();
    for (std::size_t c = 0; c < channels; ++c) {
      add_value.bind(1, run_id).bind(2, s.index).bind(3, static_cast<std::int64_t>(c)).bind(4, s.values[c]).run();
    }
  }
  tx.commit();
}

std::vector<ThermalSample> Store::thermalSamples(Id run_id) {
  const auto channels = thermalChannels(run_id).size();
  Statement st(db_,
               "SELECT s.idx, s.time_s, v.channel, v.value, s.segment FROM thermal_samples s LEFT JOIN thermal_values v"
               " ON v.run_id = s.run_id AND v.sample = s.idx WHERE s.run_id = ? ORDER BY s.idx, v.channel");
  st.bind(1, run_id);
  std::vector<ThermalSample> out;
  while (st.step()) {
    const std::int64_t idx = st.getInt(0);
    if (out.empty() || out.back().index != idx)
      out.push_back(
          {idx, st.getDouble(1), std::vector<std::optional<double>>(channels), static_cast<int>(st.getInt(4))});
    if (const auto c = st.getOptionalInt(2); c && static_cast<std::size_t>(*c) < channels) {
      out.back().values[static_cast<std::size_t>(*c)] = st.getOptionalDouble(3);
    }
  }
  return out;
}

std::int64_t Store::thermalSampleCount(Id run_id) { return rowsOfRun("thermal_samples", run_id); }

void Store::addProbeStep(Id run_id, const ProbeStep& step) {
  Transaction tx(db_);
  Statement ins(db_,
                "INSERT INTO probe_steps(run_id, step, position_mm, channel, value_um, s_um, readings)"
                " VALUES (?,?,?,?,?,?,?)");
  for (const auto& c : step.channels) {
    ins.bind(1, run_id).bind(2, step.step).bind(3, step.position_mm).bind(4, static_cast<std::int64_t>(c.channel));
    ins.bind(5, c.value_um).bind(6, c.s_um).bind(7, static_cast<std::int64_t>(c.readings)).run();
  }
  tx.commit();
}

std::vector<ProbeStep> Store::probeSteps(Id run_id) {
  Statement st(db_,
               "SELECT step, position_mm, channel, value_um, s_um, readings FROM probe_steps WHERE run_id = ?"
               " ORDER BY step, channel");
  st.bind(1, run_id);
  std::vector<ProbeStep> out;
  while (st.step()) {
    const std::int64_t step = st.getInt(0);
    if (out.empty() || out.back().step != step) out.push_back({step, st.getDouble(1), {}});
    out.back().channels.push_back(
        {static_cast<int>(st.getInt(2)), st.getDouble(3), st.getOptionalDouble(4), static_cast<int>(st.getInt(5))});
  }
  return out;
}

void Store::addCirclePoints(Id run_id, std::span<const CirclePointRecord> points) {
  Transaction tx(db_);
  Statement ins(
      db_, "INSERT INTO circle_points(run_id, direction, idx, angle_deg, deviation_um, time_s) VALUES (?,?,?,?,?,?)");
  for (const auto& p : points) {
    ins.bind(1, run_id)
        .bind(2, p.direction)
        .bind(3, p.index)
        .bind(4, p.angle_deg)
        .bind(5, p.deviation_um)
        .bind(6, p.time_s)
        .run();
  }
  tx.commit();
}

std::vector<CirclePointRecord> Store::circlePoints(Id run_id) {
  Statement st(db_,
               "SELECT direction, idx, angle_deg, deviation_um, time_s FROM circle_points WHERE run_id = ?"
               " ORDER BY direction = 'cw', idx");
  st.bind(1, run_id);
  std::vector<CirclePointRecord> out;
  while (st.step()) {
    out.push_back({st.getText(0), st.getInt(1), st.getDouble(2), st.getDouble(3), st.getOptionalDouble(4)});
  }
  return out;
}

void Store::addTrackerPoints(Id run_id, std::span<const TrackerPointRecord> points) {
  Transaction tx(db_);
  Statement next(db_, "SELECT COALESCE(MAX(idx) + 1, 0) FROM tracker_points WHERE run_id = ?");
  next.bind(1, run_id);
  next.step();
  std::int64_t idx = next.getInt(0);
  Statement ins(db_,
                "INSERT INTO tracker_points(run_id, idx, feature, place, x_mm, y_mm, z_mm, time_s, integration_ms)"
                " VALUES (?,?,?,?,?,?,?,?,?)");
  for (const auto& p : points) {
    std::optional<std::int64_t> integration;
    if (p.integration_ms) integration = *p.integration_ms;
    ins.bind(1, run_id)
        .bind(2, idx++)
        .bind(3, p.feature)
        .bind(4, p.place)
        .bind(5, p.x_mm)
        .bind(6, p.y_mm)
        .bind(7, p.z_mm)
        .bind(8, p.time_s)
        .bind(9, integration)
        .run();
  }
  tx.commit();
}

std::int64_t Store::trackerPointCount(Id run_id) { return rowsOfRun("tracker_points", run_id); }

std::vector<TrackerPointRecord> Store::trackerPoints(Id run_id) {
  Statement st(db_,
               "SELECT feature, place, x_mm, y_mm, z_mm, time_s, integration_ms FROM tracker_points WHERE run_id = ?"
               " ORDER BY idx");
  st.bind(1, run_id);
  std::vector<TrackerPointRecord> out;
  while (st.step()) {
    TrackerPointRecord r{
        st.getText(0), st.getText(1), st.getDouble(2), st.getDouble(3), st.getDouble(4), st.getOptionalDouble(5), {}};
    if (const auto ms = st.getOptionalDouble(6)) r.integration_ms = static_cast<int>(*ms);
    out.push_back(r);
  }
  return out;
}

std::vector<Store::Result> Store::results(Id run_id) {
  Statement st(db_,
               "SELECT id, processor, processor_version, parameters_json, output_json, created_at FROM results"
               " WHERE run_id = ? ORDER BY id");
  st.bind(1, run_id);
  std::vector<Result> out;
  while (st.step())
    out.push_back({st.getInt(0), st.getText(1), st.getText(2), st.getText(3), st.getText(4), st.getText(5)});
  return out;
}

void Store::logEvent(std::optional<Id> run_id, const std::string& level, const std::string& message) {
  Statement ins(db_, "INSERT INTO events(run_id, level, message) VALUES (?,?,?)");
  ins.bind(1, run_id).bind(2, level).bind(3, message).run();
}

std::vector<Id> Store::campaignRuns(Id campaign_id) {
  Statement exists(db_, "SELECT 1 FROM campaigns WHERE id = ?");
  exists.bind(1, campaign_id);
  if (!exists.step()) throw InputError("campaign c" + std::to_string(campaign_id) + " does not exist in " + name());
  Statement st(db_, "SELECT id FROM runs WHERE campaign_id = ? ORDER BY id");
  st.bind(1, campaign_id);
  std::vector<Id> out;
  while (st.step()) out.push_back(st.getInt(0));
  return out;
}

namespace {
// What belongs to a run, the dependent rows first.
constexpr const char* kRunRows[] = {
    "DELETE FROM thermal_values WHERE run_id = ?",
    "DELETE FROM thermal_samples WHERE run_id = ?",
    "DELETE FROM thermal_channels WHERE run_id = ?",
    "DELETE FROM tracker_points WHERE run_id = ?",
    "DELETE FROM circle_points WHERE run_id = ?",
    "DELETE FROM probe_steps WHERE run_id = ?",
    "DELETE FROM channel_values WHERE channel_id IN (SELECT id FROM channels WHERE run_id = ?)",
    "DELETE FROM channels WHERE run_id = ?",
    "DELETE FROM samples WHERE run_id = ?",
    "DELETE FROM environment WHERE run_id = ?",
    "DELETE FROM targets WHERE run_id = ?",
    "DELETE FROM results WHERE run_id = ?",
    "DELETE FROM events WHERE run_id = ?",
    "DELETE FROM run_notes WHERE run_id = ?",
    "DELETE FROM run_instruments WHERE run_id = ?",
    "DELETE FROM runs WHERE id = ?",
};
}  // namespace

void Store::deleteRun(Id run_id) {
  Transaction tx(db_);
  const auto info = run(run_id);
  if (info.status == run_status::kRunning) {
    throw InputError("run " + std::to_string(run_id) + " is being recorded by " + describe(*info.owner) +
                     ": it cannot be deleted now");
  }
  Statement(db_, "INSERT OR IGNORE INTO deleted_runs(uuid) VALUES (?)").bind(1, info.uuid).run();
  for (const char* sql : kRunRows) Statement(db_, sql).bind(1, run_id).run();
  tx.commit();
}

void Store::deleteCampaign(Id campaign_id) {
  Transaction tx(db_);
  for (const Id run_id : campaignRuns(campaign_id)) deleteRun(run_id);
  Statement(db_, "DELETE FROM campaigns WHERE id = ?").bind(1, campaign_id).run();
  tx.commit();
}

void Store::renameRun(Id run_id, const std::string& name) {
  if (name.empty()) throw InputError("a run's name cannot be empty");
  checkLabel(name, "a run's name");
  Statement upd(db_, "UPDATE runs SET name = ? WHERE id = ?");
  upd.bind(1, name).bind(2, run_id).run();
  if (db_.changes() != 1) throw InputError("run " + std::to_string(run_id) + " does not exist in " + this->name());
}

void Store::addNote(Id run_id, const std::string& author, const std::string& text) {
  if (text.empty()) throw InputError("a note needs a text");
  run(run_id);  // it exists
  Statement(db_, "INSERT INTO run_notes(run_id, author, text) VALUES (?,?,?)")
      .bind(1, run_id)
      .bind(2, author)
      .bind(3, text)
      .run();
}

std::vector<Store::Note> Store::notes(Id run_id) {
  Statement st(db_, "SELECT author, text, created_at FROM run_notes WHERE run_id = ? ORDER BY id");
  st.bind(1, run_id);
  std::vector<Note> out;
  while (st.step()) out.push_back({st.getText(0), st.getText(1), st.getText(2)});
  return out;
}

void Store::backupTo(const std::string& path) { db_.backupTo(path); }

std::vector<std::string> Store::check() {
  std::vector<std::string> problems;
  Statement integrity(db_, "PRAGMA integrity_check");
  while (integrity.step()) {
    if (integrity.getText(0) != "ok") problems.push_back("integrity: " + integrity.getText(0));
  }
  Statement keys(db_, "PRAGMA foreign_key_check");
  while (keys.step()) {
    problems.push_back("foreign key: a row of " + keys.getText(0) + " (rowid " + keys.getText(1) +
                       ") refers to a missing row of " + keys.getText(2));
  }
  for (const char* table :
       {"targets", "samples", "environment", "channels", "results", "events", "probe_steps", "circle_points",
        "tracker_points", "thermal_channels", "thermal_samples", "thermal_values", "run_instruments", "run_notes"}) {
    Statement orphans(db_, std::string("SELECT COUNT(*) FROM ") + table +
                               " WHERE run_id IS NOT NULL AND run_id NOT IN (SELECT id FROM runs)");
    orphans.step();
    if (const auto n = orphans.getInt(0); n > 0)
      problems.push_back(std::to_string(n) + " row(s) of " + table + " belong to no run");
  }
  return problems;
}

std::vector<Store::Event> Store::events(Id run_id) {
  Statement st(db_, "SELECT level, message, created_at FROM events WHERE run_id = ? ORDER BY id");
  st.bind(1, run_id);
  std::vector<Event> out;
  while (st.step()) out.push_back({st.getText(0), st.getText(1), st.getText(2)});
  return out;
}

}  // namespace mtcal::storage
