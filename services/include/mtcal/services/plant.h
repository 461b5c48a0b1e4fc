#pragma once
// The plant archive (docs/archive.md): pushing a store's runs to the PostgreSQL archive every
// station shares, listing what it holds and pulling runs back into a store.

#include <nlohmann/json.hpp>
#include <string>
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

struct PlantRunList {
  std::string archive;
  std::vector<archive::ArchivedRun> runs;
  nlohmann::json document() const;
};
/// The runs the archive holds (newest version each); `machine`: of machines whose name contains it.
PlantRunList listPlant(const std::string& address, const std::string& machine = {});

struct PlantPullResult {
  std::string archive;
  std::vector<archive::PulledRun> runs;
  nlohmann::json document() const;
};
/// Brings a run (its archive number or uuid) or a campaign (cN) into the session's store.
PlantPullResult pullFromPlant(Session& session, const std::string& address, const std::string& what);

}  // namespace mtcal::services
