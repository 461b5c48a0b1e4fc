#include "mtcal/acquisition/circle_run.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <chrono>
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

}  // namespace

CircleRunResult runCircleTest(storage::Store& store, storage::Id campaign_id, drivers::ballbar::BallbarDevice& bar,
                              MachineController& controller, const CirclePlan& plan, const CircleRunOptions& options) {
  const auto a = processing::planeAxes(plan.plane);
  const std::string axis_names[3] = {"X", "Y", "Z"};
  RunClock& clock = options.run_clock ? *options.run_clock : realTime();
  storage::NewRun run;
  run.campaign_id = campaign_id;
  run.instrument_id = store.ensureInstrument(
      {bar.info().kind, bar.info().model, bar.info().serial, bar.info().firmware, bar.info().uri});
  run.kind = storage::run_kind::kCircle;
  run.axis = processing::planeName(plan.plane);
  run.name = plan.name;
  run.plan_json = plan.toJson().dump();
  run.software_version = options.software_version;
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
  bar.startStream(plan.sample_rate_hz, log);
  std::size_t committed_samples = 0;
  try {
    const auto [in_s, arc_s] = measuringWindow(plan);
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
            "this machine controller cannot follow a contour: run the part program (`mtcal plan gcode`) on "
            "the CNC; a triggered capture of circles is not built yet");
      }
      waitForDeviceTime(log, bar, clock, plan.sample_rate_hz, times->second,
                        std::chrono::seconds(static_cast<long>(path.durationS() * 10 + 120)));
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
            throw DeviceError(
                fmt::format("ballbar over range at {:.1f} deg of the {} run: check the bar's set-up "
                            "(centre, length) and the feed-in",
                            angle_deg, processing::directionName(d)));
          }
          points.push_back({processing::directionName(d), static_cast<std::int64_t>(points.size()), angle_deg,
                            s.value * 1000.0, t - in_s});
        }
        committed_samples = log.samples.size();
      }
      if (points.size() < 3)
        throw DeviceError(
            fmt::format("{} run: only {} samples in the measuring arc", processing::directionName(d), points.size()));
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
    recordInterruption(store, result.run_id, "error", std::string("run interrupted: ") + e.what());
  }
  return result;
}

}  // namespace mtcal::acquisition
