#include "mtcal/acquisition/gantry_plan.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>

#include "mtcal/acquisition/gcode.h"
#include "mtcal/drivers/tracker/driver.h"
#include "mtcal/error.h"
#include "plan_json.h"

namespace mtcal::acquisition {
namespace {

using plan_json::bad;
using plan_json::read;

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
    if (std::find(v.begin(), v.end(), x.get<std::string>()) != v.end())
      bad(source, key, "'" + x.get<std::string>() + "' is given twice: each names another place");
    v.push_back(x.get<std::string>());
  }
  return v;
}

/// The longest tool (mm, wrist centre to tool point): a length beyond is a unit mistaken.
constexpr double kLongestToolMm = 2000.0;

int gridCount(double value, const std::string& source, const char* key) {
  if (!(value >= 1.0) || value != std::floor(value) || value > 1000.0)
    bad(source, key, "the count (third number) must be an integer 1..1000");
  return static_cast<int>(value);
}

}  // namespace

processing::TrackerMpe trackerMpeFromJson(const nlohmann::json& m, const std::string& source, const std::string& key) {
  if (!m.is_object())
    bad(source, key, "must be an object (distance_um, distance_um_per_m, transverse_um, transverse_um_per_m)");
  processing::TrackerMpe mpe;
  for (const auto& [name, value] : m.items()) {
    double* field = name == "distance_um"           ? &mpe.distance_um
                    : name == "distance_um_per_m"   ? &mpe.distance_um_per_m
                    : name == "transverse_um"       ? &mpe.transverse_um
                    : name == "transverse_um_per_m" ? &mpe.transverse_um_per_m
                                                    : nullptr;
    if (!field)
      bad(source, key + "." + name, "unknown key (distance_um, distance_um_per_m, transverse_um, transverse_um_per_m)");
    if (!value.is_number() || value.get<double>() < 0.0) bad(source, key + "." + name, "must be a number >= 0");
    *field = value.get<double>();
  }
  return mpe;
}

std::string GantryPlan::cornerFace(const std::string& corner, const std::string& face) { return corner + "." + face; }

std::vector<std::string> GantryPlan::facesAt(const std::string& corner) const {
  if (corner == origin_corner) return {"top", "side1", "side2"};
  return {"top"};
}

std::vector<std::string> GantryPlan::reflectorPlaces() const {
  std::vector<std::string> places;
  const auto add = [&places](const std::string& place) {
    if (std::find(places.begin(), places.end(), place) == places.end()) places.push_back(place);
  };
  for (const auto& corner : corners) {
    for (const auto& face : facesAt(corner)) add(cornerFace(corner, face));
  }
  add(sweep_target);
  if (measure_tool_point) add("TCP");
  for (const auto& target : targets) add(target);
  return places;
}

double GantryPlan::reflectorRadiusMm() const {
  if (const auto radius = drivers::tracker::reflectorRadiusMm(reflector)) return *radius;
  throw InputError("reflector '" + reflector + "' is not one of RRR1.5, RRR0.875, RRR0.5");
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
  if (p.integration_ms < 1 || p.integration_ms > drivers::tracker::kMaxIntegrationMs)
    bad(source, "integration_ms", "must be 1..60000");
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
  if (std::abs(p.gantry_to_mm - p.gantry_from_mm) < 100.0)
    bad(source, "gantry_to_mm", "the tracked pass must be at least 100 mm long");
  read(j, "passes", p.passes, source);
  if (p.passes < 1 || p.passes > 20) bad(source, "passes", "must be 1..20");
  read(j, "track_rate_hz", p.track_rate_hz, source);
  if (p.track_rate_hz < 1 || p.track_rate_hz > drivers::tracker::kMaxRateHz)
    bad(source, "track_rate_hz", "must be 1..1000");
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
  if (p.tool_length_mm > kLongestToolMm)
    bad(source, "tool_length_mm",
        fmt::format("{:g} mm: a tool is at most {:g} mm long", p.tool_length_mm, kLongestToolMm));
  if (j.contains("gantry_positions_mm"))
    p.gantry_positions_mm = numbers(j["gantry_positions_mm"], "gantry_positions_mm", source);
  if (p.gantry_positions_mm.empty()) bad(source, "gantry_positions_mm", "at least one gantry position");
  if (j.contains("hole_y_mm")) p.hole_y_mm = fixed<3>(j["hole_y_mm"], "hole_y_mm", source, "[start, step, count]");
  if (j.contains("hole_z_mm")) p.hole_z_mm = fixed<3>(j["hole_z_mm"], "hole_z_mm", source, "[start, step, count]");
  gridCount(p.hole_y_mm[2], source, "hole_y_mm");
  gridCount(p.hole_z_mm[2], source, "hole_z_mm");
  if (j.contains("orientations_deg")) {
    const auto& o = j["orientations_deg"];
    if (!o.is_array() || o.empty()) bad(source, "orientations_deg", "must be a non-empty array of [a_deg, c_deg]");
    p.orientations_deg.clear();
    for (const auto& pair : o)
      p.orientations_deg.push_back(fixed<2>(pair, "orientations_deg", source, "an array of [a_deg, c_deg]"));
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
  g << fmt::format("( {} : gantry point accuracy, patent CN106017326 )\n", gcodeCommentText(plan.name));
  g << fmt::format("( {} holes at {} gantry positions; the tracker measures {} targets at each )\n", holes.size(),
                   plan.gantry_positions_mm.size(), plan.targets.size());
  g << "G90 G21 G94\n";
  g << fmt::format(
      "G0 A0 C0\nG0 X{:.3f} Y{:.3f} Z{:.3f}\nM0 (measure the bed corners' faces; then track {} on the passes)\n",
      plan.gantry_from_mm, plan.initial_mm[1], plan.initial_mm[2], gcodeCommentText(plan.sweep_target));
  for (int pass = 1; pass <= plan.passes; ++pass) {
    g << fmt::format("G1 X{:.3f} F{:.0f} (gantry pass {})\n", pass % 2 == 1 ? plan.gantry_to_mm : plan.gantry_from_mm,
                     plan.track_feed_mm_per_min, pass);
  }
  g << fmt::format("G0 X{:.3f} (initial state)\n", plan.initial_mm[0]);
  for (const auto& [axis, angles] : {std::pair{"C", plan.c_sweep_deg}, std::pair{"A", plan.a_sweep_deg}}) {
    for (const double angle : angles) {
      g << fmt::format("G0 {}{:.3f}\nM0 (measure {} on the {} sweep)\n", axis, angle,
                       gcodeCommentText(plan.sweep_target), axis);
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
    g << fmt::format(
        "G0 X{:.3f} Y{:.3f} Z{:.3f} A{:.3f} C{:.3f} ( {} NP {:.3f} {:.3f} {:.3f} V {:.5f} {:.5f} {:.5f} )\n", h.x_mm,
        h.y_mm, h.z_mm, h.a_deg, h.c_deg, gcodeCommentText(h.id), h.np_mm.x(), h.np_mm.y(), h.np_mm.z(),
        h.tool_vector.x(), h.tool_vector.y(), h.tool_vector.z());
    g << "M0 (measure the targets)\n";
  }
  g << "G0 A0 C0\nM30\n";
  return g.str();
}

}  // namespace mtcal::acquisition
