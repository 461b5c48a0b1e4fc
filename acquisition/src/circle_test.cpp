#include "mtcal/acquisition/circle_test.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <cmath>
#include <condition_variable>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <numbers>
#include <set>
#include <sstream>
#include <thread>

#include "stop_after_failure.h"
#include "mtcal/acquisition/columns_csv.h"
#include "mtcal/error.h"
#include "mtcal/acquisition/gcode.h"
#include "plan_json.h"
#include "sample_log.h"

namespace mtcal::acquisition {
namespace {

using plan_json::bad;
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
  if (j.contains("centre_mm")) {
    const auto& c = j["centre_mm"];
    if (!c.is_array() || c.size() != 3) bad(source, "centre_mm", "must be [x, y, z] in mm");
    for (int i = 0; i < 3; ++i) {
      if (!c[static_cast<std::size_t>(i)].is_number()) bad(source, "centre_mm", "must be [x, y, z] in mm");
      p.centre_mm(i) = c[static_cast<std::size_t>(i)].get<double>();
    }
  }
  if (j.contains("directions")) {
    const auto& d = j["directions"];
    if (!d.is_array() || d.empty() || d.size() > 2) bad(source, "directions", "must be [\"ccw\", \"cw\"] or one of them");
    p.directions.clear();
    for (const auto& v : d) {
      if (!v.is_string()) bad(source, "directions", "must hold \"ccw\" and/or \"cw\"");
      try {
        p.directions.push_back(processing::parseDirection(v.get<std::string>()));
      } catch (const InputError& e) {
        bad(source, "directions", e.what());
      }
    }
    if (p.directions.size() == 2 && p.directions[0] == p.directions[1]) bad(source, "directions", "names a direction twice");
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
  plan_json::positive(p.feed_mm_per_min, source, "feed_mm_per_min");
  if (!(p.arc_deg >= 90.0 && p.arc_deg <= 360.0)) bad(source, "arc_deg", "must be 90..360 (a partial arc of at least a quarter)");
  if (!(p.overshoot_deg >= 5.0 && p.overshoot_deg <= 180.0)) bad(source, "overshoot_deg", "must be 5..180 (the servo settles from the feed-in there)");
  if (!(p.feed_in_mm > 0.0 && p.feed_in_mm < p.radius_mm)) bad(source, "feed_in_mm", "must be > 0 and less than the radius");
  if (p.sample_rate_hz < 1 || p.sample_rate_hz > drivers::ballbar::kMaxRateHz) bad(source, "sample_rate_hz", "must be 1..1000");
  plan_json::nonNegative(p.settle_s, source, "settle_s");
  if (p.gcode_dialect != "iso") bad(source, "gcode_dialect", "only 'iso' is written for circular tests");
  return p;
}

nlohmann::json CirclePlan::toJson() const {
  nlohmann::json dirs = nlohmann::json::array();
  for (auto d : directions) dirs.push_back(processing::directionName(d));
  return {{"type", "circle"},
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
  const char* plane_code = plan.plane == processing::Plane::kXY ? "G17" : plan.plane == processing::Plane::kZX ? "G18" : "G19";
  std::ostringstream g;
  g << "%\n";
  g << fmt::format("(mtcal circular test: {})\n", plan.name);
  g << fmt::format("({} plane, radius {} mm, centre X{:.4f} Y{:.4f} Z{:.4f}, F{:.0f} mm/min, arc {} deg + overshoot {} deg)\n",
                   processing::planeName(plan.plane), plan.radius_mm, plan.centre_mm.x(), plan.centre_mm.y(),
                   plan.centre_mm.z(), plan.feed_mm_per_min, plan.arc_deg, plan.overshoot_deg);
  g << "(mount the ballbar at the centre before cycle start)\n";
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
        const Eigen::Vector3d to = processing::rotateInPlane(seg.start_mm, seg.centre_mm, seg.plane, seg.sweep_rad * k / pieces);
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

std::vector<processing::CirclePoint> toCirclePoints(const std::vector<storage::CirclePointRecord>& records) {
  std::vector<processing::CirclePoint> out;
  for (const auto& r : records) out.push_back({processing::parseDirection(r.direction), r.angle_deg * kDeg, r.deviation_um});
  return out;
}

CircleRunResult runCircleTest(storage::Store& store, storage::Id campaign_id, drivers::ballbar::BallbarDevice& bar,
                              MachineController& controller, const CirclePlan& plan, const CircleRunOptions& options) {
  const auto a = processing::planeAxes(plan.plane);
  const std::string axis_names[3] = {"X", "Y", "Z"};
  RunClock& clock = options.run_clock ? *options.run_clock : realTime();
  storage::NewRun run;
  run.campaign_id = campaign_id;
  run.instrument_id = store.ensureInstrument({bar.info().kind, bar.info().model, bar.info().serial, bar.info().firmware, bar.info().uri});
  run.kind = "circle";
  run.axis = processing::planeName(plan.plane);
  run.name = plan.name;
  run.plan_json = plan.toJson().dump();
  run.software_version = options.software_version;
  CircleRunResult result;
  {
    // Moves to the centre: the table ball is set there, the bar mounted.
    std::optional<double> at_centre;
    for (int i : {a.normal, a.first, a.second}) {
      at_centre = controller.moveTo(axis_names[i], plan.centre_mm(i));
    }
    if (plan.calibrator_length_mm) bar.zero(*plan.calibrator_length_mm);
    SampleLog settle;
    bar.startStream(plan.sample_rate_hz, settle);
    try {
      if (at_centre) waitForDeviceTime(settle, bar, clock, plan.sample_rate_hz, *at_centre + plan.settle_s, std::chrono::seconds(120));
    } catch (...) {
      bar.stopStream();
      throw;
    }
    bar.stopStream();
    if (options.mount_bar) options.mount_bar();
  }
  result.run_id = store.addRun(run);
  SampleLog log;
  bar.startStream(plan.sample_rate_hz, log);
  std::size_t committed_samples = 0;
  try {
    const auto [in_s, arc_s] = measuringWindow(plan);
    std::size_t directions_done = 0;
    for (CircleDirection d : plan.directions) {
      if (options.stop_requested && *options.stop_requested) throw InputError("stopped by the user");
      const auto path = circlePath(plan, d);
      const Eigen::Vector3d start = path.start();
      for (int i : {a.first, a.second, a.normal}) controller.moveTo(axis_names[i], start(i));
      const auto times = controller.followPath(path);
      if (!times) {
        throw InputError("this machine controller cannot follow a contour: run the part program (`mtcal plan gcode`) on "
                         "the CNC; a triggered capture of circles is not built yet");
      }
      waitForDeviceTime(log, bar, clock, plan.sample_rate_hz, times->second, std::chrono::seconds(static_cast<long>(path.durationS() * 10 + 120)));
      // The measuring arc's samples, by the programmed angle at their device time.
      std::vector<storage::CirclePointRecord> points;
      std::vector<storage::SampleRecord> raw;
      {
        std::lock_guard lock(log.mutex);
        for (std::size_t i = committed_samples; i < log.samples.size(); ++i) {
          const auto& s = log.samples[i];
          raw.push_back({s.seq, s.device_time_ns, s.value, s.signal_pct});
          const double t = static_cast<double>(s.device_time_ns) * 1e-9 - times->first;
          if (t < in_s || t > in_s + arc_s) continue;
          const double angle_deg = programmedAngle(plan, d, t) / kDeg;
          if (!s.beam_ok) {
            throw DeviceError(fmt::format("ballbar over range at {:.1f} deg of the {} run: check the bar's set-up "
                                          "(centre, length) and the feed-in",
                                          angle_deg, processing::directionName(d)));
          }
          points.push_back({processing::directionName(d), static_cast<std::int64_t>(points.size()), angle_deg,
                            s.value * 1000.0, t - in_s});
        }
        committed_samples = log.samples.size();
      }
      if (points.size() < 3) throw DeviceError(fmt::format("{} run: only {} samples in the measuring arc",
                                                           processing::directionName(d), points.size()));
      storage::Transaction tx(store.database());
      store.appendSamples(result.run_id, raw);
      store.addCirclePoints(result.run_id, points);
      tx.commit();
      result.points += points.size();
      spdlog::info("circle {} run: {} points", processing::directionName(d), points.size());
      if (options.on_progress) {
        options.on_progress(++directions_done, plan.directions.size(), points.size());
      }
    }
    result.stats = bar.stopStream();
    store.setRunStatus(result.run_id, storage::run_status::kCompleted);
  } catch (const Error& e) {
    if (const auto stats = stopAfterFailure(bar)) result.stats = *stats;
    result.outcome = RunOutcome::kInterrupted;
    result.reason = e.what();
    store.setRunStatus(result.run_id, storage::run_status::kInterrupted);
    store.logEvent(result.run_id, "error", std::string("run interrupted: ") + e.what());
  }
  return result;
}

storage::Id importCircleCsv(storage::Store& store, const std::string& path, const CircleImportOptions& options) {
  if (!(options.radius_mm > 0.0)) throw InputError("--radius-mm must be > 0");
  if (!(options.feed_mm_per_min > 0.0)) throw InputError("--feed-mm-min must be > 0");
  std::ifstream in(path);
  if (!in) throw InputError(path + ": cannot open file");
  const auto table = readColumnTable(in, path, {"angle_deg", "deviation_um"}, {"time_s"}, {"direction"});
  const auto& angle = table.numbers.at("angle_deg");
  const auto& deviation = table.numbers.at("deviation_um");
  const auto time = table.numbers.find("time_s");
  std::vector<storage::CirclePointRecord> points;
  std::map<std::string, std::int64_t> count;
  for (std::size_t i = 0; i < angle.size(); ++i) {
    std::string direction;
    try {
      direction = processing::directionName(processing::parseDirection(table.texts.at("direction")[i]));
    } catch (const InputError& e) {
      throw InputError(fmt::format("{}:{}: column 'direction': {}", path, table.lines[i], e.what()));
    }
    if (std::abs(deviation[i]) > 0.5 * options.radius_mm * 1000.0) {
      throw InputError(fmt::format("{}:{}: column 'deviation_um': {} um is not a deviation from a {} mm radius (um?)", path,
                                   table.lines[i], deviation[i], options.radius_mm));
    }
    points.push_back({direction, count[direction]++, angle[i], deviation[i],
                      time != table.numbers.end() ? std::optional<double>(time->second[i]) : std::nullopt});
  }
  for (const auto& [direction, n] : count) {
    if (n < 3) throw InputError(fmt::format("{}: the {} path has {} point(s), at least 3 needed", path, direction, n));
  }
  const std::string file_name = std::filesystem::path(path).filename().string();
  nlohmann::json plan = {{"type", "circle"},
                         {"plane", processing::planeName(options.plane)},
                         {"radius_mm", options.radius_mm},
                         {"feed_mm_per_min", options.feed_mm_per_min},
                         {"imported_from", file_name}};
  storage::Transaction tx(store.database());
  storage::NewRun run;
  run.campaign_id = store.addCampaign(store.ensureMachine(options.machine, "", "{}"), "import " + file_name);
  run.kind = "circle";
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
