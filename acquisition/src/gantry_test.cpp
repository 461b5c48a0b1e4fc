#include "mtcal/acquisition/gantry_test.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "stop_after_failure.h"
#include "mtcal/error.h"
#include "plan_json.h"
#include "sample_log.h"

namespace mtcal::acquisition {
namespace {

using plan_json::bad;
using plan_json::read;
using processing::GantryMeasurements;
using processing::Points3d;

std::vector<double> numbers(const nlohmann::json& j, const char* key, const std::string& source) {
  if (!j.is_array()) bad(source, key, "must be an array of numbers");
  std::vector<double> v;
  for (const auto& x : j) {
    if (!x.is_number()) bad(source, key, "must be an array of numbers");
    v.push_back(x.get<double>());
  }
  return v;
}

template <std::size_t N>
std::array<double, N> fixed(const nlohmann::json& j, const char* key, const std::string& source, const char* form) {
  const auto v = numbers(j, key, source);
  if (v.size() != N) bad(source, key, std::string("must be ") + form);
  std::array<double, N> a{};
  std::copy(v.begin(), v.end(), a.begin());
  return a;
}

std::vector<std::string> strings(const nlohmann::json& j, const char* key, const std::string& source) {
  if (!j.is_array()) bad(source, key, "must be an array of strings");
  std::vector<std::string> v;
  for (const auto& x : j) {
    if (!x.is_string() || x.get<std::string>().empty()) bad(source, key, "must be an array of non-empty strings");
    v.push_back(x.get<std::string>());
  }
  return v;
}

int gridCount(double value, const std::string& source, const char* key) {
  if (!(value >= 1.0) || value != std::floor(value) || value > 1000.0) bad(source, key, "the count (third number) must be an integer 1..1000");
  return static_cast<int>(value);
}

constexpr double kDeg = std::numbers::pi / 180.0;

}  // namespace

processing::TrackerMpe trackerMpeFromJson(const nlohmann::json& m, const std::string& source, const std::string& key) {
  if (!m.is_object()) bad(source, key, "must be an object (distance_um, distance_um_per_m, transverse_um, transverse_um_per_m)");
  processing::TrackerMpe mpe;
  for (const auto& [name, value] : m.items()) {
    double* field = name == "distance_um" ? &mpe.distance_um : name == "distance_um_per_m" ? &mpe.distance_um_per_m
                    : name == "transverse_um" ? &mpe.transverse_um : name == "transverse_um_per_m" ? &mpe.transverse_um_per_m
                                                                                                   : nullptr;
    if (!field) bad(source, key + "." + name, "unknown key (distance_um, distance_um_per_m, transverse_um, transverse_um_per_m)");
    if (!value.is_number() || value.get<double>() < 0.0) bad(source, key + "." + name, "must be a number >= 0");
    *field = value.get<double>();
  }
  return mpe;
}

double GantryPlan::reflectorRadiusMm() const {
  if (const auto radius = drivers::tracker::reflectorRadiusMm(reflector)) return *radius;
  throw InputError("reflector '" + reflector + "' is not one of RRR1.5, RRR0.875, RRR0.5");
}

namespace {

/// Keys the run adds to its plan (the expansion); the rest is the plan as given.
constexpr const char* kExpansionKeys[] = {"reflector_radius_mm", "initial_np_mm", "holes"};

/// Feature names of the stored points: a pass (odd passes increase X).
int passDirection(int pass) { return pass % 2 == 1 ? 1 : -1; }
std::string passFeature(int pass) { return fmt::format("pass:{}:{}", pass, passDirection(pass) > 0 ? "+" : "-"); }

}  // namespace

GantryPlan gantryPlanOfRun(const storage::RunInfo& run) {
  nlohmann::json plan = nlohmann::json::parse(run.plan_json);
  for (const char* key : kExpansionKeys) plan.erase(key);
  return GantryPlan::fromJson(plan, fmt::format("run {} plan", run.id));
}

GantryPlan GantryPlan::fromJson(const nlohmann::json& j, const std::string& source) {
  plan_json::checkTypeAndKeys(j, source, "gantry");
  GantryPlan p;
  read(j, "name", p.name, source);
  read(j, "device", p.device, source);
  read(j, "reflector", p.reflector, source);
  try {
    p.reflectorRadiusMm();
  } catch (const InputError& e) {
    bad(source, "reflector", e.what());
  }
  read(j, "integration_ms", p.integration_ms, source);
  if (p.integration_ms < 1 || p.integration_ms > drivers::tracker::kMaxIntegrationMs) bad(source, "integration_ms", "must be 1..60000");
  if (j.contains("corners")) p.corners = strings(j["corners"], "corners", source);
  if (p.corners.size() < 3) bad(source, "corners", "at least 3 corners (the patent measures 4)");
  read(j, "origin_corner", p.origin_corner, source);
  if (std::find(p.corners.begin(), p.corners.end(), p.origin_corner) == p.corners.end()) {
    bad(source, "origin_corner", "'" + p.origin_corner + "' is not one of the corners");
  }
  read(j, "points_per_face", p.points_per_face, source);
  if (p.points_per_face < 3) bad(source, "points_per_face", "must be >= 3 (a plane)");
  read(j, "gantry_from_mm", p.gantry_from_mm, source);
  read(j, "gantry_to_mm", p.gantry_to_mm, source);
  if (std::abs(p.gantry_to_mm - p.gantry_from_mm) < 100.0) bad(source, "gantry_to_mm", "the tracked pass must be at least 100 mm long");
  read(j, "passes", p.passes, source);
  if (p.passes < 1 || p.passes > 20) bad(source, "passes", "must be 1..20");
  read(j, "track_rate_hz", p.track_rate_hz, source);
  if (p.track_rate_hz < 1 || p.track_rate_hz > drivers::tracker::kMaxRateHz) bad(source, "track_rate_hz", "must be 1..1000");
  read(j, "track_feed_mm_per_min", p.track_feed_mm_per_min, source);
  plan_json::positive(p.track_feed_mm_per_min, source, "track_feed_mm_per_min");
  if (j.contains("initial_mm")) p.initial_mm = fixed<3>(j["initial_mm"], "initial_mm", source, "[x, y, z] in mm");
  read(j, "sweep_target", p.sweep_target, source);
  p.c_sweep_deg = {0, 30, 60, 90, 120, 150, 180, 210, 240, 270, 300, 330};
  p.a_sweep_deg = {-40, -30, -20, -10, 0, 10, 20, 30, 40};
  if (j.contains("c_sweep_deg")) p.c_sweep_deg = numbers(j["c_sweep_deg"], "c_sweep_deg", source);
  if (j.contains("a_sweep_deg")) p.a_sweep_deg = numbers(j["a_sweep_deg"], "a_sweep_deg", source);
  for (const auto* sweep : {&p.c_sweep_deg, &p.a_sweep_deg}) {
    const char* key = sweep == &p.c_sweep_deg ? "c_sweep_deg" : "a_sweep_deg";
    if (sweep->size() < 3) bad(source, key, "at least 3 angles (a circle)");
    const auto [lo, hi] = std::minmax_element(sweep->begin(), sweep->end());
    if (*hi - *lo < 30.0) bad(source, key, "the angles must span at least 30 deg for a usable circle");
  }
  if (j.contains("targets")) p.targets = strings(j["targets"], "targets", source);
  if (p.targets.size() < 3) bad(source, "targets", "at least 3 targets on the A axis (the patent uses 3)");
  if (std::find(p.targets.begin(), p.targets.end(), p.sweep_target) == p.targets.end()) {
    bad(source, "sweep_target", "'" + p.sweep_target + "' is not one of the targets");
  }
  read(j, "measure_tool_point", p.measure_tool_point, source);
  read(j, "tool_length_mm", p.tool_length_mm, source);
  plan_json::positive(p.tool_length_mm, source, "tool_length_mm");
  if (j.contains("gantry_positions_mm")) p.gantry_positions_mm = numbers(j["gantry_positions_mm"], "gantry_positions_mm", source);
  if (p.gantry_positions_mm.empty()) bad(source, "gantry_positions_mm", "at least one gantry position");
  if (j.contains("hole_y_mm")) p.hole_y_mm = fixed<3>(j["hole_y_mm"], "hole_y_mm", source, "[start, step, count]");
  if (j.contains("hole_z_mm")) p.hole_z_mm = fixed<3>(j["hole_z_mm"], "hole_z_mm", source, "[start, step, count]");
  gridCount(p.hole_y_mm[2], source, "hole_y_mm");
  gridCount(p.hole_z_mm[2], source, "hole_z_mm");
  if (j.contains("orientations_deg")) {
    const auto& o = j["orientations_deg"];
    if (!o.is_array() || o.empty()) bad(source, "orientations_deg", "must be a non-empty array of [a_deg, c_deg]");
    p.orientations_deg.clear();
    for (const auto& pair : o) p.orientations_deg.push_back(fixed<2>(pair, "orientations_deg", source, "an array of [a_deg, c_deg]"));
  }
  read(j, "settle_s", p.settle_s, source);
  plan_json::nonNegative(p.settle_s, source, "settle_s");
  if (j.contains("tracker_mpe")) p.mpe = trackerMpeFromJson(j["tracker_mpe"], source, "tracker_mpe");
  read(j, "monte_carlo_trials", p.monte_carlo_trials, source);
  if (p.monte_carlo_trials < 0 || p.monte_carlo_trials == 1 || p.monte_carlo_trials > 100000) {
    bad(source, "monte_carlo_trials", "must be 0 (none) or 2..100000");
  }
  return p;
}

nlohmann::json GantryPlan::toJson() const {
  nlohmann::json o = nlohmann::json::array();
  for (const auto& a : orientations_deg) o.push_back({a[0], a[1]});
  return {{"type", "gantry"},
          {"name", name},
          {"device", device},
          {"reflector", reflector},
          {"integration_ms", integration_ms},
          {"corners", corners},
          {"origin_corner", origin_corner},
          {"points_per_face", points_per_face},
          {"gantry_from_mm", gantry_from_mm},
          {"gantry_to_mm", gantry_to_mm},
          {"passes", passes},
          {"track_rate_hz", track_rate_hz},
          {"track_feed_mm_per_min", track_feed_mm_per_min},
          {"initial_mm", initial_mm},
          {"sweep_target", sweep_target},
          {"c_sweep_deg", c_sweep_deg},
          {"a_sweep_deg", a_sweep_deg},
          {"targets", targets},
          {"measure_tool_point", measure_tool_point},
          {"tool_length_mm", tool_length_mm},
          {"gantry_positions_mm", gantry_positions_mm},
          {"hole_y_mm", hole_y_mm},
          {"hole_z_mm", hole_z_mm},
          {"orientations_deg", o},
          {"settle_s", settle_s},
          {"tracker_mpe",
           {{"distance_um", mpe.distance_um},
            {"distance_um_per_m", mpe.distance_um_per_m},
            {"transverse_um", mpe.transverse_um},
            {"transverse_um_per_m", mpe.transverse_um_per_m}}},
          {"monte_carlo_trials", monte_carlo_trials}};
}

namespace {

/// Coordinates vector of the kinematics for x, y, z, c, a. @throws InputError
Eigen::VectorXd jointVector(const processing::MultibodyModel& k, double x, double y, double z, double c, double a) {
  const auto& names = k.coordinates();
  Eigen::VectorXd q = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(names.size()));
  const std::map<std::string, double> values{{"x", x}, {"y", y}, {"z", z}, {"c", c}, {"a", a}};
  for (const auto& [name, value] : values) {
    const auto it = std::find(names.begin(), names.end(), name);
    if (it == names.end()) {
      throw InputError("machine '" + k.name() + "' has no coordinate " + name +
                       ": the gantry test needs x, y, z and the swivel head's c and a");
    }
    q(it - names.begin()) = value;
  }
  return q;
}

}  // namespace

Eigen::Vector3d initialToolPoint(const GantryPlan& plan, const processing::MultibodyModel& k) {
  return k.idealPoint(jointVector(k, plan.initial_mm[0], plan.initial_mm[1], plan.initial_mm[2], 0.0, 0.0));
}

std::vector<PlannedHole> planHoles(const GantryPlan& plan, const processing::MultibodyModel& k) {
  std::vector<PlannedHole> holes;
  const Eigen::VectorXd zero = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(k.terms().size()));
  const int ny = static_cast<int>(plan.hole_y_mm[2]), nz = static_cast<int>(plan.hole_z_mm[2]);
  for (std::size_t g = 0; g < plan.gantry_positions_mm.size(); ++g) {
    int n = 0;
    for (int iz = 0; iz < nz; ++iz) {
      for (int iy = 0; iy < ny; ++iy, ++n) {
        const auto& o = plan.orientations_deg[static_cast<std::size_t>(n) % plan.orientations_deg.size()];
        PlannedHole h;
        h.id = fmt::format("g{}-h{:02d}", g + 1, n + 1);
        h.gantry_position = static_cast<int>(g) + 1;
        h.a_deg = o[0];
        h.c_deg = o[1];
        // The head's offset at this orientation (the linear axes only translate it).
        const Eigen::Vector3d head = k.idealPoint(jointVector(k, 0, 0, 0, h.c_deg, h.a_deg));
        const Eigen::Vector3d tool_point(plan.gantry_positions_mm[g], plan.hole_y_mm[0] + iy * plan.hole_y_mm[1],
                                         plan.hole_z_mm[0] + iz * plan.hole_z_mm[1]);
        h.x_mm = tool_point.x() - head.x();
        h.y_mm = tool_point.y() - head.y();
        h.z_mm = tool_point.z() - head.z();
        const Eigen::VectorXd q = jointVector(k, h.x_mm, h.y_mm, h.z_mm, h.c_deg, h.a_deg);
        h.np_mm = k.idealPoint(q);
        h.tool_vector = (k.actualPoint(q, zero, k.toolPoint() + Eigen::Vector3d::UnitZ()) - h.np_mm).normalized();
        holes.push_back(h);
      }
    }
  }
  return holes;
}

std::string gantryGcode(const GantryPlan& plan, const std::vector<PlannedHole>& holes) {
  // In the order the run measures: the corner faces need no motion; the gantry passes; the C
  // and A sweeps; the initial state; the holes. An M0 wherever the tracker measures.
  std::ostringstream g;
  g << fmt::format("( {} : gantry point accuracy, patent CN106017326 )\n", plan.name);
  g << fmt::format("( {} holes at {} gantry positions; the tracker measures {} targets at each )\n", holes.size(),
                   plan.gantry_positions_mm.size(), plan.targets.size());
  g << "G90 G21 G94\n";
  g << fmt::format("G0 A0 C0\nG0 X{:.3f} Y{:.3f} Z{:.3f}\nM0 (measure the bed corners' faces; then track {} on the passes)\n",
                   plan.gantry_from_mm, plan.initial_mm[1], plan.initial_mm[2], plan.sweep_target);
  for (int pass = 1; pass <= plan.passes; ++pass) {
    g << fmt::format("G1 X{:.3f} F{:.0f} (gantry pass {})\n", pass % 2 == 1 ? plan.gantry_to_mm : plan.gantry_from_mm,
                     plan.track_feed_mm_per_min, pass);
  }
  g << fmt::format("G0 X{:.3f} (initial state)\n", plan.initial_mm[0]);
  for (const auto& [axis, angles] : {std::pair{"C", plan.c_sweep_deg}, std::pair{"A", plan.a_sweep_deg}}) {
    for (const double angle : angles) {
      g << fmt::format("G0 {}{:.3f}\nM0 (measure {} on the {} sweep)\n", axis, angle, plan.sweep_target, axis);
    }
    g << fmt::format("G0 {}0\n", axis);
  }
  g << "M0 (measure TCP0 and the targets in the initial state)\n";
  int position = 0;
  for (const auto& h : holes) {
    if (h.gantry_position != position) {
      position = h.gantry_position;
      g << fmt::format("( gantry position {} )\n", position);
    }
    g << fmt::format("G0 X{:.3f} Y{:.3f} Z{:.3f} A{:.3f} C{:.3f} ( {} NP {:.3f} {:.3f} {:.3f} V {:.5f} {:.5f} {:.5f} )\n", h.x_mm,
                     h.y_mm, h.z_mm, h.a_deg, h.c_deg, h.id, h.np_mm.x(), h.np_mm.y(), h.np_mm.z(), h.tool_vector.x(),
                     h.tool_vector.y(), h.tool_vector.z());
    g << "M0 (measure the targets)\n";
  }
  g << "G0 A0 C0\nM30\n";
  return g.str();
}

namespace {

nlohmann::json point(const Eigen::Vector3d& p) { return {p.x(), p.y(), p.z()}; }
nlohmann::json points(const Points3d& ps) {
  nlohmann::json a = nlohmann::json::array();
  for (const auto& p : ps) a.push_back(point(p));
  return a;
}

Eigen::Vector3d pointFrom(const nlohmann::json& j, const std::string& source, const std::string& key) {
  if (!j.is_array() || j.size() != 3) bad(source, key, "must be [x, y, z] in mm");
  Eigen::Vector3d p;
  for (int i = 0; i < 3; ++i) {
    if (!j[static_cast<std::size_t>(i)].is_number()) bad(source, key, "must be [x, y, z] in mm");
    p(i) = j[static_cast<std::size_t>(i)].get<double>();
  }
  return p;
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

GantryMeasurements measurementsFromJson(const nlohmann::json& j, const std::string& source) {
  if (!j.is_object()) throw InputError(source + ": a measurement file must be a JSON object");
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
    if (!c.is_object() || !c.contains("name") || !c["name"].is_string()) bad(source, key, "must be an object with a name");
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
    m.gantry_passes.push_back({p["direction"].get<int>(), pointsFrom(required(p, "points", source), source, key + ".points")});
  }
  m.c_sweep = pointsFrom(required(j, "c_sweep", source), source, "c_sweep");
  m.a_sweep = pointsFrom(required(j, "a_sweep", source), source, "a_sweep");
  read(j, "tool_length_mm", m.tool_length_mm, source);
  if (j.contains("tool_point")) m.tool_point = pointFrom(j["tool_point"], source, "tool_point");
  m.initial_targets = pointsFrom(required(j, "initial_targets", source), source, "initial_targets");
  m.initial_np_mm = pointFrom(required(j, "initial_np_mm", source), source, "initial_np_mm");
  const auto& holes = required(j, "holes", source);
  if (!holes.is_array()) bad(source, "holes", "must be an array");
  for (std::size_t i = 0; i < holes.size(); ++i) {
    const std::string key = "holes[" + std::to_string(i) + "]";
    const auto& h = holes[i];
    if (!h.is_object()) bad(source, key, "must be an object");
    processing::HoleMeasurement hole;
    hole.id = h.contains("id") && h["id"].is_string() ? h["id"].get<std::string>() : std::to_string(i + 1);
    if (h.contains("gantry_position")) {
      if (!h["gantry_position"].is_number_integer() || h["gantry_position"].get<int>() < 1) bad(source, key + ".gantry_position", "must be an integer >= 1");
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

namespace {

struct Recorder {
  storage::Store& store;
  storage::Id run_id;
  std::size_t points = 0;
  void commit(const std::vector<storage::TrackerPointRecord>& records) {
    store.addTrackerPoints(run_id, records);
    points += records.size();
  }
};

/// Runs `body` while the tracker measures continuously into `log`; the measurement is stopped
/// however `body` ends (when it threw, its error is the one reported).
template <typename Body>
void whileStreaming(drivers::tracker::TrackerDevice& tracker, std::uint32_t rate_hz, SampleLog& log, Body body) {
  tracker.startStream(rate_hz, log);
  try {
    body();
  } catch (...) {
    stopAfterFailure(tracker);
    throw;
  }
  tracker.stopStream();
}

storage::TrackerPointRecord record(const std::string& feature, const std::string& place, const drivers::tracker::Point& p,
                                   int integration_ms) {
  return {feature, place, p.xyz_mm[0], p.xyz_mm[1], p.xyz_mm[2], p.time_s, integration_ms};
}

}  // namespace

GantryRunResult runGantryTest(storage::Store& store, storage::Id campaign_id, drivers::tracker::TrackerDevice& tracker,
                              MachineController& controller, const GantryPlan& plan,
                              const processing::MultibodyModel& kinematics, const GantryRunOptions& options) {
  if (!options.place_reflector) throw InputError("gantry run: nobody to place the reflector (no operator callback)");
  const auto holes = planHoles(plan, kinematics);
  RunClock& clock = options.run_clock ? *options.run_clock : realTime();
  nlohmann::json expanded = plan.toJson();
  expanded["reflector_radius_mm"] = plan.reflectorRadiusMm();
  expanded["initial_np_mm"] = point(initialToolPoint(plan, kinematics));
  expanded["holes"] = nlohmann::json::array();
  for (const auto& h : holes) {
    expanded["holes"].push_back({{"id", h.id}, {"gantry_position", h.gantry_position}, {"machine_mm_deg", {h.x_mm, h.y_mm, h.z_mm, h.a_deg, h.c_deg}},
                                 {"np_mm", point(h.np_mm)}, {"tool_vector", point(h.tool_vector)}});
  }
  tracker.initialise();
  tracker.setUnits();
  if (options.environment) tracker.setEnvironment(*options.environment);
  tracker.setReflector(plan.reflector);
  tracker.goHome();  // the reflector starts in the bird bath, the beam locked on it

  storage::NewRun run;
  run.campaign_id = campaign_id;
  run.kind = storage::run_kind::kGantry;
  run.instrument_id = options.instrument_id;
  run.axis = "XYZAC";
  run.name = plan.name;
  run.plan_json = expanded.dump();
  run.software_version = options.software_version;
  GantryRunResult result;
  result.run_id = store.addRun(run);
  Recorder rec{store, result.run_id};
  std::size_t features = static_cast<std::size_t>(plan.passes) + 2 + 1 + holes.size(), started = 0;  // passes, sweeps, initial, holes
  for (const auto& corner : plan.corners) features += corner == plan.origin_corner ? 3 : 1;
  const auto progress = [&](const std::string& what) {
    if (options.stop_requested && *options.stop_requested) throw InputError("stopped by the user");
    if (options.on_progress) options.on_progress(started, features, what);
    ++started;
    spdlog::info("gantry run: {}", what);
  };
  const auto stationary = [&](const std::string& feature, const std::string& place, int count,
                              std::vector<storage::TrackerPointRecord>& out) {
    for (int i = 0; i < count; ++i) out.push_back(record(feature, place, tracker.measure(plan.integration_ms), plan.integration_ms));
  };
  const auto confirm = [&](const std::string& what) {
    if (!options.confirm_in_position) {
      throw InputError("this machine controller does not report in-position times and nobody confirms them: " + what);
    }
    options.confirm_in_position(what);
  };
  // Waits, watching the tracker's clock, until the machine is in position and settled (or
  // until the operator confirms it).
  const auto settle = [&](std::optional<double> in_position_s, const std::string& what) {
    if (!in_position_s) {
      confirm(what);
      return;
    }
    SampleLog log;
    whileStreaming(tracker, plan.track_rate_hz, log,
                   [&] { waitForDeviceTime(log, tracker, clock, plan.track_rate_hz, *in_position_s + plan.settle_s, std::chrono::seconds(600)); });
  };
  const auto moveAll = [&](std::initializer_list<std::pair<const char*, double>> moves) {
    std::optional<double> latest = 0.0;
    for (const auto& [axis, value] : moves) {
      const auto t = controller.moveTo(axis, value);
      latest = t && latest ? std::optional(std::max(*latest, *t)) : std::nullopt;
    }
    return latest;
  };
  try {
    // 1. The bed's corners.
    for (const auto& corner : plan.corners) {
      for (const char* face : {"top", "side1", "side2"}) {
        if (std::string(face) != "top" && corner != plan.origin_corner) continue;
        progress(fmt::format("corner {} {}", corner, face));
        const std::string place = corner + "." + face;
        options.place_reflector(place);
        std::vector<storage::TrackerPointRecord> points;
        stationary(fmt::format("corner:{}:{}", corner, face), place, plan.points_per_face, points);
        rec.commit(points);
      }
    }
    // 2. The gantry's line, tracked back and forth.
    options.place_reflector(plan.sweep_target);
    settle(moveAll({{"A", 0.0}, {"C", 0.0}, {"Y", plan.initial_mm[1]}, {"Z", plan.initial_mm[2]}, {"X", plan.gantry_from_mm}}),
           fmt::format("the start of the passes: X {} Y {} Z {} A 0 C 0", plan.gantry_from_mm, plan.initial_mm[1], plan.initial_mm[2]));
    for (int pass = 1; pass <= plan.passes; ++pass) {
      const bool forward = passDirection(pass) > 0;
      progress(fmt::format("gantry pass {} of {}", pass, plan.passes));
      // The pass as a contouring move at the plan's feed (the controller reports when it
      // starts and ends); the points of that window make the line.
      const double from = forward ? plan.gantry_from_mm : plan.gantry_to_mm, to = forward ? plan.gantry_to_mm : plan.gantry_from_mm;
      processing::ContourPath path(Eigen::Vector3d(from, plan.initial_mm[1], plan.initial_mm[2]));
      path.lineTo(Eigen::Vector3d(to, plan.initial_mm[1], plan.initial_mm[2]), plan.track_feed_mm_per_min);
      SampleLog log;
      std::vector<storage::TrackerPointRecord> points;
      std::optional<std::pair<double, double>> window;
      whileStreaming(tracker, plan.track_rate_hz, log, [&] {
        window = controller.followPath(path);
        if (window) {
          waitForDeviceTime(log, tracker, clock, plan.track_rate_hz, window->second + plan.settle_s, std::chrono::seconds(600));
        } else {
          confirm(fmt::format("gantry pass {}: X {} to {} at F{} (tracking {}), stopped at the end", pass, from, to,
                              plan.track_feed_mm_per_min, plan.sweep_target));
          // Every point up to the confirmation, when the instruments' time is known.
          if (const auto now_s = clock.nowS()) waitForDeviceTime(log, tracker, clock, plan.track_rate_hz, *now_s, std::chrono::seconds(600));
        }
      });
      {
        std::lock_guard lock(log.mutex);
        for (std::size_t i = 0; i + 2 < log.samples.size(); i += 3) {
          const auto& s = log.samples;
          const double t = static_cast<double>(s[i].device_time_ns) * 1e-9;
          // After the start (a point at the very start instant may belong to the rest before it).
          if (window && (t <= window->first + 1e-6 || t > window->second + 1e-9)) continue;
          points.push_back({passFeature(pass), plan.sweep_target, s[i].value,
                            s[i + 1].value, s[i + 2].value, t, std::nullopt});
        }
      }
      if (points.size() < 10) throw DeviceError(fmt::format("gantry pass {}: only {} points tracked", pass, points.size()));
      rec.commit(points);
    }
    // 3. The rotary axes, one target each, at the initial state.
    settle(moveAll({{"X", plan.initial_mm[0]}}), fmt::format("the initial state: X {}", plan.initial_mm[0]));
    for (const auto& [axis, angles] : {std::pair{"C", plan.c_sweep_deg}, std::pair{"A", plan.a_sweep_deg}}) {
      progress(fmt::format("{} sweep", axis));
      std::vector<storage::TrackerPointRecord> points;
      for (const double angle : angles) {
        settle(controller.moveTo(axis, angle), fmt::format("{} at {} deg", axis, angle));
        stationary(std::string(axis == std::string("C") ? "c" : "a") + "-sweep", plan.sweep_target, 1, points);
      }
      settle(controller.moveTo(axis, 0.0), fmt::format("{} back at 0 deg", axis));
      rec.commit(points);
    }
    // 4. TCP0 (beyond the patent) and the targets in the initial state.
    progress("initial state");
    std::vector<storage::TrackerPointRecord> initial;
    if (plan.measure_tool_point) {
      options.place_reflector("TCP");
      stationary("tool-point", "TCP", 1, initial);
    }
    for (const auto& target : plan.targets) {
      options.place_reflector(target);
      stationary("initial", target, 1, initial);
    }
    rec.commit(initial);
    // 5. The holes.
    for (const auto& h : holes) {
      progress(fmt::format("hole {} ({} of {})", h.id, &h - holes.data() + 1, holes.size()));
      settle(moveAll({{"C", h.c_deg}, {"A", h.a_deg}, {"X", h.x_mm}, {"Y", h.y_mm}, {"Z", h.z_mm}}),
             fmt::format("hole {}: X {:.3f} Y {:.3f} Z {:.3f} A {:.3f} C {:.3f}", h.id, h.x_mm, h.y_mm, h.z_mm, h.a_deg, h.c_deg));
      std::vector<storage::TrackerPointRecord> points;
      for (const auto& target : plan.targets) {
        options.place_reflector(target);
        stationary("hole:" + h.id, target, 1, points);
      }
      rec.commit(points);
    }
    store.setRunStatus(result.run_id, storage::run_status::kCompleted);
  } catch (const Error& e) {
    result.outcome = RunOutcome::kInterrupted;
    result.reason = e.what();
    store.setRunStatus(result.run_id, storage::run_status::kInterrupted);
    store.logEvent(result.run_id, "error", std::string("run interrupted: ") + e.what());
  }
  result.points = rec.points;
  return result;
}

GantryMeasurements loadGantryMeasurements(storage::Store& store, storage::Id run_id) {
  const auto run = store.run(run_id);
  if (run.kind != "gantry") throw InputError(fmt::format("run {} is a {} run, not a gantry point accuracy run", run_id, run.kind));
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
      throw InputError(fmt::format("{} has no '{}' points (status {}): it cannot be evaluated", source, name, run.status));
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
  for (int pass = 1; pass <= plan.passes; ++pass) m.gantry_passes.push_back({passDirection(pass), feature(passFeature(pass))});
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
