#pragma once
// What the archive holds: its runs listed, one run shown whole.

#include <cstdint>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "mtcal/services/session.h"

namespace mtcal::services {

/// Why a stale run (status running, its process gone) reads interrupted; empty for others.
std::string staleNote(const storage::RunInfo& run);

/// A run as `mtcal runs --json` lists it.
nlohmann::json runDocument(const storage::RunInfo& run);

/// The list `mtcal runs --json` prints: {"schema_version", "runs": [...]}.
nlohmann::json runListDocument(const std::vector<storage::RunInfo>& runs);

/// Which runs `mtcal runs` lists, and in which order.
struct RunFilter {
  std::string machine, kind, axis, status;  ///< empty: any; the machine matches a part of its name
  std::optional<storage::Id> campaign;
  std::string since, until;  ///< started on or after / before the end of (UTC, 2026-11-24 or a whole timestamp)
  std::string sort = "id";   ///< id, started, machine, kind, axis, status, name
  bool descending = false;
  /// Whether it leaves some runs out.
  bool filters() const {
    return !machine.empty() || !kind.empty() || !axis.empty() || !status.empty() || campaign || !since.empty() ||
           !until.empty();
  }
};

/// The runs the filter lets through, in its order. @throws InputError for an unknown sort key
std::vector<storage::RunInfo> listRuns(Session& session, const RunFilter& filter = {});

/// What a command names in the archive: a run (12), a campaign (c3) or a model (m2).
struct ArchiveItem {
  std::optional<storage::Id> run, campaign, model;
  /// `accepted`: the kinds the command takes, of "rcm". @throws InputError when `text` is none of them
  static ArchiveItem parse(const std::string& text, std::string_view accepted = "rc");
};
/// A model's id as given on a command line: m2 or 2 (> 0); an InputError names the text otherwise.
storage::Id modelIdOf(const std::string& text);

/// The runs that deleting `what` removes (a campaign: all of them). @throws InputError when
/// it does not exist
std::vector<storage::RunInfo> runsOf(Session& session, const ArchiveItem& what);
/// Deletes a run or a campaign with everything that belongs to it, in one transaction.
/// @throws InputError when a run of it is being recorded
void deleteRuns(Session& session, const ArchiveItem& what);
void renameRun(Session& session, storage::Id run_id, const std::string& name);
/// A note on a run, by the session's operator.
void noteRun(Session& session, storage::Id run_id, const std::string& text);
/// A consistent copy of the archive (while a run records). @throws InputError when `path` exists
void backupArchive(Session& session, const std::string& path);
/// What is wrong with the archive, in words (empty: sound).
std::vector<std::string> checkArchive(Session& session);

/// One run whole: what `mtcal show` tells.
struct RunDetail {
  storage::RunInfo run;
  std::vector<storage::TargetRecord> targets;
  std::vector<storage::Store::Event> events;
  std::vector<storage::RunInstrument> instruments;  ///< every instrument that measured, the main one first
  std::vector<std::string> channels;                ///< auxiliary channels of imported data
  std::int64_t raw_samples = 0;                     ///< acquired runs
  std::int64_t tracker_points = 0;                  ///< gantry runs
  std::int64_t thermal_samples = 0;                 ///< thermal runs
  std::vector<storage::ThermalChannel> thermal_channels;
  std::vector<storage::Store::Result> results;  ///< stored analyses, oldest first
  std::vector<storage::Store::Note> notes;
  nlohmann::json document() const;
};
/// @throws InputError when there is no such run
RunDetail showRun(Session& session, storage::Id run_id);

/// What a watcher of a run (the dashboard's live page) has not seen yet.
/// What a watcher has seen of a run so far (all zero: nothing).
struct ProgressSeen {
  std::size_t captures = 0, events = 0, environment = 0;
  std::int64_t stream_position = 0;  ///< RunProgress::stream_position of the last look
};
struct RunProgress {
  /// A look shows at most this many of the newest raw samples, every n-th of the newest
  /// kStreamSamples: the reading stream for display, however fast it is recorded.
  static constexpr std::size_t kStreamSamples = 2000, kStreamPoints = 200;
  storage::RunInfo run;
  std::size_t planned = 0;   ///< the plan's measurements (linear runs: targets); 0 when not known
  std::size_t captures = 0;  ///< stored so far
  std::vector<storage::TargetRecord> new_captures;          ///< after those seen
  std::vector<storage::Store::Event> new_events;            ///< after those seen
  std::vector<storage::EnvironmentRecord> new_environment;  ///< after those seen
  std::vector<storage::SampleRecord> stream;                ///< recorded since the last look, decimated (see above)
  std::int64_t stream_position = 0;                         ///< for the next look
  bool finished() const;                                    ///< not running any more
};
/// @throws InputError when there is no such run
RunProgress runProgress(Session& session, storage::Id run_id, const ProgressSeen& seen);

}  // namespace mtcal::services
