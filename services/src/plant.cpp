#include "mtcal/services/plant.h"

#include <algorithm>

#include "mtcal/services/version.h"

namespace mtcal::services {

std::size_t PlantPushResult::count(const std::string& outcome) const {
  return static_cast<std::size_t>(std::count_if(summary.runs.begin(), summary.runs.end(),
                                                [&](const archive::PushedRun& r) { return r.outcome == outcome; }));
}

nlohmann::json PlantPushResult::document() const {
  nlohmann::json runs = nlohmann::json::array();
  for (const auto& r : summary.runs) {
    nlohmann::json j = {{"uuid", r.uuid}, {"outcome", r.outcome}, {"version", r.version}, {"rows_sent", r.rows_sent}};
    if (r.local_id != 0) j["run_id"] = r.local_id;
    if (!r.sha256.empty()) j["sha256"] = r.sha256;
    runs.push_back(std::move(j));
  }
  return {{"schema_version", 1},
          {"archive", archive},
          {"station", station},
          {"runs", runs},
          {"rows_sent", summary.rows_sent}};
}

PlantPushResult pushToPlant(Session& session, const PlantPushRequest& request) {
  PlantPushResult result;
  auto& store = session.store(Access::kRead);
  archive::Connection connection(request.archive, "mtcal push");
  result.archive = connection.where();
  archive::PushOptions options;
  options.station = request.station;
  options.software_version = kVersion;
  options.progress = [&session](std::size_t done, std::size_t total, const std::string& what) {
    session.observer().onProgress({done, total, what, std::nullopt});
  };
  result.summary = archive::push(store, connection, options);
  result.station = result.summary.station;
  return result;
}

namespace {
nlohmann::json archivedDocument(const archive::ArchivedRun& r) {
  return {{"id", r.id},
          {"uuid", r.uuid},
          {"machine", r.machine},
          {"campaign", r.campaign},
          {"campaign_id", r.campaign_id},
          {"kind", r.kind},
          {"axis", r.axis},
          {"name", r.name},
          {"status", r.status},
          {"started_at", r.started_at},
          {"version", r.version},
          {"station", r.station},
          {"pushed_at", r.pushed_at},
          {"deleted", r.deleted},
          {"sha256", r.sha256}};
}
}  // namespace

nlohmann::json PlantRunList::document() const {
  nlohmann::json list = nlohmann::json::array();
  for (const auto& r : runs) list.push_back(archivedDocument(r));
  return {{"schema_version", 1}, {"archive", archive}, {"runs", list}};
}

PlantRunList listPlant(const std::string& address, const std::string& machine) {
  archive::Connection connection(address, "mtcal list");
  PlantRunList list;
  list.archive = connection.where();
  list.runs = archive::listArchive(connection, machine);
  return list;
}

nlohmann::json PlantPullResult::document() const {
  nlohmann::json list = nlohmann::json::array();
  for (const auto& r : runs) {
    auto j = archivedDocument(r.archived);
    j["run_id"] = r.local_id;
    j["already_here"] = r.already_here;
    list.push_back(std::move(j));
  }
  return {{"schema_version", 1}, {"archive", archive}, {"runs", list}};
}

PlantPullResult pullFromPlant(Session& session, const std::string& address, const std::string& what) {
  auto& store = session.store(Access::kCreate);
  archive::Connection connection(address, "mtcal pull");
  PlantPullResult result;
  result.archive = connection.where();
  result.runs = archive::pull(store, connection, what);
  return result;
}

}  // namespace mtcal::services
