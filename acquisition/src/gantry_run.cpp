#include "mtcal/acquisition/gantry_run.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <initializer_list>
#include <mutex>
#include <nlohmann/json.hpp>
#include <set>
#include <utility>
#include <vector>

#include "gantry_stored_run.h"
#include "mtcal/error.h"
#include "resume_run.h"
#include "sample_log.h"
#include "stop_after_failure.h"

namespace mtcal::acquisition {
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

storage::TrackerPointRecord record(const std::string& feature, const std::string& place,
                                   const drivers::tracker::Point& p, int integration_ms) {
  return {feature, place, p.xyz_mm[0], p.xyz_mm[1], p.xyz_mm[2], p.time_s, integration_ms};
}

}  // namespace

GantryRunResult runGantryTest(storage::Store& store, storage::Id campaign_id, drivers::tracker::TrackerDevice& tracker,
                              MachineController& controller, const GantryPlan& plan,
                              const processing::MultibodyModel& kinematics, const GantryRunOptions& options) {
  if (!options.place_reflector) throw InputError("gantry run: nobody to place the reflector (no operator callback)");
  const auto holes = planHoles(plan, kinematics);
  RunClock& clock = options.run_clock ? *options.run_clock : realTime();
  const nlohmann::json expanded = gantry_stored_run::expandedPlan(plan, kinematics, holes);
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
  // A resumed run keeps the features it stored (each was committed whole).
  std::set<std::string> stored;
  if (options.resume_run) {
    runToResume(store, *options.resume_run, storage::run_kind::kGantry, "gantry run");
    for (const auto& p : store.trackerPoints(*options.resume_run)) stored.insert(p.feature);
    takeOverRun(store, *options.resume_run, fmt::format("{} features", stored.size()));
    result.run_id = *options.resume_run;
  } else {
    result.run_id = store.addRun(run);
  }
  const auto measured = [&](const std::string& feature) { return stored.contains(feature); };
  Recorder rec{store, result.run_id};
  std::size_t features = static_cast<std::size_t>(plan.passes) + 2 + 1 + holes.size(),
              started = 0;  // passes, sweeps, initial, holes
  for (const auto& corner : plan.corners) features += corner == plan.origin_corner ? 3 : 1;
  const auto progress = [&](const std::string& what) {
    if (options.stop_requested && *options.stop_requested) throw InputError("stopped by the user");
    if (options.on_progress) options.on_progress(started, features, what);
    ++started;
    spdlog::info("gantry run: {}", what);
  };
  const auto stationary = [&](const std::string& feature, const std::string& place, int count,
                              std::vector<storage::TrackerPointRecord>& out) {
    for (int i = 0; i < count; ++i)
      out.push_back(record(feature, place, tracker.measure(plan.integration_ms), plan.integration_ms));
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
    whileStreaming(tracker, plan.track_rate_hz, log, [&] {
      waitForDeviceTime(log, tracker, clock, plan.track_rate_hz, *in_position_s + plan.settle_s,
                        std::chrono::seconds(600));
    });
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
      for (const auto& face : plan.facesAt(corner)) {
        if (measured(fmt::format("corner:{}:{}", corner, face))) {
          ++started;
          continue;
        }
        progress(fmt::format("corner {} {}", corner, face));
        const std::string place = GantryPlan::cornerFace(corner, face);
        options.place_reflector(place);
        std::vector<storage::TrackerPointRecord> points;
        stationary(fmt::format("corner:{}:{}", corner, face), place, plan.points_per_face, points);
        rec.commit(points);
      }
    }
    // 2. The gantry's line, tracked back and forth.
    options.place_reflector(plan.sweep_target);
    settle(
        moveAll(
            {{"A", 0.0}, {"C", 0.0}, {"Y", plan.initial_mm[1]}, {"Z", plan.initial_mm[2]}, {"X", plan.gantry_from_mm}}),
        fmt::format("the start of the passes: X {} Y {} Z {} A 0 C 0", plan.gantry_from_mm, plan.initial_mm[1],
                    plan.initial_mm[2]));
    bool at_pass_start = true;  // the machine stands where the next pass starts
    for (int pass = 1; pass <= plan.passes; ++pass) {
      const bool forward = gantry_stored_run::passDirection(pass) > 0;
      // The pass as a contouring move at the plan's feed (the controller reports when it
      // starts and ends); the points of that window make the line.
      const double from = forward ? plan.gantry_from_mm : plan.gantry_to_mm,
                   to = forward ? plan.gantry_to_mm : plan.gantry_from_mm;
      if (measured(gantry_stored_run::passFeature(pass))) {
        ++started;
        at_pass_start = false;
        continue;
      }
      if (!at_pass_start) settle(moveAll({{"X", from}}), fmt::format("the start of gantry pass {}: X {}", pass, from));
      at_pass_start = true;
      progress(fmt::format("gantry pass {} of {}", pass, plan.passes));
      processing::ContourPath path(Eigen::Vector3d(from, plan.initial_mm[1], plan.initial_mm[2]));
      path.lineTo(Eigen::Vector3d(to, plan.initial_mm[1], plan.initial_mm[2]), plan.track_feed_mm_per_min);
      SampleLog log;
      std::vector<storage::TrackerPointRecord> points;
      std::optional<std::pair<double, double>> window;
      whileStreaming(tracker, plan.track_rate_hz, log, [&] {
        window = controller.followPath(path);
        if (window) {
          waitForDeviceTime(log, tracker, clock, plan.track_rate_hz, window->second + plan.settle_s,
                            std::chrono::seconds(600));
        } else {
          confirm(fmt::format("gantry pass {}: X {} to {} at F{} (tracking {}), stopped at the end", pass, from, to,
                              plan.track_feed_mm_per_min, plan.sweep_target));
          // Every point up to the confirmation, when the instruments' time is known.
          if (const auto now_s = clock.nowS())
            waitForDeviceTime(log, tracker, clock, plan.track_rate_hz, *now_s, std::chrono::seconds(600));
        }
      });
      {
        std::lock_guard lock(log.mutex);
        for (std::size_t i = 0; i + 2 < log.samples.size(); i += 3) {
          const auto& s = log.samples;
          const double t = static_cast<double>(s[i].device_time_ns) * 1e-9;
          // After the start (a point at the very start instant may belong to the rest before it).
          if (window && (t <= window->first + 1e-6 || t > window->second + 1e-9)) continue;
          points.push_back({gantry_stored_run::passFeature(pass), plan.sweep_target, s[i].value, s[i + 1].value,
                            s[i + 2].value, t, std::nullopt});
        }
      }
      if (points.size() < 10)
        throw DeviceError(fmt::format("gantry pass {}: only {} points tracked", pass, points.size()));
      rec.commit(points);
    }
    // 3. The rotary axes, one target each, at the initial state.
    // Every axis named: a resumed run's machine starts wherever it was left.
    settle(
        moveAll(
            {{"A", 0.0}, {"C", 0.0}, {"Y", plan.initial_mm[1]}, {"Z", plan.initial_mm[2]}, {"X", plan.initial_mm[0]}}),
        fmt::format("the initial state: X {} Y {} Z {} A 0 C 0", plan.initial_mm[0], plan.initial_mm[1],
                    plan.initial_mm[2]));
    for (const auto& [axis, angles] : {std::pair{"C", plan.c_sweep_deg}, std::pair{"A", plan.a_sweep_deg}}) {
      if (measured(std::string(axis == std::string("C") ? "c" : "a") + "-sweep")) {
        ++started;
        continue;
      }
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
    if (measured("initial")) {
      ++started;
    } else {
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
    }
    // 5. The holes.
    for (const auto& h : holes) {
      if (measured("hole:" + h.id)) {
        ++started;
        continue;
      }
      progress(fmt::format("hole {} ({} of {})", h.id, &h - holes.data() + 1, holes.size()));
      settle(moveAll({{"C", h.c_deg}, {"A", h.a_deg}, {"X", h.x_mm}, {"Y", h.y_mm}, {"Z", h.z_mm}}),
             fmt::format("hole {}: X {:.3f} Y {:.3f} Z {:.3f} A {:.3f} C {:.3f}", h.id, h.x_mm, h.y_mm, h.z_mm, h.a_deg,
                         h.c_deg));
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
    recordInterruption(store, result.run_id, "error", std::string("run interrupted: ") + e.what());
  }
  result.points = rec.points;
  return result;
}

}  // namespace mtcal::acquisition
