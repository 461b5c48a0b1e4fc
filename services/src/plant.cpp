#include "mtcal/services/plant.h"

#include <fcntl.h>
#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <sys/file.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <functional>
#include <regex>
#include <set>

#include "mtcal/archive/plant_schema.h"
#include "mtcal/archive/run_content.h"
#include "mtcal/error.h"
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
    if (r.archive_id != 0) j["archive_id"] = r.archive_id;
    if (!r.sha256.empty()) j["sha256"] = r.sha256;
    runs.push_back(std::move(j));
  }
  return {{"schema_version", 1},
          {"archive", archive},
          {"station", station},
          {"plant", summary.plant.empty() ? nlohmann::json() : nlohmann::json(summary.plant)},
          {"runs", runs},
          {"models", summary.models},
          {"rows_sent", summary.rows_sent}};
}

nlohmann::json PlantInitResult::document() const {
  return {{"schema_version", 1},
          {"archive", archive},
          {"archive_uuid", archive_uuid},
          {"archive_schema_version", schema_version},
          {"archive_schema_version_before", schema_version_before}};
}

PlantInitResult initPlant(const std::string& address) {
  archive::Connection connection(address, "mtcal init");
  PlantInitResult result;
  result.archive = connection.where();
  result.schema_version_before = archive::migratePlant(connection);
  result.schema_version = archive::plantSchemaVersion();
  result.archive_uuid = archive::archiveUuid(connection);
  return result;
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
  for (const auto& warning : result.summary.warnings) session.observer().onMessage("warning", warning);
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
          {"first_station", r.first_station},
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
  archive::Connection connection(address, "mtcal pull");
  PlantPullResult result;
  result.archive = connection.where();
  const bool new_store = !std::filesystem::exists(session.options().db_path);
  archive::PullResult pulled;
  try {
    pulled =
        archive::pull([&session]() -> storage::Store& { return session.store(Access::kCreate); }, connection, what);
  } catch (...) {
    if (new_store) session.discardNewStore();  // a pull that brought nothing leaves no store behind
    throw;
  }
  result.runs = std::move(pulled.runs);
  result.models = std::move(pulled.models);
  return result;
}

bool isPlantAddress(const std::string& db) {
  if (db.starts_with("postgresql://") || db.starts_with("postgres://")) return true;
  // libpq's keyword = value form: "service=plant", "host=/run/postgresql dbname=plant".
  static const std::regex kKeywordValue(R"(^\s*(service|host|hostaddr|port|dbname|user|sslmode)\s*=.*)");
  return std::regex_match(db, kKeywordValue);
}

namespace {

/// Brings the user's copy of the plant archive up to date; returns its file. One process at a
/// time: a dashboard's refresh and a command reading the archive queue on a lock file.
std::string updatePlantMirror(archive::Connection& connection, Observer& observer) {
  const char* cache = std::getenv("XDG_CACHE_HOME");
  const char* home = std::getenv("HOME");
  const std::filesystem::path folder = cache != nullptr && *cache != '\0'
                                           ? std::filesystem::path(cache) / "mtcal"
                                           : (home != nullptr ? std::filesystem::path(home) / ".cache" / "mtcal"
                                                              : std::filesystem::temp_directory_path() / "mtcal-cache");
  // Only its user reads the copy: it holds what the role may read, which others may not.
  std::filesystem::create_directories(folder);
  std::filesystem::permissions(folder, std::filesystem::perms::owner_all, std::filesystem::perm_options::replace);
  archive::Sha256 name;
  name.update(connection.where());
  const std::string path = (folder / ("plant-" + name.hex().substr(0, 16) + ".sqlite")).string();
  struct Lock {
    int fd;
    ~Lock() {
      if (fd >= 0) ::close(fd);  // releases the lock
    }
  } lock{::open((path + ".lock").c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0600)};
  if (lock.fd < 0 || ::flock(lock.fd, LOCK_EX) != 0)
    throw StorageError(fmt::format("the copy of the plant archive {}: cannot lock {}.lock: {}", connection.where(),
                                   path, std::strerror(errno)));
  archive::MirrorSummary summary;
  {
    storage::Store writable(path);
    for (const char* suffix : {"", "-wal", "-shm"}) {
      std::error_code ignored;  // the log files come and go
      std::filesystem::permissions(path + suffix,
                                   std::filesystem::perms::owner_read | std::filesystem::perms::owner_write,
                                   std::filesystem::perm_options::replace, ignored);
    }
    summary = archive::mirror(writable, connection);
  }
  spdlog::info("plant archive {}: {} runs ({} runs and {} models copied now) read from its copy {}", connection.where(),
               summary.runs, summary.runs_copied, summary.models_copied, path);
  for (const auto& why : summary.refused) observer.onMessage("warning", why + " (left out of what is read)");
  return path;
}

/// Says a refresh's warnings in the log, each once (a run refused stays refused).
class LoggingObserver final : public Observer {
 public:
  void onMessage(const std::string& level, const std::string& text) override {
    if (!said_.insert(text).second) return;
    if (level == "warning")
      spdlog::warn("{}", text);
    else
      spdlog::info("{}", text);
  }

 private:
  std::set<std::string> said_;
};

}  // namespace

std::unique_ptr<storage::Store> openPlantMirror(const std::string& address, Observer& observer, bool follow_writers) {
  archive::Connection connection(address, "mtcal read");
  const std::string path = updatePlantMirror(connection, observer);
  auto store = std::make_unique<storage::Store>(
      path, follow_writers ? storage::Open::kReadOnlyFollowing : storage::Open::kReadOnly);
  store->setName("the plant archive " + connection.where());
  return store;
}

PlantMirrorRefresher::PlantMirrorRefresher(std::string address, std::chrono::seconds period)
    : address_(std::move(address)), period_(period) {
  thread_ = std::thread([this] {
    LoggingObserver log;
    bool failing = false;  // said once, not at every period, until a refresh succeeds again
    std::unique_lock lock(mutex_);
    while (!wake_.wait_for(lock, period_, [this] { return stopping_; })) {
      lock.unlock();
      try {
        archive::Connection connection(address_, "mtcal read");
        updatePlantMirror(connection, log);
        if (failing) spdlog::warn("the copy of the plant archive is up to date again");
        failing = false;
      } catch (const std::exception& e) {
        if (!failing)
          spdlog::warn(
              "the copy of the plant archive is not brought up to date (it is shown as it was; tried again "
              "every {} s): {}",
              period_.count(), e.what());
        failing = true;
      }
      lock.lock();
    }
  });
}

PlantMirrorRefresher::~PlantMirrorRefresher() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
  thread_.join();
}

}  // namespace mtcal::services
