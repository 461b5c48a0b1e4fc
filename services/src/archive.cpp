#include "mtcal/services/archive.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <chrono>
#include <filesystem>
#include <tuple>

#include "mtcal/acquisition/linear_plan.h"
#include "mtcal/error.h"

namespace mtcal::services {
namespace {

/// A date (2026-11-24) or a time (2026-11-24T08:00, 2026-11-24 08:00:05) as the archive's
/// timestamps write it (ISO 8601, UTC, with T): text order is then time order. Empty stays empty.
std::string timestampOf(const std::string& text, const char* option) {
  if (text.empty()) return text;
  const auto refuse = [&] {
    return InputError(
        fmt::format("{} '{}': not a date or time; give 2026-11-24, 2026-11-24T08:00 or "
                    "2026-11-24 08:00:05 (UTC)",
                    option, text));
  };
  static const std::string kShape = "dddd-dd-ddTdd:dd:dd";
  std::string t = text;
  if (t.size() > 10 && t[10] == ' ') t[10] = 'T';
  if (t.size() != 10 && t.size() != 16 && t.size() != 19) throw refuse();
  for (std::size_t i = 0; i < t.size(); ++i) {
    const bool digit = std::isdigit(static_cast<unsigned char>(t[i])) != 0;
    if (kShape[i] == 'd' ? !digit : t[i] != kShape[i]) throw refuse();
  }
  const auto number = [&](std::size_t at, std::size_t n) { return std::stoi(t.substr(at, n)); };
  const std::chrono::year_month_day date{std::chrono::year(number(0, 4)),
                                         std::chrono::month(static_cast<unsigned>(number(5, 2))),
                                         std::chrono::day(static_cast<unsigned>(number(8, 2)))};
  if (!date.ok()) throw refuse();
  if (t.size() >= 16 && (number(11, 2) > 23 || number(14, 2) > 59)) throw refuse();
  if (t.size() == 19 && number(17, 2) > 59) throw refuse();
  return t;
}

}  // namespace

std::string staleNote(const storage::RunInfo& run) {
  if (!run.stale) return {};
  return (run.owner ? storage::describe(*run.owner) : std::string("its process")) +
         " ended without closing the run: resume it with mtcal resume " + std::to_string(run.id);
}

nlohmann::json runDocument(const storage::RunInfo& run) {
  nlohmann::json owner = nullptr;
  if (run.owner) owner = {{"host", run.owner->host}, {"pid", run.owner->pid}};
  return {{"id", run.id},
          {"uuid", run.uuid},
          {"owner", owner},
          {"stale", run.stale},
          {"name", run.name},
          {"kind", run.kind},
          {"axis", run.axis},
          {"status", run.status},
          {"source", run.source},
          {"machine", run.machine_name},
          {"campaign", run.campaign_name},
          {"campaign_id", run.campaign_id},
          {"instrument_id", run.instrument_id ? nlohmann::json(*run.instrument_id) : nlohmann::json(nullptr)},
          {"targets", run.target_count},
          {"measured", run.measurement_count},
          {"measured_unit", storage::measurementUnit(run.kind)},
          {"operator", run.operator_name},
          {"software_version", run.software_version},
          {"started_at", run.started_at},
          {"finished_at", run.finished_at ? nlohmann::json(*run.finished_at) : nlohmann::json(nullptr)}};
}

nlohmann::json runListDocument(const std::vector<storage::RunInfo>& runs) {
  nlohmann::json list = nlohmann::json::array();
  for (const auto& r : runs) list.push_back(runDocument(r));
  return {{"schema_version", 1}, {"runs", list}};
}

std::vector<storage::RunInfo> listRuns(Session& session, const RunFilter& filter) {
  static const std::vector<std::string> kSorts = {"id", "started", "machine", "kind", "axis", "status", "name"};
  if (std::find(kSorts.begin(), kSorts.end(), filter.sort) == kSorts.end()) {
    throw InputError(fmt::format("sort '{}': sort by one of {}", filter.sort, fmt::join(kSorts, ", ")));
  }
  for (const auto& [option, given, known] :
       {std::tuple{"kind", &filter.kind, std::vector<std::string>{"linear", "circle", "est", "gantry", "thermal"}},
        {"status", &filter.status,
         std::vector<std::string>{"running", "interrupted", "completed", "failed", "imported"}}}) {
    if (!given->empty() && std::find(known.begin(), known.end(), *given) == known.end())
      throw InputError(fmt::format("{} '{}': one of {}", option, *given, fmt::join(known, ", ")));
  }
  const auto lower = [](std::string text) {
    std::transform(text.begin(), text.end(), text.begin(), [](unsigned char c) { return std::tolower(c); });
    return text;
  };
  // A run's axes are letters of the machine's: an axis (X), a plane (XY), a gantry's XYZAC.
  if (lower(filter.axis).find_first_not_of("xyzabc") != std::string::npos)
    throw InputError(
        fmt::format("axis '{}': a run's axes are of X, Y, Z, A, B, C (an axis X, a plane XY, a gantry's "
                    "XYZAC)",
                    filter.axis));
  const std::string since = timestampOf(filter.since, "since"), until = timestampOf(filter.until, "until");
  if (!since.empty() && !until.empty() && since.substr(0, until.size()) > until)
    throw InputError(
        fmt::format("since {} is after until {}: no run could have started between", filter.since, filter.until));
  std::vector<storage::RunInfo> out;
  for (auto& r : session.store().listRuns()) {
    if (!filter.machine.empty() && lower(r.machine_name).find(lower(filter.machine)) == std::string::npos) continue;
    if (!filter.kind.empty() && r.kind != filter.kind) continue;
    if (!filter.axis.empty() && lower(r.axis) != lower(filter.axis)) continue;
    if (!filter.status.empty() && r.status != filter.status) continue;
    if (filter.campaign && r.campaign_id != *filter.campaign) continue;
    // Timestamps are ISO 8601 UTC: text order is time order; a date alone takes its whole day.
    if (!since.empty() && r.started_at < since) continue;
    if (!until.empty() && r.started_at.substr(0, until.size()) > until) continue;
    out.push_back(std::move(r));
  }
  const auto key = [&](const storage::RunInfo& r) -> std::string {
    if (filter.sort == "started") return r.started_at;
    if (filter.sort == "machine") return r.machine_name;
    if (filter.sort == "kind") return r.kind;
    if (filter.sort == "axis") return r.axis;
    if (filter.sort == "status") return r.status;
    if (filter.sort == "name") return r.name;
    return {};
  };
  std::stable_sort(out.begin(), out.end(), [&](const storage::RunInfo& a, const storage::RunInfo& b) {
    const auto ka = key(a), kb = key(b);
    if (ka != kb) return filter.descending ? ka > kb : ka < kb;
    return filter.descending ? a.id > b.id : a.id < b.id;
  });
  return out;
}

ArchiveItem ArchiveItem::parse(const std::string& text, std::string_view accepted) {
  const char prefix = text.empty() ? '\0' : static_cast<char>(std::tolower(static_cast<unsigned char>(text[0])));
  const char kind = prefix == 'c' || prefix == 'm' ? prefix : 'r';
  const std::string digits = kind == 'r' ? text : text.substr(1);
  storage::Id id = 0;
  const auto [end, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), id);
  if (accepted.find(kind) == std::string_view::npos || digits.empty() || ec != std::errc() ||
      end != digits.data() + digits.size() || id <= 0) {
    std::vector<std::string> forms;
    if (accepted.find('r') != std::string_view::npos) forms.emplace_back("a run id (e.g. 12)");
    if (accepted.find('c') != std::string_view::npos) forms.emplace_back("a campaign (e.g. c3)");
    if (accepted.find('m') != std::string_view::npos) forms.emplace_back("a model (e.g. m2)");
    throw InputError(fmt::format("'{}' is not {}", text, fmt::join(forms, " or ")));
  }
  ArchiveItem item;
  (kind == 'c' ? item.campaign : kind == 'm' ? item.model : item.run) = id;
  return item;
}

storage::Id modelIdOf(const std::string& text) {
  const bool digit = !text.empty() && std::isdigit(static_cast<unsigned char>(text[0]));
  try {
    return *ArchiveItem::parse(digit ? "m" + text : text, "m").model;
  } catch (const InputError&) {
    throw InputError(fmt::format("'{}' is not a model (e.g. m2 or 2)", text));
  }
}

std::vector<storage::RunInfo> runsOf(Session& session, const ArchiveItem& what) {
  auto& store = session.store();
  if (what.run) return {store.run(*what.run)};
  std::vector<storage::RunInfo> out;
  for (const auto id : store.campaignRuns(*what.campaign)) out.push_back(store.run(id));
  return out;
}

void deleteRuns(Session& session, const ArchiveItem& what) {
  session.requireLocalStore("delete");
  auto& store = session.store();
  if (what.run) {
    store.deleteRun(*what.run);
  } else {
    store.deleteCampaign(*what.campaign);
  }
}

void renameRun(Session& session, storage::Id run_id, const std::string& name) {
  session.requireLocalStore("rename");
  // One line of text (Store::renameRun), not blank.
  if (name.find_first_not_of(' ') == std::string::npos) throw InputError("a run's name cannot be empty");
  session.store().renameRun(run_id, name);
}

void noteRun(Session& session, storage::Id run_id, const std::string& text) {
  session.requireLocalStore("note");
  session.store().addNote(run_id, session.options().operator_name, text);
}

void backupArchive(Session& session, const std::string& path) {
  session.requireLocalStore("backup");
  session.store().backupTo(path);
}

std::vector<std::string> checkArchive(Session& session) {
  session.requireLocalStore("check");
  const auto& path = session.options().db_path;
  if (!std::filesystem::exists(path)) storage::Database missing(path, storage::Open::kReadOnly);  // throws: no store
  try {
    return session.store().check();
  } catch (const StorageError&) {
    // A file too damaged to open as a store: what SQLite's own check of it finds.
    std::vector<std::string> damage;
    try {
      storage::Database file(path, storage::Open::kReadOnly);
      storage::Statement integrity(file, "PRAGMA integrity_check");
      while (integrity.step())
        if (integrity.getText(0) != "ok") damage.push_back("integrity: " + integrity.getText(0));
    } catch (const StorageError& unreadable) {
      damage.push_back(unreadable.what());
    }
    if (damage.empty()) throw;  // sound to SQLite, but no mtcal store (another program's database)
    return damage;
  }
}

RunDetail showRun(Session& session, storage::Id run_id) {
  auto& store = session.store();
  RunDetail d;
  d.run = store.run(run_id);
  d.targets = store.targets(run_id);
  d.events = store.events(run_id);
  d.instruments = store.runInstruments(run_id);
  d.channels = store.channelNames(run_id);
  d.results = store.results(run_id);
  d.notes = store.notes(run_id);
  if (d.run.source == "acquired") d.raw_samples = store.sampleCount(run_id);
  if (d.run.kind == storage::run_kind::kGantry) d.tracker_points = store.trackerPointCount(run_id);
  if (d.run.kind == storage::run_kind::kThermal) {
    d.thermal_samples = store.thermalSampleCount(run_id);
    d.thermal_channels = store.thermalChannels(run_id);
  }
  return d;
}

nlohmann::json RunDetail::document() const {
  nlohmann::json j = runDocument(run);
  j["schema_version"] = 1;
  j["plan"] = nlohmann::json::parse(run.plan_json);
  j["compensation"] = nlohmann::json::parse(run.compensation_json);  // the tables the controller ran
  j["channels"] = channels;
  nlohmann::json t = nlohmann::json::array();
  const std::string value = run.value_unit == "urad" ? "deviation_urad" : "deviation_um";  // an angle's in urad
  for (const auto& r : targets) {
    t.push_back({{"seq", r.seq},
                 {"target_mm", r.target_mm},
                 {"direction", r.direction > 0 ? "up" : "down"},
                 {"cycle", r.cycle},
                 {"measured_mm", r.measured_mm},
                 {value, r.deviation_um},
                 {"samples", r.sample_count}});
  }
  j["target_values"] = t;
  if (run.kind == storage::run_kind::kGantry) j["tracker_points"] = tracker_points;
  if (run.kind == storage::run_kind::kThermal) {
    j["thermal_samples"] = thermal_samples;
    nlohmann::json c = nlohmann::json::array();
    for (const auto& ch : thermal_channels) c.push_back({{"name", ch.name}, {"kind", ch.kind}, {"unit", ch.unit}});
    j["thermal_channels"] = c;
  }
  nlohmann::json e = nlohmann::json::array();
  for (const auto& ev : events) e.push_back({{"level", ev.level}, {"message", ev.message}, {"time", ev.created_at}});
  j["events"] = e;
  nlohmann::json instruments = nlohmann::json::array();
  for (const auto& i : this->instruments) {
    instruments.push_back({{"id", i.instrument_id},
                           {"role", i.role},
                           {"kind", i.info.kind},
                           {"model", i.info.model},
                           {"serial", i.info.serial},
                           {"firmware", i.info.firmware},
                           {"uri", i.info.driver_uri}});
  }
  j["instruments"] = instruments;
  nlohmann::json stored = nlohmann::json::array();
  for (const auto& r : results) {
    stored.push_back({{"id", r.id},
                      {"processor", r.processor},
                      {"version", r.processor_version},
                      {"parameters", nlohmann::json::parse(r.parameters_json, nullptr, false)},
                      {"created_at", r.created_at}});
  }
  j["results"] = stored;
  nlohmann::json notes_json = nlohmann::json::array();
  for (const auto& n : notes)
    notes_json.push_back({{"author", n.author}, {"text", n.text}, {"created_at", n.created_at}});
  j["notes"] = notes_json;
  if (run.stale) j["interrupted_because"] = staleNote(run);
  return j;
}

bool RunProgress::finished() const { return run.status != storage::run_status::kRunning || run.stale; }

RunProgress runProgress(Session& session, storage::Id run_id, const ProgressSeen& seen) {
  // Only what a watcher needs, every poll: not showRun's sample counts (millions at 50 kHz).
  auto& store = session.store();
  RunProgress p;
  p.run = store.run(run_id);
  const auto targets = store.targets(run_id);
  const auto events = store.events(run_id);
  p.captures =
      p.run.kind == storage::run_kind::kLinear ? targets.size() : static_cast<std::size_t>(p.run.measurement_count);
  if (p.run.kind == storage::run_kind::kLinear) {
    const auto plan = nlohmann::json::parse(p.run.plan_json, nullptr, false);
    if (plan.is_object() && p.run.source != "imported") {
      try {
        p.planned = acquisition::linearTargets(acquisition::LinearPlan::fromJson(plan, "stored plan")).size();
      } catch (const InputError&) {
        p.planned = 0;  // a plan of an older version: progress without a total
      }
    }
  }
  for (std::size_t i = seen.captures; i < targets.size(); ++i) p.new_captures.push_back(targets[i]);
  for (std::size_t i = seen.events; i < events.size(); ++i) p.new_events.push_back(events[i]);
  p.new_environment = store.environment(run_id, seen.environment);
  auto tail = store.sampleTail(run_id, seen.stream_position, RunProgress::kStreamSamples);
  p.stream_position = tail.position;
  // Every n-th counted back from the newest, which is always shown: the current reading.
  const std::size_t n = tail.samples.size();
  const std::size_t stride =
      std::max<std::size_t>((n + RunProgress::kStreamPoints - 1) / RunProgress::kStreamPoints, 1);
  for (std::size_t back = 0; back < n; back += stride) p.stream.push_back(tail.samples[n - 1 - back]);
  std::reverse(p.stream.begin(), p.stream.end());
  return p;
}

}  // namespace mtcal::services
