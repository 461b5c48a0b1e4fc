#include "mtcal/acquisition/circle_measurements.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <numbers>
#include <optional>

#include "mtcal/acquisition/circle_plan.h"
#include "mtcal/acquisition/csv.h"
#include "mtcal/error.h"
#include "plan_json.h"

namespace mtcal::acquisition {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

}  // namespace

std::vector<processing::CirclePoint> toCirclePoints(const std::vector<storage::CirclePointRecord>& records) {
  std::vector<processing::CirclePoint> out;
  for (const auto& r : records)
    out.push_back({processing::parseDirection(r.direction), r.angle_deg * kDeg, r.deviation_um});
  return out;
}

std::optional<std::string> feedAssumedNote(const nlohmann::json& plan) {
  if (!plan.value("feed_assumed", false)) return std::nullopt;
  return fmt::format(
      "the feed was not given at import: {} mm/min is taken; a servo mismatch in ms scales with its inverse "
      "(import with --feed-mm-min)",
      plan.value("feed_mm_per_min", kAssumedFeedMmPerMin));
}

/// The largest angle of a circular test's point (deg): a few turns, an overshoot or a lap more.
constexpr double kLargestAngleDeg = 3600.0;

storage::Id importCircleCsv(const StoreWhenNeeded& store, const std::string& path, const CircleImportOptions& options) {
  std::ifstream in = openInputFile(path);
  return importCircleCsv(store, in, path, options);
}

void checkCircleImportOptions(const CircleImportOptions& options) {
  // A ballbar's radius is under 1.2 m: a value far beyond is in other units (um) or no
  // measurement.
  if (!(options.radius_mm > 0.0 && options.radius_mm <= 1e4))
    throw InputError(fmt::format("--radius-mm must be > 0 and at most 10 000 mm (10 m), got {:g}", options.radius_mm));
  const double feed_mm_per_min = options.feed_mm_per_min.value_or(kAssumedFeedMmPerMin);
  if (!(feed_mm_per_min >= kLeastFeedMmPerMin && feed_mm_per_min <= kGreatestFeedMmPerMin))
    throw InputError(fmt::format("--feed-mm-min must be at least {:.0f} and at most {:.0f} mm/min, got {:g}",
                                 kLeastFeedMmPerMin, kGreatestFeedMmPerMin, feed_mm_per_min));
  // The table ball's machine coordinates: finite, and within 100 m of the origin (mm, not um).
  if (options.centre_mm && !(options.centre_mm->allFinite() &&
                             options.centre_mm->cwiseAbs().maxCoeff() <= plan_json::kMaxMachineCoordinateMm)) {
    throw InputError(fmt::format("--centre-mm must be three machine coordinates within {:g} m (mm), got {},{},{}",
                                 plan_json::kMaxMachineCoordinateMm / 1000.0, (*options.centre_mm)(0),
                                 (*options.centre_mm)(1), (*options.centre_mm)(2)));
  }
}

storage::Id importCircleCsv(const StoreWhenNeeded& store_when_needed, std::istream& in, const std::string& path,
                            const CircleImportOptions& options) {
  checkCircleImportOptions(options);
  const double feed_mm_per_min = options.feed_mm_per_min.value_or(kAssumedFeedMmPerMin);
  const auto table = readColumnTable(in, path, {"angle_deg", "deviation_um"}, {"time_s"}, {"direction"}, options.csv);
  const auto& angle = table.numbers.at("angle_deg");
  const auto& deviation = table.numbers.at("deviation_um");
  const auto time = table.numbers.find("time_s");
  std::vector<storage::CirclePointRecord> points;
  std::map<std::string, std::int64_t> count;
  std::map<std::pair<long long, std::string>, int> seen;  // (angle in udeg, direction) -> line
  for (std::size_t i = 0; i < angle.size(); ++i) {
    std::string direction;
    try {
      direction = processing::directionName(processing::parseDirection(table.texts.at("direction")[i]));
    } catch (const InputError& e) {
      throw InputError(fmt::format("{}:{}: column 'direction': {}", path, table.lines[i], e.what()));
    }
    if (std::abs(deviation[i]) > 0.5 * options.radius_mm * 1000.0) {
      throw InputError(fmt::format(
          "{}:{}: column 'deviation_um': {} um is more than half the {} mm radius, not a deviation from it (is the "
          "column in um?)",
          path, table.lines[i], deviation[i], options.radius_mm));
    }
    // A test goes round a few times at most (an overshoot, a second lap): an angle of 1e11 deg is
    // not one of its points.
    if (!(std::abs(angle[i]) <= kLargestAngleDeg)) {
      throw InputError(fmt::format("{}:{}: column 'angle_deg': {} deg is beyond +-{:g} deg (a few turns)", path,
                                   table.lines[i], angle[i], kLargestAngleDeg));
    }
    if (auto [it, inserted] = seen.emplace(std::pair{std::llround(angle[i] * 1e6), direction}, table.lines[i]);
        !inserted) {
      throw InputError(fmt::format("{}:{}: angle {} deg, direction {} was already given on line {}", path,
                                   table.lines[i], angle[i], direction, it->second));
    }
    points.push_back({direction, count[direction]++, angle[i], deviation[i],
                      time != table.numbers.end() ? std::optional<double>(time->second[i]) : std::nullopt});
  }
  for (const auto& [direction, n] : count) {
    if (n < 3) throw InputError(fmt::format("{}: the {} path has {} point(s), at least 3 needed", path, direction, n));
    // The arc its points cover: the circle less the largest gap between neighbours.
    std::vector<double> around;
    for (const auto& p : points) {
      if (p.direction == direction) around.push_back(std::fmod(std::fmod(p.angle_deg, 360.0) + 360.0, 360.0));
    }
    std::sort(around.begin(), around.end());
    double gap = 360.0 - (around.back() - around.front());
    for (std::size_t k = 1; k < around.size(); ++k) gap = std::max(gap, around[k] - around[k - 1]);
    // (Each point stands for its share of the arc: 90 points a degree apart are a quarter, and,
    // within the rounding, 900 points at the middles of a quarter's bins.)
    const double n_points = static_cast<double>(n), arc_deg = (360.0 - gap) * n_points / (n_points - 1.0);
    if (arc_deg < kLeastArcDeg * (1.0 - 1e-9)) {
      throw InputError(
          fmt::format("{}: the {} path's {} points cover {:.1f} deg of the circle ({:.1f} deg with "
                      "each point's share): a circular test covers at least a quarter of it ({:g} deg)",
                      path, direction, n, 360.0 - gap, arc_deg, kLeastArcDeg));
    }
  }
  const std::string file_name = std::filesystem::path(path).filename().string();
  nlohmann::json plan = {{"type", "circle"},
                         {"plane", processing::planeName(options.plane)},
                         {"radius_mm", options.radius_mm},
                         {"feed_mm_per_min", feed_mm_per_min},
                         {"imported_from", file_name}};
  if (!options.feed_mm_per_min) plan["feed_assumed"] = true;
  if (!options.source_sha256.empty()) plan["imported_sha256"] = options.source_sha256;
  if (options.centre_mm)
    plan["centre_mm"] = {(*options.centre_mm)(0), (*options.centre_mm)(1), (*options.centre_mm)(2)};
  auto& store = store_when_needed();
  storage::Transaction tx(store.database());
  storage::NewRun run;
  run.campaign_id = store.addCampaign(store.ensureMachine(options.machine, "", "{}"), "import " + file_name);
  run.kind = storage::run_kind::kCircle;
  run.axis = processing::planeName(options.plane);
  run.name = options.name.empty() ? file_name : options.name;
  run.plan_json = plan.dump();
  run.status = storage::run_status::kImported;
  run.source = "imported";
  run.software_version = options.software_version;
  const storage::Id id = store.addRun(run);
  store.addCirclePoints(id, points);
  tx.commit();
  return id;
}

}  // namespace mtcal::acquisition
