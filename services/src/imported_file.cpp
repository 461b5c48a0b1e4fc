#include "imported_file.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "mtcal/archive/run_content.h"

namespace mtcal::services::detail {

std::string fileSha256(const std::string& path) {
  // A pipe or a FIFO is read once, by the import: not hashed (nothing to compare it with later).
  std::error_code error;
  if (!std::filesystem::is_regular_file(path, error)) return {};
  std::ifstream in(path, std::ios::binary);
  if (!in) return {};
  archive::Sha256 digest;
  std::array<char, 1 << 16> buffer{};
  while (in.read(buffer.data(), buffer.size()) || in.gcount() > 0)
    digest.update(std::string_view(buffer.data(), static_cast<std::size_t>(in.gcount())));
  return in.bad() ? std::string() : digest.hex();
}

std::vector<std::string> importedBefore(storage::Store& store, const std::string& sha256, const std::string& path,
                                        const std::vector<storage::Id>& new_ids) {
  if (sha256.empty()) return {};
  std::vector<std::string> before;
  for (const auto& run : store.listRuns()) {
    if (std::find(new_ids.begin(), new_ids.end(), run.id) != new_ids.end()) continue;
    const auto plan = nlohmann::json::parse(run.plan_json, nullptr, false);
    if (plan.is_object() && plan.value("imported_sha256", std::string()) == sha256)
      before.push_back(fmt::format("run {} ('{}')", run.id, run.name));
  }
  if (before.empty()) return {};
  constexpr std::size_t kNamed = 5;
  const std::size_t more = before.size() > kNamed ? before.size() - kNamed : 0;
  before.resize(std::min(before.size(), kNamed));
  const std::string file = std::filesystem::path(path).filename().string();
  const std::string holders = new_ids.size() == 1 ? fmt::format("run {} holds", new_ids.front())
                                                  : fmt::format("runs {} hold", fmt::join(new_ids, ", "));
  // Every import makes a campaign of its own: deleting it removes this import's runs only.
  return {
      fmt::format("{}: the same file was imported before, as {}{}: {} it again (mtcal delete c{} removes this "
                  "import)",
                  file, fmt::join(before, ", "), more ? fmt::format(" and {} more", more) : "", holders,
                  store.run(new_ids.front()).campaign_id)};
}

}  // namespace mtcal::services::detail
