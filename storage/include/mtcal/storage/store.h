#pragma once
// Typed access to an mtcal database: what acquisition, import and analysis read and write.
// Every write that belongs together is one transaction: a target and its raw samples, an
// imported run and all its rows. A failure rolls the whole unit back.
//
// Thread-safety: a Store owns one connection and belongs to one thread (see sqlite.h).
// Units: lengths mm, deviations um, temperatures degC, pressure Pa, device time ns.

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "mtcal/storage/run_owner.h"
#include "mtcal/storage/sqlite.h"

namespace mtcal::storage {

using Id = std::int64_t;

struct InstrumentInfo {
  std::string kind;  ///< interferometer, ballbar, probes, tracker, imported
  std::string model;
  std::string serial;
  std::string firmware;
  std::string driver_uri;
};

/// Run status values as stored.
namespace run_status {
inline constexpr const char* kRunning = "running";
inline constexpr const char* kInterrupted = "interrupted";
inline constexpr const char* kCompleted = "completed";
inline constexpr const char* kFailed = "failed";
inline constexpr const char* kImported = "imported";
}  // namespace run_status

/// The machine of runs imported without one named: one machine to the archive, whatever they
/// were measured on.
inline constexpr const char* kImportedMachine = "imported";

/// Run kinds as stored: what a run measured and so which tables hold its data.
namespace run_kind {
inline constexpr const char* kLinear = "linear";    ///< targets along one axis (interferometer)
inline constexpr const char* kCircle = "circle";    ///< circle_points (ballbar)
inline constexpr const char* kEst = "est";          ///< probe_steps (probes stepped along a guideway)
inline constexpr const char* kGantry = "gantry";    ///< tracker_points (laser tracker)
inline constexpr const char* kThermal = "thermal";  ///< thermal_samples (logger, probes, interferometer)
/// "a linear run", "an est run": a run of `kind` in a sentence.
inline std::string aRunOf(const std::string& kind) {
  const bool vowel = !kind.empty() && std::string_view("aeiou").find(kind.front()) != std::string_view::npos;
  return (vowel ? "an " : "a ") + kind + " run";
}
}  // namespace run_kind

struct NewRun {
  Id campaign_id = 0;
  std::optional<Id> instrument_id;
  std::string kind = run_kind::kLinear;
  std::string axis;
  std::string name;
  std::string plan_json = "{}";
  std::string status = run_status::kRunning;
  std::string source = "acquired";
  std::string software_version;
  std::string value_unit = "um";  ///< unit of the targets' values: um, or urad for angular runs
  std::string operator_name;      ///< who measured; empty: not known
  /// The compensation tables the machine's controller applied while the run measured (JSON:
  /// {"X": {"controller", "file", "position", "correction_up_um", "correction_down_um"}});
  /// "{}": none, or not known.
  std::string compensation_json = "{}";
};

/// An instrument that took part in a run.
struct RunInstrument {
  Id instrument_id = 0;
  std::string role;  ///< measuring (the run's main instrument), displacement, environment ...
  InstrumentInfo info;
};

/// One channel at one step of a probe stepping run.
struct ProbeReading {
  int channel = 1;
  double value_um = 0.0;
  std::optional<double> s_um;
  int readings = 1;
};
struct ProbeStep {
  std::int64_t step = 0;
  double position_mm = 0.0;
  std::vector<ProbeReading> channels;
};

/// One point of a circular test (ballbar): radial deviation at an angle of the plane.
struct CirclePointRecord {
  std::string direction;  ///< "ccw" or "cw"
  std::int64_t index = 0;
  double angle_deg = 0.0;
  double deviation_um = 0.0;
  std::optional<double> time_s;
};

/// A point measured by a laser tracker (its frame, mm).
struct TrackerPointRecord {
  std::string feature;  ///< what the point belongs to: corner:A:top, pass:1:+, c-sweep, hole:ID ...
  std::string place;    ///< where the reflector was: TB1, A.side1, ...
  double x_mm = 0.0, y_mm = 0.0, z_mm = 0.0;
  std::optional<double> time_s;
  std::optional<int> integration_ms;  ///< none for a continuous measurement's points
};

/// A channel of a thermal monitoring run.
struct ThermalChannel {
  std::string name;
  std::string kind;  ///< temperature (degC), displacement (um), speed (rpm)
  std::string unit;
};
/// The values of every channel of a thermal run at one sample, in channel order; nullopt:
/// no valid reading (missing, never 0).
struct ThermalSample {
  std::int64_t index = 0;
  double time_s = 0.0;  ///< since the run's start
  std::vector<std::optional<double>> values;
  /// 0, then one more after each gap (a resumed run): the machine's state is not continuous
  /// from one segment to the next.
  int segment = 0;
};

struct RunInfo {
  Id id = 0;
  Id campaign_id = 0;
  std::string campaign_name;
  std::string machine_name;
  std::optional<Id> instrument_id;
  std::string kind, axis, name, plan_json, status, source, software_version, started_at;
  std::string value_unit = "um";
  std::optional<std::string> finished_at;
  std::int64_t target_count = 0;
  std::string operator_name;
  std::string compensation_json = "{}";  ///< as NewRun's
  /// What the run holds, in the unit its kind counts (measurementUnit): targets, circle
  /// points, probe steps, tracker points or thermal samples.
  std::int64_t measurement_count = 0;
  /// The process that recorded the run last (none: imported, or older than owners).
  std::optional<RunOwner> owner;
  /// Stored as running, but its process has gone: status reads interrupted.
  bool stale = false;
  std::string uuid;  ///< its identity in every store and in the plant archive (docs/archive.md)
};

/// What a run kind's measurement_count counts: targets, circle points, probe steps, tracker
/// points or thermal samples.
std::string measurementUnit(const std::string& kind);

struct TargetRecord {
  std::int64_t seq = 0;  ///< index in the plan's target sequence
  double target_mm = 0.0;
  int direction = 1;  ///< +1 up (positive approach), -1 down
  int cycle = 1;
  double measured_mm = 0.0;   ///< the position reached; the target for runs that measure another error
  double deviation_um = 0.0;  ///< error value in the run's value_unit (um, or urad for angular runs)
  std::optional<double> time_s;
  std::int64_t sample_count = 0;
  std::optional<double> sample_stddev_um;
  std::optional<double> air_temp_c, air_pressure_pa, humidity_pct, material_temp_c, air_index;
};

struct SampleRecord {
  std::int64_t device_seq = 0;
  std::int64_t device_time_ns = 0;
  double value = 0.0;
  int signal_pct = 0;
};

/// The newest samples of a run and where the next look starts.
struct SampleTail {
  std::vector<SampleRecord> samples;
  std::int64_t position = 0;
};

struct EnvironmentRecord {
  std::optional<std::int64_t> device_time_ns;
  std::optional<double> air_temp_c, air_pressure_pa, humidity_pct;
  std::optional<double> material_temp1_c, material_temp2_c, material_temp3_c;
};

struct ModelRecord {
  Id id = 0;
  std::string name, machine_json, method, provenance_json, software_version, created_at;
  std::vector<std::pair<std::string, std::string>> error_functions;  ///< (ISO name, function JSON)
};

/// Auxiliary channel values of one imported row, in the order of the run's channel names.
using ChannelRow = std::vector<std::optional<double>>;

class Store {
 public:
  /// Samples are inserted this many rows per statement: SQLite's per-statement cost, not
  /// the rows, dominates single-row inserts (docs/performance.md).
  static constexpr int kSampleRowsPerStatement = 32;

  /// Opens (creating it if `open` says so) and migrates. @throws StorageError
  explicit Store(const std::string& path, Open open = Open::kCreate);
  ~Store();
  Store(const Store&) = delete;
  Store& operator=(const Store&) = delete;

  Database& database() { return db_; }
  /// What messages call the store: its file, or what `setName` gave (the plant archive a
  /// copy stands for).
  const std::string& name() const { return name_.empty() ? db_.path() : name_; }
  void setName(std::string name) { name_ = std::move(name); }
  bool readOnly() const { return db_.readOnly(); }

  Id ensureMachine(const std::string& name, const std::string& description, const std::string& config_json);
  Id ensureInstrument(const InstrumentInfo& info);
  Id addCampaign(Id machine_id, const std::string& name);
  /// A new run; a running one is owned by this process (and logs that it started).
  Id addRun(const NewRun& run);
  /// Sets the status (completed, interrupted ...: the time it finished; completed is logged).
  void setRunStatus(Id run_id, const std::string& status);
  /// Takes an interrupted (or stale) acquired run over to continue it: status running, owned
  /// by this process, the resumption (and a stale owner's end) logged.
  /// @throws InputError when the run is imported, completed, or recorded by a live process
  RunInfo claimRun(Id run_id);
  /// Who works with this store (named in the events of runs it resumes); empty: not known.
  void setOperator(std::string name) { operator_ = std::move(name); }
  /// This process stops recording the run without storing its end (the archive would not
  /// take it): the run reads interrupted from now on. Nothing is written.
  void abandonRun(Id run_id) noexcept;
  /// Records that `instrument_id` took part in the run as `role` (once per instrument).
  void addRunInstrument(Id run_id, Id instrument_id, const std::string& role);
  /// Every instrument of the run, the main one first.
  std::vector<RunInstrument> runInstruments(Id run_id);
  void setRunOperator(Id run_id, const std::string& operator_name);

  /// Stores one captured target with its raw samples, atomically. @return target id
  Id addTarget(Id run_id, const TargetRecord& target, std::span<const SampleRecord> samples);
  /// Appends streamed samples in one transaction (one durable commit).
  void appendSamples(Id run_id, std::span<const SampleRecord> samples);
  void addEnvironment(Id run_id, const EnvironmentRecord& env);
  /// Stores one step of a probe run (all its channels) atomically.
  void addProbeStep(Id run_id, const ProbeStep& step);
  /// The steps of a probe run in order.
  std::vector<ProbeStep> probeSteps(Id run_id);

  /// Stores points of a circular test atomically.
  void addCirclePoints(Id run_id, std::span<const CirclePointRecord> points);
  /// The points of a circular test: CCW first, each direction in measuring order.
  std::vector<CirclePointRecord> circlePoints(Id run_id);

  /// Appends tracker points to a run (after the ones it has), in one transaction.
  void addTrackerPoints(Id run_id, std::span<const TrackerPointRecord> points);
  std::int64_t trackerPointCount(Id run_id);
  /// A run's tracker points in measuring order.
  std::vector<TrackerPointRecord> trackerPoints(Id run_id);

  /// Sets the channels of a thermal run (once, before its samples).
  void addThermalChannels(Id run_id, const std::vector<ThermalChannel>& channels);
  std::vector<ThermalChannel> thermalChannels(Id run_id);
  /// Appends samples of a thermal run in one transaction. @throws StorageError, InputError
  /// when a sample has another number of values than the run has channels
  void addThermalSamples(Id run_id, std::span<const ThermalSample> samples);
  std::vector<ThermalSample> thermalSamples(Id run_id);
  std::int64_t thermalSampleCount(Id run_id);

  /// Stores an imported run, its targets and auxiliary channels in one transaction.
  /// @return the new run id
  Id importRun(const NewRun& run, const std::vector<TargetRecord>& targets,
               const std::vector<std::string>& channel_names, const std::vector<ChannelRow>& channel_rows);

  std::vector<RunInfo> listRuns();
  /// The runs whose stored plan holds `text` (an imported file's digest), oldest first: found by
  /// the store, without loading every run and counting its readings.
  std::vector<RunInfo> runsWhosePlanHolds(const std::string& text);
  /// The runs of a campaign, oldest first. @throws InputError when there is no such campaign
  std::vector<Id> campaignRuns(Id campaign_id);
  /// Deletes a run and everything that belongs to it (targets, samples, points, channels,
  /// results, events, notes) in one transaction, and remembers its uuid (deleted_runs: a push
  /// to the plant archive tombstones it).
  /// @throws InputError when it does not exist or is being recorded
  void deleteRun(Id run_id);
  /// Deletes a campaign with all its runs, in one transaction.
  void deleteCampaign(Id campaign_id);
  void renameRun(Id run_id, const std::string& name);
  struct Note {
    std::string author, text, created_at;
  };
  void addNote(Id run_id, const std::string& author, const std::string& text);
  std::vector<Note> notes(Id run_id);
  /// A consistent copy of the whole archive at `path` (SQLite's online backup: others may
  /// write meanwhile). @throws StorageError, InputError when `path` exists
  void backupTo(const std::string& path);
  /// What is wrong with the archive, in words: PRAGMA integrity_check, foreign_key_check and
  /// rows that belong to no run. Empty: sound.
  std::vector<std::string> check();
  /// The description (config_json) of the machine a run was measured on.
  std::string machineDescriptionOfRun(Id run_id);
  /// @throws InputError when no such run exists
  RunInfo run(Id run_id);
  std::vector<TargetRecord> targets(Id run_id);
  std::vector<SampleRecord> samplesOfTarget(Id run_id, std::int64_t seq);
  /// Every raw sample of a run in recording order, one at a time (a 50 kHz capture does not
  /// fit in memory whole).
  void forEachSample(Id run_id, const std::function<void(const SampleRecord&)>& visit);
  /// The environment records of a run in recording order, after the first `skip`.
  std::vector<EnvironmentRecord> environment(Id run_id, std::size_t skip = 0);
  /// The newest raw samples of a run recorded after `after` (a position this returned
  /// before; 0: any), at most `newest`, in recording order: what a watcher shows of the
  /// stream. Reads only rows recorded since `after`.
  SampleTail sampleTail(Id run_id, std::int64_t after, std::size_t newest);
  std::int64_t sampleCount(Id run_id);
  std::vector<std::string> channelNames(Id run_id);
  /// The auxiliary channel values of a run's targets: one row per target in the order of
  /// targets(), one value per channel in the order of channelNames() (nullopt: none stored).
  std::vector<ChannelRow> channelRows(Id run_id);

  /// Stores a model and its error functions in one transaction. @return model id
  Id addModel(const ModelRecord& model);
  /// @throws InputError when no such model exists
  ModelRecord model(Id model_id);
  std::vector<ModelRecord> listModels();  ///< without the error functions

  /// The stored result identical to this one (processor, version, parameters, output), if any.
  std::optional<Id> sameResult(Id run_id, const std::string& processor, const std::string& version,
                               const std::string& parameters_json, const std::string& output_json);
  /// Stores a processing result; an identical one (processor, version, parameters, output)
  /// already stored is reused. Results are never overwritten. @return its id
  Id addResult(Id run_id, const std::string& processor, const std::string& version, const std::string& parameters_json,
               const std::string& output_json);
  struct Result {
    Id id = 0;
    std::string processor, processor_version, parameters_json, output_json, created_at;
  };
  /// Results stored for a run, oldest first.
  std::vector<Result> results(Id run_id);
  void logEvent(std::optional<Id> run_id, const std::string& level, const std::string& message);
  struct Event {
    std::string level, message, created_at;
  };
  std::vector<Event> events(Id run_id);

 private:
  /// Rows of `table` (a name of ours, never input) that belong to a run.
  std::int64_t rowsOfRun(const char* table, Id run_id);
  void insertSamples(Id run_id, std::span<const SampleRecord> samples);
  void setOwner(Id run_id, const RunOwner& owner);
  RunInfo withLiveness(RunInfo run) const;
  Id insertTarget(Id run_id, const TargetRecord& t, std::optional<std::int64_t> first_rowid,
                  std::optional<std::int64_t> last_rowid);

  Database db_;
  std::string archive_;  ///< the canonical path: which archive this process records in
  std::string operator_;
  std::string name_;
  std::unique_ptr<Statement> insert_sample_;
  std::unique_ptr<Statement> insert_samples_batch_;  // kSampleRowsPerStatement rows at once
  std::unique_ptr<Statement> insert_target_;
};

}  // namespace mtcal::storage
