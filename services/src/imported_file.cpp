#include "imported_file.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>

#include "mtcal/acquisition/csv.h"
#include "mtcal/archive/run_content.h"
#include "mtcal/error.h"

namespace mtcal::services::detail {

acquisition::StoreWhenNeeded storeWhenNeeded(Session& session) {
  return acquisition::StoreWhenNeeded([&session]() -> storage::Store& { return session.store(Access::kCreate); });
}

ImportedFile readImportedFile(const std::string& path) {
  std::ifstream in = acquisition::openInputFile(path);
  std::string bytes;
  std::array<char, 1 << 16> buffer{};
  while (in.read(buffer.data(), buffer.size()) || in.gcount() > 0)
    bytes.append(buffer.data(), static_cast<std::size_t>(in.gcount()));
  if (in.bad()) throw InputError(path + ": cannot read file: " + std::strerror(errno));  // not the end: an error
  ImportedFile file;
  file.bytes.str(std::move(bytes));
  std::error_code error;
  if (std::filesystem::is_regular_file(path, error)) {
    archive::Sha256 digest;
    digest.update(file.bytes.view());
    file.sha256 = digest.hex();
  }
  return file;
}

std::vector<std::string> importedBefore(storage::Store& store, const std::string& sha256, const std::string& path,
                                        const std::vector<storage::Id>& new_ids) {
  if (sha256.empty()) return {};
  // The earlier imports, each a campaign of its own: its runs (a file of several errors has one
  // per error).
  std::map<storage::Id, std::vector<storage::RunInfo>> imports;
  for (auto& run : store.runsWhosePlanHolds(sha256)) {
    if (std::find(new_ids.begin(), new_ids.end(), run.id) != new_ids.end()) continue;
    const auto plan = nlohmann::json::parse(run.plan_json, nullptr, false);
    if (plan.is_object() && plan.value("imported_sha256", std::string()) == sha256)
      imports[run.campaign_id].push_back(std::move(run));
  }
  if (imports.empty()) return {};
  constexpr std::size_t kNamed = 5;
  std::vector<std::string> named;
  for (const auto& [campaign, runs] : imports) {
    if (named.size() == kNamed) break;
    if (runs.size() == 1) {
      named.push_back(fmt::format("run {} ('{}')", runs.front().id, runs.front().name));
    } else {
      std::vector<storage::Id> ids;
      for (const auto& r : runs) ids.push_back(r.id);
      named.push_back(fmt::format("runs {} (c{})", fmt::join(ids, ", "), campaign));
    }
  }
  const std::size_t more = imports.size() - named.size();
  const std::string file = std::filesystem::path(path).filename().string();
  const std::string holders = new_ids.size() == 1 ? fmt::format("run {} holds", new_ids.front())
                                                  : fmt::format("runs {} hold", fmt::join(new_ids, ", "));
  // Every import makes a campaign of its own: deleting it removes this import's runs only.
  return {fmt::format(
      "{}: the same file was imported before, as {}{}: {} it again (mtcal delete c{} removes this "
      "import)",
      file, fmt::join(named, ", "), more ? fmt::format(" and {} more import{}", more, more > 1 ? "s" : "") : "",
      holders, store.run(new_ids.front()).campaign_id)};
}

}  // namespace mtcal::services::detail
