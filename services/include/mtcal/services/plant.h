#pragma once
// The plant archive (docs/archive.md): pushing a store's runs to the PostgreSQL archive every
// station shares, listing what it holds and pulling runs back into a store.

#include <chrono>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>
#include <vector>

#include "mtcal/archive/plant_archive.h"
#include "mtcal/services/session.h"

namespace mtcal::services {

struct PlantPushRequest {
  std::string archive;  ///< libpq address: postgresql://host/db?sslmode=verify-full, service=plant ...
  std::string station;  ///< empty: the station role's name, or this computer's host name
};
struct PlantPushResult {
  std::string archive;  ///< where it went: user@host:port/database
  std::string station;
  archive::PushSummary summary;
  /// How many runs had each outcome (new, changed, unchanged, deleted, recording).
  std::size_t count(const std::string& outcome) const;
  nlohmann::json document() const;
};
/// Pushes every finished or interrupted run of the session's store (progress: one step per run).
/// @throws InputError, StorageError
PlantPushResult pushToPlant(Session& session, const PlantPushRequest& request);

struct PlantInitResult {
  std::string archive, archive_uuid;
  int schema_version = 0;
  int schema_version_before = 0;  ///< 0: the database held no archive
  nlohmann::json document() const;
};
/// Makes the plant archive's schema in an empty database, or migrates it to this mtcal's
/// version (the administrator: the database's owner). @throws InputError, StorageError
PlantInitResult initPlant(const std::string& address);

struct PlantRunList {
  std::string archive;
  std::vector<archive::ArchivedRun> runs;
  nlohmann::json document() const;
};
/// The runs the archive holds (newest version each); `machine`: of machines whose name contains it.
PlantRunList listPlant(const std::string& address, const std::string& machine = {});

/// Every version of a run of the archive (its number or uuid), oldest first.
PlantRunList plantRunHistory(const std::string& address, const std::string& run);

struct PlantPullResult {
  std::string archive;
  std::vector<archive::PulledRun> runs;
  std::vector<archive::PulledModel> models;
  nlohmann::json document() const;
};
/// Brings a run (its archive number or uuid), a campaign (cN) or a model (mN) into the session's store.
PlantPullResult pullFromPlant(Session& session, const std::string& address, const std::string& what);

/// Whether --db names the plant archive (postgresql://..., postgres://..., service=NAME) rather
/// than a store's file.
bool isPlantAddress(const std::string& db);
/// The plant archive as a store that commands read: a copy of its runs (newest versions,
/// numbered as in the archive) kept in the user's cache ($XDG_CACHE_HOME/mtcal, else
/// ~/.cache/mtcal), brought up to date now (only what changed is copied), opened read-only.
/// @throws InputError, StorageError
std::unique_ptr<storage::Store> openPlantMirror(const std::string& address, Observer& observer, bool follow_writers);

/// Brings the copy openPlantMirror reads up to date every `period`, in a thread of its own,
/// until destroyed: a running dashboard (opened following writers) shows what stations pushed
/// after it started. A refresh that fails (the server unreachable) leaves the copy as it was
/// and is logged as a warning once, until a refresh succeeds again.
class PlantMirrorRefresher {
 public:
  PlantMirrorRefresher(std::string address, std::chrono::seconds period);
  ~PlantMirrorRefresher();
  PlantMirrorRefresher(const PlantMirrorRefresher&) = delete;
  PlantMirrorRefresher& operator=(const PlantMirrorRefresher&) = delete;

 private:
  std::string address_;
  std::chrono::seconds period_;
  std::mutex mutex_;
  std::condition_variable wake_;
  bool stopping_ = false;
  std::thread thread_;
};

}  // namespace mtcal::services
