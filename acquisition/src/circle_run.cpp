#include "mtcal/acquisition/circle_run.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <limits>
#include <mutex>
#include <nlohmann/json.hpp>
#include <numbers>
#include <optional>
#include <set>
#include <vector>

#include "mtcal/error.h"
#include "resume_run.h"
#include "sample_log.h"
#include "stop_after_failure.h"

namespace mtcal::acquisition {
namespace {

using processing::CircleDirection;
constexpr double kDeg = std::numbers::pi / 180.0;

/// Stores the measuring arc of direction `d`: the samples of `log` from `committed` up to
/// `end` (clamped to those there are), each by the programmed angle at its device time, the
/// path having started at device time `path_start_s`, with the raw samples, in one transaction.
/// `committed` moves to the end. @return the points stored
/// @throws DeviceError for a sample over range in the measuring arc or fewer than 3 points
std::size_t storeDirection(storage::Store& store, storage::Id run_id, const CirclePlan& plan, CircleDirection d,
                           SampleLog& log, std::size_t& committed, std::size_t end, double path_start_s) {
  const auto [in_s, arc_s] = measuringWindow(plan);
  std::vector<storage::CirclePointRecord> points;
  std::vector<storage::SampleRecord> raw;
  {
    std::lock_guard lock(log.mutex);
    end = std::min(end, log.samples.size());
    for (std::size_t i = committed; i < end; ++i) {
      const auto& s = log.samples[i];
      raw.push_back({s.seq, s.device_time_ns, s.value, s.signal_pct});
      const double t = static_cast<double>(s.device_time_ns) * 1e-9 - path_start_s;
      if (t < in_s || t > in_s + arc_s) continue;
      const double angle_deg = programmedAngle(plan, d, t) / kDeg;
      if (!s.beam_ok) {
        throw DeviceError(
            fmt::format("ballbar over range at {:.1f} deg of the {} run: check the bar's set-up "
                        "(centre, length) and the feed-in",
                        angle_deg, processing::directionName(d)));
      }
      points.push_back({processing::directionName(d), static_cast<std::int64_t>(points.size()), angle_deg,
                        s.value * 1000.0, t - in_s});
    }
    committed = end;
  }
  if (points.size() < 3)
    throw DeviceError(
        fmt::format("{} run: only {} samples in the measuring arc", processing::directionName(d), points.size()));
  storage::Transaction tx(store.database());
  store.appendSamples(run_id, raw);
  store.addCirclePoints(run_id, points);
  tx.commit();
  spdlog::info("circle {} run: {} points", processing::directionName(d), points.size());
  return points.size();
}

/// Streams the bar into `log` while `measure` stores the directions, then completes the run.
/// An error stops the bar and marks the run interrupted with the reason (the directions stored
/// stay).
void measureStreaming(storage::Store& store, drivers::ballbar::BallbarDevice& bar, const CirclePlan& plan,
                      SampleLog& log, CircleRunResult& result, const std::function<void()>& measure) {
  bar.startStream(plan.sample_rate_hz, log);
  try {
    measure();
    result.stats = bar.stopStream();
    store.setRunStatus(result.run_id, storage::run_status::kCompleted);
  } catch (const Error& e) {
    if (const auto stats = stopAfterFailure(bar)) result.stats = *stats;
    result.outcome = RunOutcome::kInterrupted;
    result.reason = e.what();
    recordInterruption(store, result.run_id, "error", std::string("run interrupted: ") + e.what());
  }
}

/// The run's row, the plan as it is stored.
storage::NewRun circleRunRow(storage::Store& store, storage::Id campaign_id, drivers::ballbar::BallbarDevice& bar,
                             const nlohmann::json& plan_json, const CirclePlan& plan, const std::string& version) {
  storage::NewRun run;
  run.campaign_id = campaign_id;
  run.instrument_id = store.ensureInstrument(
      {bar.info().kind, bar.info().model, bar.info().serial, bar.info().firmware, bar.info().uri});
  run.kind = storage::run_kind::kCircle;
  run.axis = processing::planeName(plan.plane);
  run.name = plan.name;
  run.plan_json = plan_json.dump();
  run.software_version = version;
  return run;
}

}  // namespace

CircleRunResult runCircleTest(storage::Store& store, storage::Id campaign_id, drivers::ballbar::BallbarDevice& bar,
                              MachineController& controller, const CirclePlan& plan, const CircleRunOptions& options) {
  const auto a = processing::planeAxes(plan.plane);
  const std::string axis_names[3] = {"X", "Y", "Z"};
  RunClock& clock = options.run_clock ? *options.run_clock : realTime();
  const storage::NewRun run = circleRunRow(store, campaign_id, bar, plan.toJson(), plan, options.software_version);
  CircleRunResult result;
  // A resumed run keeps the directions it stored; a live owner is refused before anything moves.
  std::set<std::string> stored_directions;
  std::size_t stored_points = 0;
  if (options.resume_run) {
    runToResume(store, *options.resume_run, storage::run_kind::kCircle, "circular test");
    for (const auto& p : store.circlePoints(*options.resume_run)) {
      stored_directions.insert(p.direction);
      ++stored_points;
    }
    takeOverRun(store, *options.resume_run,
                fmt::format("{} of {} directions", stored_directions.size(), plan.directions.size()));
  }
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
      if (at_centre)
        waitForDeviceTime(settle, bar, clock, plan.sample_rate_hz, *at_centre + plan.settle_s,
                          std::chrono::seconds(120));
    } catch (...) {
      bar.stopStream();
      throw;
    }
    bar.stopStream();
    if (options.mount_bar) options.mount_bar();
  }
  result.run_id = options.resume_run ? *options.resume_run : store.addRun(run);
  SampleLog log;
  std::size_t committed_samples = 0;
  measureStreaming(store, bar, plan, log, result, [&] {
    std::size_t directions_done = stored_directions.size();
    result.points = stored_points;
    if (options.on_progress) options.on_progress(directions_done, plan.directions.size(), 0);
    for (CircleDirection d : plan.directions) {
      if (stored_directions.contains(processing::directionName(d))) continue;
      if (options.stop_requested && *options.stop_requested) throw InputError("stopped by the user");
      const auto path = circlePath(plan, d);
      const Eigen::Vector3d start = path.start();
      for (int i : {a.first, a.second, a.normal}) controller.moveTo(axis_names[i], start(i));
      const auto times = controller.followPath(path);
      if (!times) {
        throw InputError(
            "this machine controller cannot follow a contour: the CNC runs the part program (`mtcal plan gcode`) "
            "and the test is captured from it (runTriggeredCircleTest)");
      }
      waitForDeviceTime(log, bar, clock, plan.sample_rate_hz, times->second,
                        std::chrono::seconds(static_cast<long>(path.durationS() * 10 + 120)));
      const std::size_t points = storeDirection(store, result.run_id, plan, d, log, committed_samples,
                                                std::numeric_limits<std::size_t>::max(), times->first);
      result.points += points;
      if (options.on_progress) options.on_progress(++directions_done, plan.directions.size(), points);
    }
  });
  return result;
}

CircleRunResult runTriggeredCircleTest(storage::Store& store, storage::Id campaign_id,
                                       drivers::ballbar::BallbarDevice& bar, const CirclePlan& plan,
                                       const CircleRunOptions& options) {
  if (options.resume_run) {
    throw InputError(
        "a circular test captured from the part program is not resumed: run the program again as a new test");
  }
  RunClock& clock = options.run_clock ? *options.run_clock : realTime();
  nlohmann::json plan_json = plan.toJson();
  plan_json["capture"] = "part program";
  const storage::NewRun run = circleRunRow(store, campaign_id, bar, plan_json, plan, options.software_version);
  if (plan.calibrator_length_mm) bar.zero(*plan.calibrator_length_mm);
  if (options.mount_bar) options.mount_bar();
  CircleRunResult result;
  result.run_id = store.addRun(run);
  SampleLog log;
  measureStreaming(store, bar, plan, log, result, [&] {
    if (options.on_progress) options.on_progress(0, plan.directions.size(), 0);
    if (options.on_waiting_for_program) options.on_waiting_for_program();
    const double speed = plan.feed_mm_per_min / 60.0, half = plan.feed_in_mm / 2.0;
    // The bar's deviation (mm) in the middle of the feed-in and feed-out semicircles.
    const double level_mm = std::hypot(plan.radius_mm - half, half) - plan.radius_mm;
    const double to_middle_s = std::numbers::pi * half / 2.0 / speed;
    const double sweep_rad = (plan.arc_deg + 2.0 * plan.overshoot_deg) * kDeg;
    const double between_s = (std::numbers::pi * half + plan.radius_mm * sweep_rad) / speed;
    std::size_t scanned = 1, committed = 0, done = 0;
    const auto latestS = [&]() -> std::optional<double> {
      std::lock_guard lock(log.mutex);
      if (log.samples.empty()) return clock.nowS();
      return static_cast<double>(log.samples.back().device_time_ns) * 1e-9;
    };
    for (CircleDirection d : plan.directions) {
      const std::string name = processing::directionName(d);
      const double waiting_since_s = latestS().value_or(0.0);
      const double feed_in_within_s = done == 0 ? options.program_start_timeout_s : 3.0 * between_s + 60.0;
      std::optional<double> in_s, out_s;
      std::size_t out_index = 0;
      while (!out_s) {
        if (options.stop_requested && *options.stop_requested) throw InputError("stopped by the user");
        const double now_s = latestS().value_or(0.0);
        if (!in_s && now_s > waiting_since_s + feed_in_within_s) {
          // What the bar read meanwhile, for the operator.
          double lowest = std::numeric_limits<double>::infinity(), highest = -lowest;
          std::size_t in_range = 0;
          {
            std::lock_guard lock(log.mutex);
            for (std::size_t i = committed; i < log.samples.size(); ++i) {
              if (!log.samples[i].beam_ok) continue;
              ++in_range;
              lowest = std::min(lowest, log.samples[i].value);
              highest = std::max(highest, log.samples[i].value);
            }
          }
          throw TimeoutError(fmt::format(
              "no feed-in of the {} run within {:.0f} s: is the part program of this plan running (mtcal plan "
              "gcode)? The bar must pass {:.3f} mm on the way out to the circle; it read {}",
              name, feed_in_within_s, level_mm,
              in_range == 0 ? std::string("nothing in its range")
                            : fmt::format("{:.3f} to {:.3f} mm ({} samples in range)", lowest, highest, in_range)));
        }
        if (in_s && now_s > *in_s + 2.0 * between_s + 10.0) {
          throw DeviceError(
              fmt::format("the {} run's feed-out did not come {:.1f} s after its feed-in (the plan's "
                          "path takes {:.1f} s): was the program stopped?",
                          name, now_s - *in_s, between_s));
        }
        waitForDeviceTime(log, bar, clock, plan.sample_rate_hz, now_s + 0.5, std::chrono::seconds(120));
        std::lock_guard lock(log.mutex);
        for (; scanned < log.samples.size() && !out_s; ++scanned) {
          const auto& a = log.samples[scanned - 1];
          const auto& b = log.samples[scanned];
          if (!a.beam_ok || !b.beam_ok) continue;
          const double ta = static_cast<double>(a.device_time_ns) * 1e-9;
          const double tb = static_cast<double>(b.device_time_ns) * 1e-9;
          const double crossing = ta + (level_mm - a.value) / (b.value - a.value) * (tb - ta);
          if (!in_s && a.value < level_mm && b.value >= level_mm) {
            in_s = crossing;
          } else if (in_s && a.value >= level_mm && b.value < level_mm) {
            out_s = crossing;
            out_index = scanned;
          }
        }
      }
      const double measured_s = *out_s - *in_s;
      store.logEvent(result.run_id, "info",
                     fmt::format("{} run: feed-in at {:.4f} s, feed-out at {:.4f} s of the bar's time: {:.4f} s "
                                 "apart, the plan's path {:.4f} s",
                                 name, *in_s, *out_s, measured_s, between_s));
      if (std::abs(measured_s / between_s - 1.0) > 0.01) {
        throw InputError(fmt::format(
            "the {} run took {:.3f} s from feed-in to feed-out where this plan's path at F{:.0f} takes {:.3f} s: run "
            "this plan's program (mtcal plan gcode) at 100 % feed override",
            name, measured_s, plan.feed_mm_per_min, between_s));
      }
      const std::size_t points =
          storeDirection(store, result.run_id, plan, d, log, committed, out_index, *in_s - to_middle_s);
      result.points += points;
      if (options.on_progress) options.on_progress(++done, plan.directions.size(), points);
    }
  });
  return result;
}

}  // namespace mtcal::acquisition
