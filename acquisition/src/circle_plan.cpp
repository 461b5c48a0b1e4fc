#include "mtcal/acquisition/circle_plan.h"

#include <fmt/format.h>

#include <cmath>
#include <nlohmann/json.hpp>
#include <numbers>
#include <sstream>

#include "mtcal/acquisition/gcode.h"
#include "mtcal/drivers/ballbar/driver.h"
#include "mtcal/error.h"
#include "plan_json.h"

namespace mtcal::acquisition {
namespace {

using plan_json::bad;
using plan_json::kMaxMachineCoordinateMm;
using plan_json::pointMm;
using plan_json::read;
using processing::CircleDirection;
constexpr double kPi = std::numbers::pi;
constexpr double kDeg = kPi / 180.0;

// Where on the circle (machine coordinates) the angle `angle_rad` of the plane is.
Eigen::Vector3d onCircle(const CirclePlan& plan, double radius_mm, double angle_rad) {
  const auto a = processing::planeAxes(plan.plane);
  Eigen::Vector3d p = plan.centre_mm;
  p(a.first) += radius_mm * std::cos(angle_rad);
  p(a.second) += radius_mm * std::sin(angle_rad);
  return p;
}

double startAngle(const CirclePlan& plan, CircleDirection d) {
  return (plan.start_angle_deg + (d == CircleDirection::kCw ? plan.arc_deg : 0.0)) * kDeg;
}

}  // namespace

CirclePlan CirclePlan::fromJson(const nlohmann::json& j, const std::string& source) {
  plan_json::checkTypeAndKeys(j, source, "circle");
  CirclePlan p;
  read(j, "name", p.name, source);
  read(j, "device", p.device, source);
  std::string plane = "XY";
  read(j, "plane", plane, source);
  try {
    p.plane = processing::parsePlane(plane);
  } catch (const InputError& e) {
    bad(source, "plane", e.what());
  }
  read(j, "radius_mm", p.radius_mm, source);
  read(j, "feed_mm_per_min", p.feed_mm_per_min, source);
  read(j, "start_angle_deg", p.start_angle_deg, source);
  read(j, "arc_deg", p.arc_deg, source);
  read(j, "overshoot_deg", p.overshoot_deg, source);
  read(j, "feed_in_mm", p.feed_in_mm, source);
  read(j, "sample_rate_hz", p.sample_rate_hz, source);
  read(j, "settle_s", p.settle_s, source);
  read(j, "gcode_dialect", p.gcode_dialect, source);
  if (j.contains("centre_mm"))
    p.centre_mm = pointMm(j["centre_mm"], source, "centre_mm", kMaxMachineCoordinateMm, "the origin");
  if (j.contains("directions")) {
    const auto& d = j["directions"];
    if (!d.is_array() || d.empty() || d.size() > 2)
      bad(source, "directions", "must be [\"ccw\", \"cw\"] or one of them");
    p.directions.clear();
    for (const auto& v : d) {
      if (!v.is_string()) bad(source, "directions", "must hold \"ccw\" and/or \"cw\"");
      try {
        p.directions.push_back(processing::parseDirection(v.get<std::string>()));
      } catch (const InputError& e) {
        bad(source, "directions", e.what());
      }
    }
    if (p.directions.size() == 2 && p.directions[0] == p.directions[1])
      bad(source, "directions", "names a direction twice");
  }
  p.calibrator_length_mm = p.radius_mm;  // a bar of the test's length, zeroed in its calibrator
  if (j.contains("calibrator_length_mm")) {
    if (j["calibrator_length_mm"].is_null()) {
      p.calibrator_length_mm.reset();
    } else {
      double v = 0.0;
      read(j, "calibrator_length_mm", v, source);
      if (!(v > 0.0)) bad(source, "calibrator_length_mm", "must be > 0, or null to skip the zero");
      p.calibrator_length_mm = v;
    }
  }
  plan_json::positive(p.radius_mm, source, "radius_mm");
  if (!(p.feed_mm_per_min >= kLeastFeedMmPerMin && p.feed_mm_per_min <= kGreatestFeedMmPerMin))
    bad(source, "feed_mm_per_min",
        fmt::format("must be {:.0f}..{:.0f} mm/min", kLeastFeedMmPerMin, kGreatestFeedMmPerMin));
  if (!(p.arc_deg >= kLeastArcDeg && p.arc_deg <= 360.0))
    bad(source, "arc_deg", fmt::format("must be {:g}..360 (a partial arc of at least a quarter)", kLeastArcDeg));
  if (!(p.overshoot_deg >= 5.0 && p.overshoot_deg <= 180.0))
    bad(source, "overshoot_deg", "must be 5..180 (the servo settles from the feed-in there)");
  if (!(p.feed_in_mm > 0.0 && p.feed_in_mm < p.radius_mm))
    bad(source, "feed_in_mm", "must be > 0 and less than the radius");
  if (p.sample_rate_hz < 1 || p.sample_rate_hz > drivers::ballbar::kMaxRateHz)
    bad(source, "sample_rate_hz", "must be 1..1000");
  plan_json::nonNegative(p.settle_s, source, "settle_s");
  if (p.gcode_dialect != "iso") bad(source, "gcode_dialect", "only 'iso' is written for circular tests");
  return p;
}

nlohmann::json CirclePlan::toJson() const {
  nlohmann::json dirs = nlohmann::json::array();
  for (auto d : directions) dirs.push_back(processing::directionName(d));
  return {
      {"type", "circle"},
      {"name", name},
      {"device", device},
      {"plane", processing::planeName(plane)},
      {"radius_mm", radius_mm},
      {"centre_mm", {centre_mm.x(), centre_mm.y(), centre_mm.z()}},
      {"feed_mm_per_min", feed_mm_per_min},
      {"directions", dirs},
      {"start_angle_deg", start_angle_deg},
      {"arc_deg", arc_deg},
      {"overshoot_deg", overshoot_deg},
      {"feed_in_mm", feed_in_mm},
      {"sample_rate_hz", sample_rate_hz},
      {"settle_s", settle_s},
      {"calibrator_length_mm", calibrator_length_mm ? nlohmann::json(*calibrator_length_mm) : nlohmann::json(nullptr)},
      {"gcode_dialect", gcode_dialect}};
}

processing::ContourPath circlePath(const CirclePlan& plan, CircleDirection direction) {
  const double sense = static_cast<int>(direction);
  const double overshoot = plan.overshoot_deg * kDeg;
  const double lead_in = startAngle(plan, direction) - sense * overshoot;
  const double sweep = sense * (plan.arc_deg * kDeg + 2.0 * overshoot);
  const double half = plan.feed_in_mm / 2.0;
  // Feed-in: a semicircle about a point half the feed-in inside the circle, turning the same
  // way as the circle, so the tool meets it tangentially; then an overshoot arc (the servo's
  // transient from the tight feed-in dies out there), the measuring arc, an overshoot arc and
  // the feed-out semicircle back inside.
  processing::ContourPath path(onCircle(plan, plan.radius_mm - plan.feed_in_mm, lead_in));
  path.arc(onCircle(plan, plan.radius_mm - half, lead_in), plan.plane, sense * kPi, plan.feed_mm_per_min);
  path.arc(plan.centre_mm, plan.plane, sweep, plan.feed_mm_per_min);
  path.arc(onCircle(plan, plan.radius_mm - half, lead_in + sweep), plan.plane, sense * kPi, plan.feed_mm_per_min);
  return path;
}

std::pair<double, double> measuringWindow(const CirclePlan& plan) {
  const double speed = plan.feed_mm_per_min / 60.0;
  return {(kPi * plan.feed_in_mm / 2.0 + plan.radius_mm * plan.overshoot_deg * kDeg) / speed,
          plan.radius_mm * plan.arc_deg * kDeg / speed};
}

double programmedAngle(const CirclePlan& plan, CircleDirection direction, double t_s) {
  const double omega = plan.feed_mm_per_min / 60.0 / plan.radius_mm;
  return startAngle(plan, direction) + static_cast<int>(direction) * omega * (t_s - measuringWindow(plan).first);
}

std::string circleGcode(const CirclePlan& plan) {
  const auto a = processing::planeAxes(plan.plane);
  const char* names = "XYZ";
  const char* centre_words = "IJK";
  const char* plane_code = plan.plane == processing::Plane::kXY   ? "G17"
                           : plan.plane == processing::Plane::kZX ? "G18"
                                                                  : "G19";
  std::ostringstream g;
  g << "%\n";
  g << fmt::format("(mtcal circular test: {})\n", gcodeCommentText(plan.name));
  g << fmt::format(
      "({} plane, radius {} mm, centre X{:.4f} Y{:.4f} Z{:.4f}, F{:.0f} mm/min, arc {} deg + overshoot {} deg)\n",
      processing::planeName(plan.plane), plan.radius_mm, plan.centre_mm.x(), plan.centre_mm.y(), plan.centre_mm.z(),
      plan.feed_mm_per_min, plan.arc_deg, plan.overshoot_deg);
  g << "(mount the ballbar at the centre before cycle start)\n";
  g << gcodeDwellComment(plan.gcode_dialect);
  g << fmt::format("G21 G90 G94 {}\n", plane_code);
  for (CircleDirection d : plan.directions) {
    const auto path = circlePath(plan, d);
    const Eigen::Vector3d s = path.start();
    g << (d == CircleDirection::kCcw ? "(counter-clockwise run)\n" : "(clockwise run)\n");
    g << fmt::format("G0 {}{:.4f} {}{:.4f}\n", names[a.first], s(a.first), names[a.second], s(a.second));
    g << fmt::format("G0 {}{:.4f}\n", names[a.normal], s(a.normal));
    for (const auto& seg : path.segments()) {
      // Arcs of more than a turn are written in turns of at most 180 degrees each.
      const int pieces = static_cast<int>(std::ceil(std::abs(seg.sweep_rad) / kPi - 1e-9));
      Eigen::Vector3d from = seg.start_mm;
      for (int k = 1; k <= pieces; ++k) {
        const Eigen::Vector3d to =
            processing::rotateInPlane(seg.start_mm, seg.centre_mm, seg.plane, seg.sweep_rad * k / pieces);
        g << fmt::format("{} {}{:.4f} {}{:.4f} {}{:.4f} {}{:.4f}", seg.sweep_rad > 0 ? "G3" : "G2", names[a.first],
                         to(a.first), names[a.second], to(a.second), centre_words[a.first],
                         seg.centre_mm(a.first) - from(a.first), centre_words[a.second],
                         seg.centre_mm(a.second) - from(a.second));
        g << (k == 1 && &seg == &path.segments().front() ? fmt::format(" F{:.0f}\n", plan.feed_mm_per_min) : "\n");
        from = to;
      }
    }
    g << gcodeDwell(plan.gcode_dialect, 2.0) << " (pause between directions)\n";
  }
  g << "M30\n%\n";
  return g.str();
}

}  // namespace mtcal::acquisition
