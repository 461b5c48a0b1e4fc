#pragma once
// The plant archive: the runs of many local stores in one PostgreSQL database (docs/archive.md).
// A push sends every finished or interrupted run a store holds that the archive does not
// have as it is now: a new run, or a new version of a changed one (a deleted one: a
// tombstone). Each run goes in one transaction, so a push cut off is resumed by the next,
// and a run's SHA-256 shows whether it changed. A pull brings runs back into a local store.

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "mtcal/archive/postgres.h"
#include "mtcal/storage/store.h"

namespace mtcal::archive {

struct PushOptions {
  /// The station's name, recorded with every row pushed. A station's role (a member of
  /// mtcal_station) pushes as itself: empty or its name. Another role: empty is the host name.
  std::string station;
  std::string software_version;  ///< of the pushing mtcal
  /// Called after each run with how far the push is (runs done, runs in all) and what was done.
  std::function<void(std::size_t done, std::size_t total, const std::string& what)> progress;
};

/// What a push did with one run.
struct PushedRun {
  storage::Id local_id = 0;     ///< 0: a tombstone of a run the store no longer holds
  std::int64_t archive_id = 0;  ///< the archive's number of the run (0: not known, a run still recording)
  std::string uuid;
  /// new, changed, unchanged, deleted, recording (not pushed: still being recorded), conflict
  /// (not pushed: the archive's version is not the one this store last pushed or pulled, or
  /// the run is another station's; `note` says which)
  std::string outcome;
  std::string note;
  int version = 0;  ///< the archive's version now (0: recording)
  std::int64_t rows_sent = 0;
  std::string sha256;
};
struct PushSummary {
  std::string station;  ///< pushed as
  /// The station's plant (a role in mtcal_plant); empty: none, its rows are read by every reader
  std::string plant;
  std::vector<std::string> warnings;  ///< for people: what the administrator should look at
  std::vector<PushedRun> runs;
  std::vector<std::string> models;  ///< uuids of the models sent (models never change: each is sent once)
  std::int64_t rows_sent = 0;
};

/// Pushes the store's runs (and its deletions) to the archive; migrates the archive's schema
/// first. @throws StorageError when the archive cannot be reached or a run fails (the runs
/// pushed before it stay pushed)
PushSummary push(storage::Store& store, Connection& archive, const PushOptions& options);

/// A run as the archive lists it: its newest version.
struct ArchivedRun {
  std::int64_t id = 0;  ///< the archive's number
  std::string uuid, machine, campaign, kind, axis, name, status, station, pushed_at, started_at, sha256;
  std::int64_t campaign_id = 0;
  int version = 0;
  bool deleted = false;   ///< its newest version is a tombstone
  std::string pushed_by;  ///< the database role that pushed the version
  /// The station that first pushed the run (`station`: the version's): the run is its plant's
  std::string first_station;
  std::vector<std::string> parts_sent;  ///< the parts whose rows came with this version
};
/// The runs of the archive, newest version each, in the archive's order; `machine`: only
/// those of machines whose name contains it. @throws StorageError
std::vector<ArchivedRun> listArchive(Connection& archive, const std::string& machine = {});

/// Every version of a run (its archive number or uuid), oldest first. @throws InputError
std::vector<ArchivedRun> runHistory(Connection& archive, const std::string& run);

struct PulledRun {
  ArchivedRun archived;
  storage::Id local_id = 0;
  bool already_here = false;  ///< the store held the same run (same uuid and SHA-256): nothing written
};
struct PulledModel {
  std::int64_t id = 0;  ///< the archive's number
  std::string uuid, name, station;
  storage::Id local_id = 0;
  bool already_here = false;
};
struct PullResult {
  std::vector<PulledRun> runs;
  std::vector<PulledModel> models;
};
/// Brings a run (its archive number, or its uuid; "12@2": its version 2), a campaign ("cN":
/// each of its runs not deleted) or a model ("mN") into the store; a run's newest version, each in one transaction,
/// its SHA-256 checked there. @throws InputError when there is no such run or model, the run
/// was deleted, or the store holds another version of it
/// @param open_store gives the store, called once what to bring is known: a failed look-up
///   creates no store
PullResult pull(const std::function<storage::Store&()>& open_store, Connection& archive, const std::string& what);

/// What a mirror's synchronisation did.
struct MirrorSummary {
  std::size_t runs_copied = 0, models_copied = 0;  ///< brought in now (new, or a newer version)
  std::size_t runs = 0;                            ///< runs it holds now
  std::vector<std::string> refused;                ///< runs left out, and why (altered in the archive)
};
/// Makes `store` a copy of the archive's runs as they are now (newest version each, deleted
/// ones left out), numbered as in the archive: what read-only commands read when given the
/// archive's address (--db postgresql://...). Copies only runs it does not hold as they are.
MirrorSummary mirror(storage::Store& store, Connection& archive);

}  // namespace mtcal::archive
