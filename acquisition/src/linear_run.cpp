#include "mtcal/acquisition/linear_run.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <cmath>

#include "mtcal/acquisition/capture.h"
#include "mtcal/acquisition/sample_queue.h"
#include "mtcal/error.h"
#include "mtcal/processing/air_index.h"
#include "resume_run.h"
#include "stop_after_failure.h"

namespace mtcal::acquisition {

namespace ifm = drivers::interferometer;

// The running stream: queue + started device; stops the device when it goes out of scope.
struct LinearRun::Stream {
  Stream(ifm::InterferometerDevice& device, std::uint32_t rate_hz, std::size_t capacity)
      : device(device), queue(capacity, OverflowPolicy::kDropNewest) {
    device.startStream(rate_hz, queue);
  }
  ~Stream() {
    queue.close();
    stopAfterFailure(device);  // the error that unwound us is the one to report
  }
  drivers::StreamStats stop() {
    queue.close();
    return device.stopStream();
  }
  ifm::InterferometerDevice& device;
  SampleQueue queue;
  std::vector<drivers::Sample> pending;  // popped but not yet consumed, in time order
};

struct LinearRun::Capture {
  std::vector<drivers::Sample> window;
  WindowStats stats;
  int rejected_windows = 0;
};

std::optional<double> LineArrival::laterOf(std::optional<double> in_position_s) const {
  if (!time_known || !in_position_s) return std::nullopt;
  return latest_s ? std::max(*in_position_s, *latest_s) : in_position_s;
}

LineArrival moveToLine(MachineController& controller, const std::map<std::string, double>& line_position_mm) {
  LineArrival arrival;
  for (const auto& [axis, position_mm] : line_position_mm) {
    const auto t = controller.moveTo(axis, position_mm);
    arrival.time_known = arrival.time_known && t.has_value();
    if (t) arrival.latest_s = std::max(arrival.latest_s.value_or(*t), *t);
  }
  return arrival;
}

LinearRun::LinearRun(storage::Store& store, ifm::InterferometerDevice& device, MachineController* controller,
                     LinearRunOptions options)
    : store_(store),
      device_(device),
      controller_(controller),
      options_(std::move(options)),
      clock_(options_.run_clock ? *options_.run_clock : realTime()) {}

LinearRun::Capture LinearRun::slide(const LinearPlan& plan, std::optional<std::int64_t> from_ns, std::int64_t delay_ns,
                                    double timeout_s, const Judge& judge,
                                    const std::function<void(const WindowStats&)>& on_timeout) {
  auto& pending = stream_->pending;
  const auto window_n = static_cast<std::size_t>(std::llround(plan.window_s * plan.sample_rate_hz));
  const auto timeout_ns = std::llround(timeout_s * 1e9);
  const auto period_ns = std::llround(1e9 / plan.sample_rate_hz);
  // With no reading and no time to start from (a stream just started or cleared), the
  // instruments' time now says where the window's samples begin.
  const auto now_s = !from_ns && pending.empty() ? clock_.nowS() : std::nullopt;
  const auto anchor_ns = now_s ? std::optional<std::int64_t>(std::llround(*now_s * 1e9)) : std::nullopt;
  Capture result;
  std::size_t begin = 0;
  for (;;) {
    device_.poll();
    if (!from_ns && !pending.empty()) from_ns = pending.front().device_time_ns + delay_ns;
    if (from_ns) {
      while (begin < pending.size() && pending[begin].device_time_ns < *from_ns) ++begin;
    }
    if (pending.size() - begin < window_n) {
      if (begin > 0) {
        pending.erase(pending.begin(), pending.begin() + static_cast<std::ptrdiff_t>(begin));
        begin = 0;
      }
      // Only lost samples can leave a time span without a complete window.
      if (from_ns && !pending.empty() &&
          pending.back().device_time_ns > *from_ns + timeout_ns + std::llround(plan.window_s * 1e9)) {
        on_timeout(result.stats);
        throw DeviceError("no complete window within the timeout");  // on_timeout throws; this is a backstop
      }
      // Let the instruments get to the window's last sample, counted from the readings there
      // are (asked again while they are on their way, the time stays the same).
      const auto missing = static_cast<std::int64_t>(window_n - (pending.size() - begin));
      const auto base_ns = !pending.empty() ? std::optional(pending.back().device_time_ns)
                           : from_ns        ? from_ns
                                            : anchor_ns;
      if (base_ns) clock_.advanceTo(static_cast<double>(*base_ns + missing * period_ns) * 1e-9);
      stream_->queue.popBatch(pending, 1 << 16, std::chrono::milliseconds(100));
      continue;
    }
    const auto window = std::span(pending).subspan(begin, window_n);
    result.stats = windowStats(window, reading_to_um_);
    if (judge(result.stats, window) == Verdict::kAccept) {
      result.window.assign(window.begin(), window.end());
      pending.erase(pending.begin(), pending.begin() + static_cast<std::ptrdiff_t>(begin + window_n));
      return result;
    }
    ++result.rejected_windows;
    if (window.back().device_time_ns > *from_ns + timeout_ns) on_timeout(result.stats);
    begin += std::max<std::size_t>(1, window_n / 2);  // slide by half a window
  }
}

LinearRun::Capture LinearRun::capture(const LinearPlan& plan, std::optional<double> in_position_s,
                                      const std::string& what) {
  if (!in_position_s) {
    // Unknown in-position time: everything queued is from before the move.
    stream_->pending.clear();
    stream_->queue.clear();
  }
  const auto dwell_ns = std::llround(plan.dwell_s * 1e9);
  const auto from =
      in_position_s ? std::optional<std::int64_t>(std::llround(*in_position_s * 1e9) + dwell_ns) : std::nullopt;
  return slide(
      plan, from, dwell_ns, plan.stability_timeout_s,
      [&](const WindowStats& s, std::span<const drivers::Sample>) {
        return isStable(s, plan.stability_threshold_um) ? Verdict::kAccept : Verdict::kSlide;
      },
      [&](const WindowStats& last) {
        if (last.beam_lost > 0) {
          throw DeviceError(fmt::format("{}: laser beam lost ({} readings of a window without beam); check the optics",
                                        what, last.beam_lost));
        }
        throw DeviceError(
            fmt::format("{}: reading not stable within {} s (s = {:.2f} um, drift = {:.2f} um, "
                        "threshold {} um)",
                        what, plan.stability_timeout_s, last.stddev_um, last.drift_um, plan.stability_threshold_um));
      });
}

LinearRun::Arrival LinearRun::waitForArrival(const LinearPlan& plan, std::optional<double> target_mm,
                                             double datum_raw_mm, std::optional<double> previous_raw_mm,
                                             const std::string& what) {
  // Raw readings are optical path lengths: the index of standard air is close enough to
  // locate the machine within the tolerance band (n - 1 varies by 1e-5 in a workshop).
  constexpr double kNominalIndex = 1.00027;
  const double band_mm = triggerToleranceMm(plan);
  const auto expected_raw_mm =
      target_mm ? std::optional<double>(datum_raw_mm + (*target_mm - plan.datum_mm) * kNominalIndex) : std::nullopt;
  bool moved = false;
  std::optional<std::int64_t> hold_start_ns;
  double hold_raw_mm = 0.0;
  const auto dwell_ns = std::llround(plan.dwell_s * 1e9);
  slide(
      plan, std::nullopt, 0, plan.trigger_timeout_s,
      [&](const WindowStats& s, std::span<const drivers::Sample> window) {
        const bool stable = isStable(s, plan.stability_threshold_um);
        if (!moved) {
          // The machine must first leave where it was: a program that holds the same
          // position twice in a row (datum, then the first target) is not captured twice,
          // and a machine resting before the program starts is not taken for the datum.
          moved = !stable || (previous_raw_mm && std::abs(s.mean - *previous_raw_mm) > band_mm);
          return Verdict::kSlide;
        }
        const bool there = !expected_raw_mm || std::abs(s.mean - *expected_raw_mm) <= band_mm;
        if (!stable || !there) {
          hold_start_ns.reset();
          return Verdict::kSlide;
        }
        // A hold, not a pause: the position must stay put for a whole dwell. A CNC stops for
        // an instant at every reversal; the program holds a target for longer than this.
        if (!hold_start_ns || std::abs(s.mean - hold_raw_mm) > band_mm) {
          hold_start_ns = window.front().device_time_ns;
          hold_raw_mm = s.mean;
        }
        return window.back().device_time_ns - *hold_start_ns >= dwell_ns ? Verdict::kAccept : Verdict::kSlide;
      },
      [&](const WindowStats& last) {
        if (!target_mm) {
          throw DeviceError(
              fmt::format("{}: the machine did not move to and hold a position within {} s; start the "
                          "part program (mtcal plan gcode), which begins by approaching the datum",
                          what, plan.trigger_timeout_s));
        }
        throw DeviceError(fmt::format(
            "{}: the machine did not hold still within +-{:.2f} mm of it within {} s (last "
            "reading at {:.3f} mm); is the part program running?",
            what, band_mm, plan.trigger_timeout_s, plan.datum_mm + (last.mean - datum_raw_mm) / kNominalIndex));
      });
  return {static_cast<double>(*hold_start_ns) * 1e-9, hold_raw_mm};
}

LinearRun::Capture LinearRun::captureHeld(const LinearPlan& plan, const Arrival& arrival, const std::string& what) {
  Capture c = capture(plan, arrival.time_s, what);
  if (std::abs(c.stats.mean - arrival.raw_mm) > triggerToleranceMm(plan)) {
    throw DeviceError(
        fmt::format("{}: the machine left the position before it could be averaged (moved {:.3f} mm); "
                    "hold targets longer in the part program",
                    what, c.stats.mean - arrival.raw_mm));
  }
  return c;
}

storage::Id LinearRun::start(const LinearPlan& plan, storage::Id campaign_id,
                             std::optional<storage::Id> instrument_id) {
  storage::NewRun run;
  run.campaign_id = campaign_id;
  run.instrument_id = instrument_id;
  run.kind = storage::run_kind::kLinear;
  run.axis = plan.axis;
  run.name = plan.name;
  run.plan_json = plan.toJson().dump();
  run.status = storage::run_status::kRunning;
  run.source = "acquired";
  run.software_version = options_.software_version;
  run.compensation_json = options_.compensation_json;
  run.value_unit = measuredComponent(plan) >= 3 ? "urad" : "um";
  if (!controller_ && !measuresPositioning(plan)) {
    throw InputError(
        "a run triggered by a part program measures positioning only: an angle or straightness reading "
        "does not tell where the carriage is");
  }
  const storage::Id run_id = store_.addRun(run);
  execute(run_id, plan, {});
  return run_id;
}

void LinearRun::resume(storage::Id run_id) {
  const auto info = runToResume(store_, run_id, storage::run_kind::kLinear, "linear run");
  const LinearPlan plan =
      LinearPlan::fromJson(nlohmann::json::parse(info.plan_json), fmt::format("run {} plan", run_id));
  std::set<std::int64_t> done;
  for (const auto& t : store_.targets(run_id)) done.insert(t.seq);
  if (!controller_ && !done.empty()) {
    throw InputError(
        fmt::format("run {} was triggered by a part program: resuming it needs a program for the "
                    "remaining targets; start a new run instead",
                    run_id));
  }
  takeOverRun(store_, run_id, fmt::format("{} of {} targets", done.size(), linearTargets(plan).size()));
  execute(run_id, plan, done);
}

void LinearRun::execute(storage::Id run_id, const LinearPlan& plan, const std::set<std::int64_t>& done) {
  const auto moves = linearMoves(plan);
  const std::size_t total = linearTargets(plan).size();
  std::size_t completed = done.size();
  outcome_ = RunOutcome::kCompleted;
  const auto model =
      plan.air_index_model == "ciddor" ? processing::AirIndexModel::kCiddor : processing::AirIndexModel::kEdlen;
  const double wavelength_nm = device_.identity().vacuum_wavelength_nm;

  const int component = measuredComponent(plan);
  const bool positioning = measuresPositioning(plan);
  reading_to_um_ = component >= 3 ? 1.0 : 1000.0;
  try {
    device_.setOptics(positioning      ? ifm::Optics::kLinear
                      : component >= 3 ? ifm::Optics::kAngular
                                       : ifm::Optics::kStraightnessShort);
    Stream stream(device_, plan.sample_rate_hz, options_.queue_capacity);
    stream_ = &stream;
    struct Reset {
      Stream*& s;
      ~Reset() { s = nullptr; }
    } reset{stream_};

    // Datum: the raw reading at the datum position is the zero of every later reading.
    Capture datum;
    if (controller_) {
      // The measured line first; the datum is captured once every axis is in position.
      const LineArrival line = moveToLine(*controller_, plan.line_position_mm);
      controller_->moveTo(plan.axis, plan.datum_mm - plan.overrun_mm);
      datum = capture(plan, line.laterOf(controller_->moveTo(plan.axis, plan.datum_mm)), "datum");
    } else {
      // Triggered: the part program approaches the datum from below and holds it.
      if (options_.on_waiting_for_program) options_.on_waiting_for_program();
      datum = captureHeld(plan, waitForArrival(plan, std::nullopt, 0.0, std::nullopt, "datum"), "datum");
    }
    const double datum_raw_mm = datum.stats.mean;
    const char* reading_unit = component >= 3 ? "urad" : "mm";
    store_.logEvent(
        run_id, "info",
        fmt::format("datum at {:.4f} mm: raw reading {:.6f} {}", plan.datum_mm, datum_raw_mm, reading_unit));
    spdlog::info("run {}: datum at {:.4f} mm, raw reading {:.6f} {}", run_id, plan.datum_mm, datum_raw_mm,
                 reading_unit);
    const double run_start_s = static_cast<double>(datum.window.front().device_time_ns) * 1e-9;

    double previous_raw_mm = datum_raw_mm;
    bool warned_no_material = false;
    bool previous_executed = true;
    for (std::size_t i = 0; i < moves.size(); ++i) {
      const PlannedMove& move = moves[i];
      if (move.capture && done.count(move.target.seq)) {
        previous_executed = false;
        continue;
      }
      if (options_.stop_requested && options_.stop_requested->load()) {
        outcome_ = RunOutcome::kInterrupted;
        break;
      }
      if (controller_ && move.capture && !previous_executed && i > 0) {
        controller_->moveTo(plan.axis, moves[i - 1].position_mm);  // approach from the planned side
      }
      previous_executed = true;
      if (!move.capture) {
        if (controller_) controller_->moveTo(plan.axis, move.position_mm);
        continue;  // triggered: the program makes the overrun by itself
      }
      const PlannedTarget& t = move.target;
      const std::string what =
          fmt::format("target {:.3f} mm ({}, cycle {})", t.target_mm, t.direction > 0 ? "up" : "down", t.cycle);
      Capture c = controller_
                      ? capture(plan, controller_->moveTo(plan.axis, move.position_mm), what)
                      : captureHeld(plan, waitForArrival(plan, t.target_mm, datum_raw_mm, previous_raw_mm, what), what);
      previous_raw_mm = c.stats.mean;
      const ifm::Environment env = device_.readEnvironment();
      if (!env.air_temp_ok || !env.pressure_ok || !env.humidity_ok) {
        throw DeviceError(what + ": environment unit reports a failed sensor (air temperature, pressure or humidity)");
      }
      std::optional<double> material_c;
      if (!env.material_temps_c.empty()) {
        double sum = 0.0;
        for (double v : env.material_temps_c) sum += v;
        material_c = sum / static_cast<double>(env.material_temps_c.size());
      } else if (!warned_no_material) {
        store_.logEvent(run_id, "warning", "no material temperature sensor: readings are not normalised to 20 degC");
        warned_no_material = true;
      }
      storage::TargetRecord record;
      record.seq = t.seq;
      record.target_mm = t.target_mm;
      record.direction = t.direction;
      record.cycle = t.cycle;
      std::optional<double> n;
      if (positioning) {
        n = processing::airIndex(model, {env.air_temp_c, env.air_pressure_pa, env.humidity_pct, plan.co2_ppm},
                                 wavelength_nm);
        double length_mm = processing::compensateWavelength(c.stats.mean - datum_raw_mm, *n);
        if (material_c) length_mm = processing::normaliseTo20C(length_mm, *material_c, plan.expansion_per_k);
        record.measured_mm = plan.datum_mm + length_mm;
        record.deviation_um = (record.measured_mm - t.target_mm) * 1000.0;
      } else {
        // Straightness (mm -> um) or angle (urad) relative to the datum; the position along
        // the axis is the commanded one.
        record.measured_mm = t.target_mm;
        record.deviation_um = (c.stats.mean - datum_raw_mm) * (component >= 3 ? 1.0 : 1000.0);
      }
      record.time_s = static_cast<double>(c.window.front().device_time_ns) * 1e-9 - run_start_s;
      record.sample_count = static_cast<std::int64_t>(c.window.size());
      record.sample_stddev_um = c.stats.stddev_um;
      record.air_temp_c = env.air_temp_c;
      record.air_pressure_pa = env.air_pressure_pa;
      record.humidity_pct = env.humidity_pct;
      record.material_temp_c = material_c;
      record.air_index = n;
      std::vector<storage::SampleRecord> samples;
      samples.reserve(c.window.size());
      for (const auto& s : c.window) {
        samples.push_back({s.seq, s.device_time_ns, s.value, s.beam_ok ? s.signal_pct : -1});
      }
      storage::EnvironmentRecord environment;
      environment.device_time_ns = c.window.back().device_time_ns;
      environment.air_temp_c = env.air_temp_c;
      environment.air_pressure_pa = env.air_pressure_pa;
      environment.humidity_pct = env.humidity_pct;
      std::optional<double>* material[] = {&environment.material_temp1_c, &environment.material_temp2_c,
                                           &environment.material_temp3_c};
      for (std::size_t k = 0; k < env.material_temps_c.size() && k < 3; ++k) *material[k] = env.material_temps_c[k];
      {
        storage::Transaction tx(store_.database());  // the target, its samples and its environment, or nothing
        store_.addEnvironment(run_id, environment);
        store_.addTarget(run_id, record, samples);
        tx.commit();
      }
      spdlog::debug("run {}: {}: {:+.3f} {} ({} unstable windows)", run_id, what, record.deviation_um,
                    component >= 3 ? "urad" : "um", c.rejected_windows);
      if (c.rejected_windows > 0) {
        store_.logEvent(run_id, "info",
                        fmt::format("{}: {} unstable window(s) before capture", what, c.rejected_windows));
      }
      ++completed;
      if (options_.on_progress) {
        options_.on_progress({completed, total, t.target_mm, t.direction, t.cycle, record.deviation_um});
      }
    }
    const auto stats = stream.stop();
    const auto dropped = stream.queue.dropped();
    if (stats.lost_samples || stats.crc_errors || dropped) {
      store_.logEvent(run_id, "warning",
                      fmt::format("stream: {} samples lost on the link, {} bad frames, {} dropped by the queue",
                                  stats.lost_samples, stats.crc_errors, dropped));
    }
  } catch (const std::exception& e) {
    const auto stats = device_.stats();
    std::string message = std::string("run interrupted: ") + e.what();
    if (stats.lost_samples > 0) {
      message += fmt::format(" ({} samples were lost on the link: the host did not keep up with the stream)",
                             stats.lost_samples);
    }
    spdlog::error("run {}: {}", run_id, message);
    recordInterruption(store_, run_id, "error", message);
    outcome_ = RunOutcome::kInterrupted;
    throw;
  }
  if (outcome_ == RunOutcome::kInterrupted) {
    recordInterruption(store_, run_id, "warning",
                       fmt::format("run interrupted by the user after {} of {} targets", completed, total));
  } else {
    store_.setRunStatus(run_id, storage::run_status::kCompleted);
  }
}

}  // namespace mtcal::acquisition
