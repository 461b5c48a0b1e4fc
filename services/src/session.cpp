#include "mtcal/services/session.h"

#include <fmt/format.h>

#include <algorithm>
#include <charconv>
#include <filesystem>

#include "mtcal/error.h"
#include "mtcal/services/plant.h"

namespace mtcal::services {

namespace {
class Silent final : public Observer {};
}  // namespace

Session::Session(SessionOptions options) : options_(std::move(options)) {}

Session::~Session() = default;

storage::Store& Session::store(Access access) {
  if (!store_ && isPlantAddress(options_.db_path)) {
    if (access != Access::kRead) requireLocalStore("");
    store_ = openPlantMirror(options_.db_path, observer(), options_.follow_writers);
  }
  if (!store_) {
    if (access == Access::kRead && !std::filesystem::exists(options_.db_path)) {
      throw InputError("no store '" + options_.db_path +
                       "': the file does not exist (a mistyped --db? runs and imports create a store, commands "
                       "that read do not)");
    }
    if (options_.read_only && access != Access::kRead)
      throw InputError("store '" + options_.db_path + "' is opened read-only: nothing can be added to it");
    const auto open = options_.read_only
                          ? (options_.follow_writers ? storage::Open::kReadOnlyFollowing : storage::Open::kReadOnly)
                      : access == Access::kRead ? storage::Open::kExisting
                                                : storage::Open::kCreate;
    store_ = std::make_unique<storage::Store>(options_.db_path, open);
    store_->setOperator(options_.operator_name);
  }
  if (access == Access::kRecord && !heartbeat_ && !store_->readOnly()) {
    heartbeat_ = std::make_unique<storage::Heartbeat>(options_.db_path);
  }
  return *store_;
}

void Session::discardNewStore() {
  if (store_ && (!store_->listRuns().empty() || !store_->listModels().empty())) return;  // something came: kept
  heartbeat_.reset();
  store_.reset();
  for (const char* suffix : {"", "-wal", "-shm"}) {
    std::error_code ignored;
    std::filesystem::remove(options_.db_path + suffix, ignored);
  }
}

void Session::requireLocalStore(const std::string& command) const {
  if (isPlantAddress(options_.db_path))
    throw InputError("--db " + options_.db_path + " is the plant archive: it is read, never written; " +
                     (command.empty() ? std::string("a command that adds") : "`mtcal " + command + "`") +
                     " works on a store of your own (mtcal archive pull RUN --from ADDRESS brings runs into one; the "
                     "archive is backed up with pg_dump, docs/archive.md)");
}

std::optional<storage::Id> Session::storeResult(storage::Id run_id, const std::string& processor,
                                                const std::string& version, const std::string& parameters_json,
                                                const std::string& output_json) {
  auto& s = store();
  if (isPlantAddress(options_.db_path)) return std::nullopt;  // the plant archive is read: nothing to say each time
  if (s.readOnly()) {  // stored already (the same analysis of the same data), or said not to be
    if (const auto same = s.sameResult(run_id, processor, version, parameters_json, output_json)) return same;
    observer().onMessage("warning", "store '" + options_.db_path + "' is read-only: the " + processor +
                                        " result of run " + std::to_string(run_id) + " is shown, not stored");
    return std::nullopt;
  }
  return s.addResult(run_id, processor, version, parameters_json, output_json);
}

Observer& Session::observer() const {
  static Silent silent;
  return options_.observer ? *options_.observer : silent;
}

Operator& Session::person(const std::string& why) const {
  if (!options_.person) throw InputError("nobody to ask: " + why);
  return *options_.person;
}

storage::Id Session::instrument(const drivers::DeviceInfo& info) {
  return store().ensureInstrument({info.kind, info.model, info.serial, info.firmware, info.uri});
}

void Session::recordRun(storage::Id run_id,
                        const std::vector<std::pair<drivers::DeviceInfo, std::string>>& instruments) {
  auto& s = store();
  if (!options_.operator_name.empty()) s.setRunOperator(run_id, options_.operator_name);
  for (const auto& [info, role] : instruments) s.addRunInstrument(run_id, instrument(info), role);
}

Progress ProgressClock::at(std::size_t done, std::string what) const {
  Progress p{done, total_, std::move(what), std::nullopt};
  const double elapsed_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  if (done > done_before_ && done <= total_) {
    p.eta_s = elapsed_s / static_cast<double>(done - done_before_) * static_cast<double>(total_ - done);
  }
  return p;
}

std::vector<storage::Id> resolveRuns(storage::Store& store, const std::vector<std::string>& sources,
                                     const std::vector<std::string>& kinds, std::vector<storage::Id>* given_twice) {
  std::vector<storage::Id> runs;
  auto add = [&](storage::Id id) {
    if (std::find(runs.begin(), runs.end(), id) == runs.end())
      runs.push_back(id);
    else if (given_twice)
      given_twice->push_back(id);
  };
  for (const auto& source : sources) {
    const bool campaign = !source.empty() && (source[0] == 'c' || source[0] == 'C');
    const std::string digits = campaign ? source.substr(1) : source;
    storage::Id id = 0;
    const auto [ptr, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), id);
    if (digits.empty() || ec != std::errc() || ptr != digits.data() + digits.size() || id <= 0) {
      throw InputError("'" + source + "' is neither a run id nor cN (campaign N)" +
                       (ec == std::errc() && ptr == digits.data() + digits.size() && id == 0
                            ? std::string(": runs and campaigns are numbered from 1")
                            : std::string()));
    }
    if (!campaign) {
      add(id);
      continue;
    }
    bool any = false;
    std::vector<std::string> others;  // its runs of those kinds that did not complete, with their status
    for (const auto& r : store.listRuns()) {
      if (r.campaign_id != id || std::find(kinds.begin(), kinds.end(), r.kind) == kinds.end()) continue;
      if (r.status == storage::run_status::kCompleted || r.status == storage::run_status::kImported) {
        add(r.id);
        any = true;
      } else {
        others.push_back(fmt::format("run {} is {}", r.id, r.status));
      }
    }
    if (!any) {
      store.campaignRuns(id);  // a campaign that does not exist is named as such
      throw InputError(fmt::format("campaign {} has no completed {} run{}", id, fmt::join(kinds, " or "),
                                   others.empty() ? std::string() : fmt::format(" ({})", fmt::join(others, ", "))));
    }
  }
  return runs;
}

}  // namespace mtcal::services
