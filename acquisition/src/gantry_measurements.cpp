#include "mtcal/acquisition/gantry_measurements.h"

#include <fmt/format.h>

#include <map>
#include <nlohmann/json.hpp>
#include <set>

#include "gantry_stored_run.h"
#include "mtcal/error.h"
#include "plan_json.h"

namespace mtcal::acquisition {
namespace {

using plan_json::bad;
using plan_json::kMaxMachineCoordinateMm;
using plan_json::pointMm;
using plan_json::read;
using processing::GantryMeasurements;
using processing::Points3d;

/// Keys the run adds to its plan (the expansion); the rest is the plan as given.
constexpr const char* kExpansionKeys[] = {"reflector_radius_mm", "initial_np_mm", "holes"};

nlohmann::json point(const Eigen::Vector3d& p) { return {p.x(), p.y(), p.z()}; }
nlohmann::json points(const Points3d& ps) {
  nlohmann::json a = nlohmann::json::array();
  for (const auto& p : ps) a.push_back(point(p));
  return a;
}

Eigen::Vector3d pointFrom(const nlohmann::json& j, const std::string& source, const std::string& key) {
  return pointMm(j, source, key, kMaxMachineCoordinateMm, "the origin");
}

Points3d pointsFrom(const nlohmann::json& j, const std::string& source, const std::string& key) {
  if (!j.is_array()) bad(source, key, "must be an array of [x, y, z]");
  Points3d ps;
  for (std::size_t i = 0; i < j.size(); ++i) ps.push_back(pointFrom(j[i], source, key + "[" + std::to_string(i) + "]"));
  return ps;
}

const nlohmann::json& required(const nlohmann::json& j, const char* key, const std::string& source) {
  if (!j.contains(key)) bad(source, key, "missing");
  return j[key];
}

}  // namespace

nlohmann::json gantry_stored_run::expandedPlan(const GantryPlan& plan, const processing::MultibodyModel& kinematics,
                                               const std::vector<PlannedHole>& holes) {
  nlohmann::json expanded = plan.toJson();
  expanded["reflector_radius_mm"] = plan.reflectorRadiusMm();
  expanded["initial_np_mm"] = point(initialToolPoint(plan, kinematics));
  expanded["holes"] = nlohmann::json::array();
  for (const auto& h : holes) {
    expanded["holes"].push_back({{"id", h.id},
                                 {"gantry_position", h.gantry_position},
                                 {"machine_mm_deg", {h.x_mm, h.y_mm, h.z_mm, h.a_deg, h.c_deg}},
                                 {"np_mm", point(h.np_mm)},
                                 {"tool_vector", point(h.tool_vector)}});
  }
  return expanded;
}

GantryPlan gantryPlanOfRun(const storage::RunInfo& run) {
  nlohmann::json plan = nlohmann::json::parse(run.plan_json);
  for (const char* key : kExpansionKeys) plan.erase(key);
  return GantryPlan::fromJson(plan, fmt::format("run {} plan", run.id));
}

nlohmann::json measurementsToJson(const GantryMeasurements& m) {
  nlohmann::json corners = nlohmann::json::array();
  for (const auto& c : m.corners) {
    nlohmann::json o{{"name", c.name}, {"top", points(c.top)}};
    if (!c.side_1.empty()) o["side_1"] = points(c.side_1);
    if (!c.side_2.empty()) o["side_2"] = points(c.side_2);
    corners.push_back(o);
  }
  nlohmann::json passes = nlohmann::json::array();
  for (const auto& p : m.gantry_passes) passes.push_back({{"direction", p.direction}, {"points", points(p.points)}});
  nlohmann::json holes = nlohmann::json::array();
  for (const auto& h : m.holes) {
    holes.push_back({{"id", h.id},
                     {"gantry_position", h.gantry_position},
                     {"np_mm", point(h.np_mm)},
                     {"tool_vector", point(h.tool_vector)},
                     {"targets", points(h.targets)}});
  }
  nlohmann::json j{{"format", "mtcal-gantry-measurements"},
                   {"version", 1},
                   {"units", "mm, tracker frame"},
                   {"reflector_radius_mm", m.reflector_radius_mm},
                   {"origin_corner", m.origin_corner},
                   {"corners", corners},
                   {"gantry_passes", passes},
                   {"c_sweep", points(m.c_sweep)},
                   {"a_sweep", points(m.a_sweep)},
                   {"tool_length_mm", m.tool_length_mm},
                   {"initial_targets", points(m.initial_targets)},
                   {"initial_np_mm", point(m.initial_np_mm)},
                   {"holes", holes}};
  if (m.tool_point) j["tool_point"] = point(*m.tool_point);
  return j;
}

namespace {

/// An object of a measurement file holds only `known` keys: a key mistyped ("tool_pointt") is
/// refused, not read as absent (the nest check it holds left out without a word).
void onlyKnownKeys(const nlohmann::json& object, const std::set<std::string>& known, const std::string& source,
                   const std::string& where) {
  for (const auto& [key, value] : object.items()) {
    if (known.count(key)) continue;
    std::string keys;
    for (const auto& k : known) keys += (keys.empty() ? "" : ", ") + k;
    bad(source, where.empty() ? key : where + "." + key,
        fmt::format("not a key of {} (its keys: {})", where.empty() ? "a measurement file" : where, keys));
  }
}

}  // namespace

GantryMeasurements measurementsFromJson(const nlohmann::json& j, const std::string& source) {
  if (!j.is_object()) throw InputError(source + ": a measurement file must be a JSON object");
  onlyKnownKeys(
      j,
      {"format", "version", "units", "reflector_radius_mm", "origin_corner", "corners", "gantry_passes", "c_sweep",
       "a_sweep", "tool_length_mm", "tool_point", "initial_targets", "initial_np_mm", "holes", "tracker_mpe"},
      source, "");
  if (!j.contains("format") || j["format"] != "mtcal-gantry-measurements") {
    bad(source, "format", "must be \"mtcal-gantry-measurements\" (docs/gantry.md)");
  }
  if (!j.contains("version") || j["version"] != 1) bad(source, "version", "this mtcal reads version 1");
  GantryMeasurements m;
  read(j, "reflector_radius_mm", m.reflector_radius_mm, source);
  plan_json::nonNegative(m.reflector_radius_mm, source, "reflector_radius_mm");
  read(j, "origin_corner", m.origin_corner, source);
  const auto& corners = required(j, "corners", source);
  if (!corners.is_array()) bad(source, "corners", "must be an array of {name, top, side_1, side_2}");
  for (std::size_t i = 0; i < corners.size(); ++i) {
    const std::string key = "corners[" + std::to_string(i) + "]";
    const auto& c = corners[i];
    if (!c.is_object() || !c.contains("name") || !c["name"].is_string())
      bad(source, key, "must be an object with a name");
    onlyKnownKeys(c, {"name", "top", "side_1", "side_2"}, source, key);
    processing::BedCorner corner;
    corner.name = c["name"].get<std::string>();
    if (c.contains("top")) corner.top = pointsFrom(c["top"], source, key + ".top");
    if (c.contains("side_1")) corner.side_1 = pointsFrom(c["side_1"], source, key + ".side_1");
    if (c.contains("side_2")) corner.side_2 = pointsFrom(c["side_2"], source, key + ".side_2");
    m.corners.push_back(corner);
  }
  const auto& passes = required(j, "gantry_passes", source);
  if (!passes.is_array()) bad(source, "gantry_passes", "must be an array of {direction, points}");
  for (std::size_t i = 0; i < passes.size(); ++i) {
    const std::string key = "gantry_passes[" + std::to_string(i) + "]";
    const auto& p = passes[i];
    if (!p.is_object() || !p.contains("direction") || !(p["direction"] == 1 || p["direction"] == -1)) {
      bad(source, key + ".direction", "must be 1 (increasing X) or -1");
    }
    onlyKnownKeys(p, {"direction", "points"}, source, key);
    m.gantry_passes.push_back(
        {p["direction"].get<int>(), pointsFrom(required(p, "points", source), source, key + ".points")});
  }
  m.c_sweep = pointsFrom(required(j, "c_sweep", source), source, "c_sweep");
  m.a_sweep = pointsFrom(required(j, "a_sweep", source), source, "a_sweep");
  read(j, "tool_length_mm", m.tool_length_mm, source);
  if (j.contains("tool_point")) m.tool_point = pointFrom(j["tool_point"], source, "tool_point");
  m.initial_targets = pointsFrom(required(j, "initial_targets", source), source, "initial_targets");
  m.initial_np_mm = pointFrom(required(j, "initial_np_mm", source), source, "initial_np_mm");
  const auto& holes = required(j, "holes", source);
  if (!holes.is_array() || holes.empty()) bad(source, "holes", "must be an array of at least one hole");
  for (std::size_t i = 0; i < holes.size(); ++i) {
    const std::string key = "holes[" + std::to_string(i) + "]";
    const auto& h = holes[i];
    if (!h.is_object()) bad(source, key, "must be an object");
    onlyKnownKeys(h, {"id", "gantry_position", "np_mm", "tool_vector", "targets"}, source, key);
    processing::HoleMeasurement hole;
    hole.id = h.contains("id") && h["id"].is_string() ? h["id"].get<std::string>() : std::to_string(i + 1);
    for (const auto& other : m.holes) {
      if (other.id == hole.id) bad(source, key + ".id", "'" + hole.id + "' is another hole's id too: each names one");
    }
    if (h.contains("gantry_position")) {
      if (!h["gantry_position"].is_number_integer() || h["gantry_position"].get<int>() < 1)
        bad(source, key + ".gantry_position", "must be an integer >= 1");
      hole.gantry_position = h["gantry_position"].get<int>();
    }
    hole.np_mm = pointFrom(required(h, "np_mm", source), source, key + ".np_mm");
    hole.tool_vector = pointFrom(required(h, "tool_vector", source), source, key + ".tool_vector");
    if (hole.tool_vector.norm() < 1e-9) bad(source, key + ".tool_vector", "must not be zero");
    hole.targets = pointsFrom(required(h, "targets", source), source, key + ".targets");
    m.holes.push_back(hole);
  }
  return m;
}

GantryMeasurements loadGantryMeasurements(storage::Store& store, storage::Id run_id) {
  const auto run = store.run(run_id);
  if (run.kind != storage::run_kind::kGantry)
    throw InputError(
        fmt::format("run {} is {}, not a gantry point accuracy run", run_id, storage::run_kind::aRunOf(run.kind)));
  const auto plan_j = nlohmann::json::parse(run.plan_json);
  const std::string source = fmt::format("run {}", run_id);
  const GantryPlan plan = gantryPlanOfRun(run);
  std::map<std::string, Points3d> by_feature;
  std::map<std::string, std::map<std::string, Eigen::Vector3d>> by_place;  // feature -> place -> point
  for (const auto& p : store.trackerPoints(run_id)) {
    const Eigen::Vector3d xyz(p.x_mm, p.y_mm, p.z_mm);
    by_feature[p.feature].push_back(xyz);
    by_place[p.feature][p.place] = xyz;
  }
  const auto feature = [&](const std::string& name) -> const Points3d& {
    const auto it = by_feature.find(name);
    if (it == by_feature.end()) {
      // The stored feature's name in words: "pass:1:+" -> "gantry pass 1 (moving +)".
      const auto parts = [&] {
        std::vector<std::string> out;
        for (std::size_t at = 0, colon; at <= name.size(); at = colon + 1) {
          colon = std::min(name.find(':', at), name.size());
          out.push_back(name.substr(at, colon - at));
        }
        return out;
      }();
      const std::string what =
          parts.size() == 3 && parts[0] == "pass"     ? "gantry pass " + parts[1] + " (moving " + parts[2] + ")"
          : parts.size() == 3 && parts[0] == "corner" ? "corner " + parts[1] + " (" + parts[2] + ")"
          : parts.size() == 2 && parts[0] == "hole"   ? "hole " + parts[1]
                                                      : name;
      throw InputError(fmt::format("{} has no points of {} (status {}): it cannot be evaluated{}", source, what,
                                   run.status,
                                   run.status == storage::run_status::kInterrupted
                                       ? fmt::format(" until the rest is measured (mtcal resume {})", run_id)
                                       : ""));
    }
    return it->second;
  };
  GantryMeasurements m;
  m.reflector_radius_mm = plan_j.at("reflector_radius_mm").get<double>();
  m.origin_corner = plan.origin_corner;
  for (const auto& c : plan.corners) {
    processing::BedCorner corner;
    corner.name = c;
    corner.top = feature("corner:" + c + ":top");
    if (c == plan.origin_corner) {
      corner.side_1 = feature("corner:" + c + ":side1");
      corner.side_2 = feature("corner:" + c + ":side2");
    }
    m.corners.push_back(corner);
  }
  for (int pass = 1; pass <= plan.passes; ++pass)
    m.gantry_passes.push_back({gantry_stored_run::passDirection(pass), feature(gantry_stored_run::passFeature(pass))});
  m.c_sweep = feature("c-sweep");
  m.a_sweep = feature("a-sweep");
  m.tool_length_mm = plan.tool_length_mm;
  if (plan.measure_tool_point) m.tool_point = feature("tool-point").front();
  const auto targetsOf = [&](const std::string& name) {
    feature(name);
    Points3d t;
    for (const auto& target : plan.targets) {
      const auto& places = by_place[name];
      const auto it = places.find(target);
      if (it == places.end()) throw InputError(fmt::format("{}: '{}' has no point of target {}", source, name, target));
      t.push_back(it->second);
    }
    return t;
  };
  m.initial_targets = targetsOf("initial");
  m.initial_np_mm = pointFrom(plan_j.at("initial_np_mm"), source, "initial_np_mm");
  for (const auto& h : plan_j.at("holes")) {
    const std::string id = h.at("id").get<std::string>();
    if (!by_feature.count("hole:" + id)) continue;  // an interrupted run: the holes measured so far
    m.holes.push_back({id, h.at("gantry_position").get<int>(), pointFrom(h.at("np_mm"), source, id),
                       pointFrom(h.at("tool_vector"), source, id), targetsOf("hole:" + id)});
  }
  return m;
}

}  // namespace mtcal::acquisition
