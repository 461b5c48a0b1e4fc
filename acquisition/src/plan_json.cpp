#include "plan_json.h"

#include <algorithm>
#include <map>
#include <vector>

namespace mtcal::acquisition::plan_json {

namespace {

/// Edits (insertions, deletions, substitutions) from a to b.
std::size_t editDistance(const std::string& a, const std::string& b) {
  std::vector<std::size_t> row(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    std::size_t diagonal = row[0];
    row[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t above = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diagonal + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diagonal = above;
    }
  }
  return row[b.size()];
}

struct PlanType {
  const char* command;         ///< what runs it
  std::set<std::string> keys;  ///< every key a plan of the type may have
};

const std::map<std::string, PlanType>& planTypes() {
  static const std::map<std::string, PlanType> kTypes = {
      {"circle",
       {"mtcal run ballbar",
        {"type", "name", "device", "plane", "radius_mm", "centre_mm", "feed_mm_per_min", "directions",
         "start_angle_deg", "arc_deg", "overshoot_deg", "feed_in_mm", "sample_rate_hz", "settle_s",
         "calibrator_length_mm", "gcode_dialect"}}},
      {"est",
       {"mtcal run est",
        {"type",
         "name",
         "axis",
         "measures",
         "start_mm",
         "step_mm",
         "points",
         "spacing_mm",
         "probes",
         "settle_s",
         "readings_per_step",
         "rate_hz",
         "step_timeout_s",
         "line_position_mm",
         "zeroing",
         "zeroing_readings",
         "stepping",
         "still_um",
         "imported_from",
         "imported_sha256"}}},
      {"gantry",
       {"mtcal run gantry",
        {"type",
         "name",
         "device",
         "reflector",
         "integration_ms",
         "corners",
         "origin_corner",
         "points_per_face",
         "gantry_from_mm",
         "gantry_to_mm",
         "passes",
         "track_rate_hz",
         "track_feed_mm_per_min",
         "initial_mm",
         "sweep_target",
         "c_sweep_deg",
         "a_sweep_deg",
         "targets",
         "measure_tool_point",
         "tool_length_mm",
         "gantry_positions_mm",
         "hole_y_mm",
         "hole_z_mm",
         "orientations_deg",
         "settle_s",
         "tracker_mpe",
         "monte_carlo_trials"}}},
      {"linear",
       {"mtcal run linear",
        {"type",
         "name",
         "axis",
         "start_mm",
         "end_mm",
         "step_mm",
         "repeats",
         "bidirectional",
         "overrun_mm",
         "dwell_s",
         "window_s",
         "sample_rate_hz",
         "stability_threshold_um",
         "stability_timeout_s",
         "random_offset_mm",
         "random_seed",
         "datum_mm",
         "expansion_per_k",
         "air_index_model",
         "co2_ppm",
         "feed_mm_min",
         "gcode_dialect",
         "trigger_timeout_s",
         "measures",
         "line_position_mm",
         "reflector_offset_mm"}}},
      {"thermal",
       {"mtcal run thermal", {"type", "name", "interval_s", "phases", "sensors", "displacement", "environment"}}},
  };
  return kTypes;
}

/// The type of a plan without a "type" key whose keys are all another type's.
std::string typeByKeys(const nlohmann::json& j, const std::string& expected) {
  for (const auto& [name, type] : planTypes()) {
    if (name == expected) continue;
    const bool fits = std::all_of(j.items().begin(), j.items().end(),
                                  [&](const auto& item) { return type.keys.count(item.key()) > 0; });
    if (fits) return name;
  }
  return {};
}

}  // namespace

void checkTypeAndKeys(const nlohmann::json& j, const std::string& source, const std::string& type) {
  if (!j.is_object()) throw InputError(source + ": a plan must be a JSON object");
  const auto& types = planTypes();
  const auto& expected = types.at(type);
  std::string declared = type;
  if (j.contains("type")) {
    if (!j["type"].is_string()) bad(source, "type", "must be a string");
    declared = j["type"].get<std::string>();
    if (!types.count(declared))
      bad(source, "type", fmt::format("'{}' is not a plan type (circle, est, gantry, linear or thermal)", declared));
  }
  const auto wrongType = [&](const std::string& other) {
    bad(source, "type",
        fmt::format("this is {} {} plan: run it with `{}`, not `{}`", other == "est" ? "an" : "a", other,
                    types.at(other).command, expected.command));
  };
  if (declared != type) wrongType(declared);
  for (const auto& [key, value] : j.items()) {
    if (expected.keys.count(key)) continue;
    if (!j.contains("type")) {
      if (const auto other = typeByKeys(j, type); !other.empty()) wrongType(other);
    }
    std::string nearest;
    std::size_t best = std::max<std::size_t>(2, key.size() / 3) + 1;  // a suggestion only for a likely typo
    for (const auto& k : expected.keys) {
      if (const auto d = editDistance(key, k); d < best) {
        best = d;
        nearest = k;
      }
    }
    bad(source, key, nearest.empty() ? "unknown key" : fmt::format("unknown key; did you mean '{}'?", nearest));
  }
}

}  // namespace mtcal::acquisition::plan_json
