#include "mtcal/services/plant.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <functional>

#include "mtcal/archive/run_content.h"
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
    if (!r.note.empty()) j["note"] = r.note;
    if (r.local_id != 0) j["run_id"] = r.local_id;
    if (!r.sha256.empty()) j["sha256"] = r.sha256;
    runs.push_back(std::move(j));
  }
  return {{"schema_version", 1}, {"archive", archive},       {"station", station},
          {"runs", runs},        {"models", summary.models}, {"rows_sent", summary.rows_sent}};
}

PlantPushResult pushToPlant(Session& session, const PlantPushRequest& request) {
  session.requireLocalStore("archive push");
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
          {"sha256", r.sha256},
          {"pushed_by", r.pushed_by},
          {"parts_sent", r.parts_sent}};
}
}  // namespace

nlohmann::json PlantRunList::document() const {
  nlohmann::json list = nlohmann::json::array();
  for (const auto& r : runs) list.push_back(archivedDocument(r));
  return {{"schema_version", 1}, {"archive", archive}, {"runs", list}};
}

namespace {
/// A list of the archive's runs that `fetch` reads over a connection of its own.
PlantRunList plantRunList(const std::string& address, const std::string& application,
                          const std::function<std::vector<archive::ArchivedRun>(archive::Connection&)>& fetch) {
  archive::Connection connection(address, application);
  return {connection.where(), fetch(connection)};
}
}  // namespace

PlantRunList listPlant(const std::string& address, const std::string& machine) {
  return plantRunList(address, "mtcal list", [&](archive::Connection& c) { return archive::listArchive(c, machine); });
}

PlantRunList plantRunHistory(const std::string& address, const std::string& run) {
  return plantRunList(address, "mtcal history", [&](archive::Connection& c) { return archive::runHistory(c, run); });
}

nlohmann::json PlantPullResult::document() const {
  nlohmann::json list = nlohmann::json::array();
  for (const auto& r : runs) {
    auto j = archivedDocument(r.archived);
    j["run_id"] = r.local_id;
    j["already_here"] = r.already_here;
    list.push_back(std::move(j));
  }
  nlohmann::json models_list = nlohmann::json::array();
  for (const auto& m : models)
    models_list.push_back({{"id", m.id},
                           {"uuid", m.uuid},
                           {"name", m.name},
                           {"station", m.station},
                           {"model_id", m.local_id},
                           {"already_here", m.already_here}});
  return {{"schema_version", 1}, {"archive", archive}, {"runs", list}, {"models", models_list}};
}

PlantPullResult pullFromPlant(Session& session, const std::string& address, const std::string& what) {
  auto& store = session.store(Access::kCreate);
  archive::Connection connection(address, "mtcal pull");
  PlantPullResult result;
  result.archive = connection.where();
  auto pulled = archive::pull(store, connection, what);
  result.runs = std::move(pulled.runs);
  result.models = std::move(pulled.models);
  return result;
}

bool isPlantAddress(const std::string& db) {
  return db.starts_with("postgresql://") || db.starts_with("postgres://") || db.starts_with("service=");
}

std::unique_ptr<storage::Store> openPlantMirror(const std::string& address, Observer& observer, bool follow_writers) {
  archive::Connection connection(address, "mtcal read");
  const char* cache = std::getenv("XDG_CACHE_HOME");
  const char* home = std::getenv("HOME");
  const std::filesystem::path folder = cache != nullptr && *cache != '\0'
                                           ? std::filesystem::path(cache) / "mtcal"
                                           : (home != nullptr ? std::filesystem::path(home) / ".cache" / "mtcal"
                                                              : std::filesystem::temp_directory_path() / "mtcal-cache");
  std::filesystem::create_directories(folder);
  archive::Sha256 name;
  name.update(connection.where());
  const std::string path = (folder / ("plant-" + name.hex().substr(0, 16) + ".sqlite")).string();
  archive::MirrorSummary summary;
  {
    storage::Store writable(path);
    summary = archive::mirror(writable, connection);
  }
  spdlog::info("plant archive {}: {} runs ({} runs and {} models copied now) read from its copy {}", connection.where(),
               summary.runs, summary.runs_copied, summary.models_copied, path);
  for (const auto& why : summary.refused) observer.onMessage("warning", why + " (left out of what is read)");
  auto store = std::make_unique<storage::Store>(
      path, follow_writers ? storage::Open::kReadOnlyFollowing : storage::Open::kReadOnly);
  store->setName("the plant archive " + connection.where());
  return store;
}

}  // namespace mtcal::services
