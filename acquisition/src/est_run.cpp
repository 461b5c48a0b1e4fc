#include "mtcal/acquisition/est_run.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <cmath>
#include <condition_variable>
#include <deque>
#include <fstream>
#include <limits>
#include <mutex>
#include <set>

#include "mtcal/acquisition/csv.h"
#include "mtcal/acquisition/linear_plan.h"
#include "mtcal/error.h"
#include "mtcal/processing/est.h"
#include "plan_json.h"
#include "resume_run.h"
#include "stop_after_failure.h"

namespace mtcal::acquisition {
namespace {

using plan_json::bad;

double number(const nlohmann::json& j, const char* key, double fallback, const std::string& source) {
  plan_json::read(j, key, fallback, source);
  return fallback;
}

int whole(const nlohmann::json& j, const char* key, int fallback, const std::string& source) {
  plan_json::read(j, key, fallback, source);
  return fallback;
}

/// Stream lines, one per probe-box line: the channels' samples grouped by seq.
struct LineQueue final : drivers::SampleSink {
  struct Line {
    std::int64_t time_ns = 0;
    std::vector<double> values_mm;
    std::vector<bool> ok;
  };
  void push(std::span<const drivers::Sample> samples) override {
    std::lock_guard lock(mutex);
    for (const auto& s : samples) {
      if (s.channel == 1) lines.push_back({s.device_time_ns, {}, {}});
      if (lines.empty()) continue;
      lines.back().values_mm.push_back(s.value);
      lines.back().ok.push_back(s.beam_ok);
    }
    cv.notify_all();
  }
  std::mutex mutex;
  std::condition_variable cv;
  std::deque<Line> lines;
};

}  // namespace

EstPlan EstPlan::fromJson(const nlohmann::json& j, const std::string& source) {
  plan_json::checkTypeAndKeys(j, source, "est");
  EstPlan p;
  if (j.contains("name")) p.name = j["name"].get<std::string>();
  p.axis = j.value("axis", p.axis);
  p.measures = j.value("measures", p.measures);
  p.start_mm = number(j, "start_mm", p.start_mm, source);
  p.step_mm = number(j, "step_mm", p.step_mm, source);
  p.points = whole(j, "points", p.points, source);
  p.spacing_mm = number(j, "spacing_mm", p.step_mm, source);
  p.probes = whole(j, "probes", p.probes, source);
  p.settle_s = number(j, "settle_s", p.settle_s, source);
  p.readings_per_step = whole(j, "readings_per_step", p.readings_per_step, source);
  p.rate_hz = static_cast<std::uint32_t>(whole(j, "rate_hz", static_cast<int>(p.rate_hz), source));
  p.step_timeout_s = number(j, "step_timeout_s", p.step_timeout_s, source);
  if (j.contains("line_position_mm")) p.line_position_mm = parseLinePosition(j["line_position_mm"], source);
  if (p.axis != "X" && p.axis != "Y" && p.axis != "Z") bad(source, "axis", "must be X, Y or Z");
  if (p.line_position_mm.count(p.axis)) bad(source, "line_position_mm." + p.axis, "is the stepped axis");
  if ((p.measures != "X" && p.measures != "Y" && p.measures != "Z") || p.measures == p.axis) {
    bad(source, "measures", "must be X, Y or Z across the stepped axis");
  }
  if (!(p.step_mm > 0.0)) bad(source, "step_mm", "must be > 0");
  const double m = p.spacing_mm / p.step_mm;
  if (!(p.spacing_mm > 0.0) || std::abs(m - std::round(m)) > 1e-9) {
    bad(source, "spacing_mm", "must be a whole number of steps (step_mm or m * step_mm)");
  }
  if (p.probes != 2 && p.probes != 3) bad(source, "probes", "must be 2 or 3");
  if (p.probes == 3 && std::abs(m - 1.0) > 1e-9) bad(source, "spacing_mm", "three probes need a spacing of one step");
  if (p.points < 3 || p.points > 100000) bad(source, "points", "must be 3..100000");
  if (!processing::spacingFitsLine(std::round(m), static_cast<std::size_t>(p.points))) {
    bad(source, "spacing_mm",
        fmt::format("{:g} mm is not shorter than the line stepped ({} points of {:g} mm: {:g} mm): the second probe "
                    "would never read where the first did",
                    p.spacing_mm, p.points, p.step_mm, (p.points - 1) * p.step_mm));
  }
  if (!(p.settle_s >= 0.0)) bad(source, "settle_s", "must be >= 0");
  if (p.readings_per_step < 1) bad(source, "readings_per_step", "must be >= 1");
  if (p.rate_hz < 1 || p.rate_hz > drivers::probes::kMaxRateHz) bad(source, "rate_hz", "must be 1..1000");
  if (!(p.step_timeout_s > 0.0)) bad(source, "step_timeout_s", "must be > 0");
  if (j.contains("zeroing")) {
    if (!j["zeroing"].is_string()) bad(source, "zeroing", "must be reference-flat or none");
    p.zeroing = j["zeroing"].get<std::string>();
  }
  if (!p.zeroing.empty() && p.zeroing != "reference-flat" && p.zeroing != "none")
    bad(source, "zeroing", "must be reference-flat or none");
  p.zeroing_readings = whole(j, "zeroing_readings", p.zeroing_readings, source);
  if (p.zeroing_readings < 1) bad(source, "zeroing_readings", "must be >= 1");
  if (j.contains("stepping")) {
    if (!j["stepping"].is_string()) bad(source, "stepping", "must be machine or hand");
    p.stepping = j["stepping"].get<std::string>();
  }
  if (p.stepping != "machine" && p.stepping != "hand") bad(source, "stepping", "must be machine or hand");
  p.still_um = number(j, "still_um", p.still_um, source);
  plan_json::read(j, "imported_from", p.imported_from, source);
  plan_json::read(j, "imported_sha256", p.imported_sha256, source);
  if (!(p.still_um > 0.0)) bad(source, "still_um", "must be > 0");
  return p;
}

EstPlan EstPlan::load(const std::string& path) { return fromJson(readJsonFile(path), path); }

nlohmann::json EstPlan::toJson() const {
  nlohmann::json j = {{"type", "est"},
                      {"name", name},
                      {"axis", axis},
                      {"measures", measures},
                      {"start_mm", start_mm},
                      {"step_mm", step_mm},
                      {"points", points},
                      {"spacing_mm", spacing_mm},
                      {"probes", probes},
                      {"settle_s", settle_s},
                      {"readings_per_step", readings_per_step},
                      {"rate_hz", rate_hz},
                      {"step_timeout_s", step_timeout_s},
                      {"line_position_mm", line_position_mm},
                      {"zeroing", zeroingMethod()},
                      {"zeroing_readings", zeroing_readings},
                      {"stepping", stepping},
                      {"still_um", still_um}};
  if (!imported_from.empty()) j["imported_from"] = imported_from;
  if (!imported_sha256.empty()) j["imported_sha256"] = imported_sha256;
  return j;
}

EstRun::EstRun(storage::Store& store, drivers::probes::ProbeBoxDevice& device, MachineController& controller,
               EstRunOptions options)
    : store_(store), device_(device), controller_(controller), options_(std::move(options)) {}

void EstRun::requireChannels(const EstPlan& plan) const {
  if (device_.channels().count < plan.probes) {
    throw InputError(
        fmt::format("the plan uses {} probes, the box has {} channels", plan.probes, device_.channels().count));
  }
}

storage::Id EstRun::start(const EstPlan& plan, storage::Id campaign_id, std::optional<storage::Id> instrument_id) {
  requireChannels(plan);
  storage::NewRun run;
  run.campaign_id = campaign_id;
  run.instrument_id = instrument_id;
  run.kind = storage::run_kind::kEst;
  run.axis = plan.axis;
  run.name = plan.name;
  run.plan_json = plan.toJson().dump();
  run.software_version = options_.software_version;
  const storage::Id run_id = store_.addRun(run);
  execute(run_id, plan, {});
  return run_id;
}

EstPlan EstRun::resume(storage::Id run_id) {
  const auto info = runToResume(store_, run_id, storage::run_kind::kEst, "probe stepping run");
  const EstPlan plan = EstPlan::fromJson(nlohmann::json::parse(info.plan_json), fmt::format("run {} plan", run_id));
  requireChannels(plan);
  std::set<int> done;
  for (const auto& step : store_.probeSteps(run_id)) done.insert(static_cast<int>(step.step));
  takeOverRun(store_, run_id, fmt::format("{} of {} steps", done.size(), plan.points));
  execute(run_id, plan, done);
  return plan;
}

namespace {

/// A channel's mean and standard deviation (um) over the lines of a capture.
storage::ProbeReading channelOf(const std::vector<LineQueue::Line>& lines, int c, const std::string& where) {
  double sum = 0.0, ss = 0.0;
  for (const auto& line : lines) {
    if (static_cast<int>(line.values_mm.size()) <= c)
      throw ProtocolError(fmt::format("{}: a line without channel {}", where, c + 1));
    if (!line.ok[static_cast<std::size_t>(c)]) {
      throw DeviceError(fmt::format("{}: channel {} is not reading (over or under range, or no probe)", where, c + 1));
    }
    sum += line.values_mm[static_cast<std::size_t>(c)] * 1000.0;
  }
  const double n = static_cast<double>(lines.size());
  const double mean = sum / n;
  for (const auto& line : lines) ss += std::pow(line.values_mm[static_cast<std::size_t>(c)] * 1000.0 - mean, 2);
  return {c + 1, mean, lines.size() > 1 ? std::optional<double>(std::sqrt(ss / (n - 1))) : std::nullopt,
          static_cast<int>(lines.size())};
}

}  // namespace

nlohmann::json EstZeroing::toJson() const {
  return {{"method", method},
          {"zero_um", zero_um},
          {"s_um", s_um},
          {"readings", readings},
          {"combination_um", combinationUm()}};
}

EstZeroing EstZeroing::fromJson(const nlohmann::json& j) {
  EstZeroing z;
  z.method = j.value("method", "");
  z.zero_um = j.value("zero_um", std::vector<double>{});
  z.s_um = j.value("s_um", std::vector<double>{});
  z.readings = j.value("readings", 0);
  return z;
}

std::optional<EstZeroing> storedZeroing(storage::Store& store, storage::Id run_id) {
  std::optional<EstZeroing> out;
  for (const auto& r : store.results(run_id)) {
    if (r.processor != kEstZeroingProcessor) continue;
    const auto j = nlohmann::json::parse(r.output_json, nullptr, false);
    if (j.is_object()) out = EstZeroing::fromJson(j);  // the latest
  }
  return out;
}

processing::EstRunInput storedEstRun(storage::Store& store, const storage::RunInfo& info) {
  const auto plan = EstPlan::fromJson(nlohmann::json::parse(info.plan_json), fmt::format("run {} plan", info.id));
  processing::EstRunInput in;
  in.source = fmt::format("run {}", info.id);
  in.spacing_mm = plan.spacing_mm;
  for (const auto& step : store.probeSteps(info.id)) {
    in.position_mm.push_back(step.position_mm);
    in.readings.push_back(0);
    for (const auto& ch : step.channels) {
      if (ch.channel < 1 || ch.channel > 3) continue;
      in.probeUm(static_cast<std::size_t>(ch.channel - 1)).push_back(ch.value_um);
      in.scatter_um[static_cast<std::size_t>(ch.channel - 1)].push_back(ch.s_um.value_or(NAN));
      // The probes' channels come from the same stream lines: one count.
      in.readings.back() = in.readings.back() == 0 ? ch.readings : std::min(in.readings.back(), ch.readings);
    }
  }
  if (in.v3_um.empty()) in.scatter_um[2].clear();
  return in;
}

void storeZeroing(storage::Store& store, storage::Id run_id, const EstZeroing& zeroing, const std::string& version) {
  store.addResult(run_id, kEstZeroingProcessor, version, "{}", zeroing.toJson().dump());
  // Two probes' zeros have no combination: the two-probe method's zero offset is a line.
  store.logEvent(run_id, "info",
                 zeroing.zero_um.size() == 3
                     ? fmt::format("probes zeroed ({}): {:.3f} um, combination z3 - 2 z2 + z1 = {:.4f} um",
                                   zeroing.method, fmt::join(zeroing.zero_um, ", "), zeroing.combinationUm())
                     : fmt::format("probes zeroed ({}): {:.3f} um", zeroing.method, fmt::join(zeroing.zero_um, ", ")));
}

void EstRun::execute(storage::Id run_id, const EstPlan& plan, const std::set<int>& stored) {
  outcome_ = RunOutcome::kCompleted;
  int done = static_cast<int>(stored.size());
  LineQueue queue;
  try {
    // The measured line first: the first step waits for those moves too.
    const LineArrival line = moveToLine(controller_, plan.line_position_mm);
    RunClock& clock = options_.run_clock ? *options_.run_clock : realTime();
    const auto period_ns = std::llround(1e9 / plan.rate_hz);
    device_.startStream(plan.rate_hz, queue);
    /// `count` stream lines time-stamped from `from_ns` (none: from now, the queue cleared).
    auto capture = [&](int count, std::optional<std::int64_t> from_ns, const std::string& where) {
      std::vector<LineQueue::Line> lines;
      std::unique_lock lock(queue.mutex);
      if (!from_ns) queue.lines.clear();
      // Where the capture's readings begin: `from_ns`, or (cleared) the time now.
      std::optional<std::int64_t> latest_ns = from_ns;
      if (!latest_ns) {
        if (const auto now_s = clock.nowS()) latest_ns = std::llround(*now_s * 1e9);
      }
      // Without a time to start from, the lines from now on (the instruments' time, when the
      // clock knows it: lines of the move before may still be on their way).
      const std::int64_t first_ns = latest_ns.value_or(std::numeric_limits<std::int64_t>::min());
      const double timeout_s = plan.step_timeout_s + static_cast<double>(count) / plan.rate_hz;
      const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
      // Without an in-position time (a carriage moved by hand), the step is taken once the
      // probes hold still: the window of `count` lines slides until no channel moves more than
      // still_um in it, and the step's readings are the next window, as still.
      const auto moving = [&]() -> std::optional<std::pair<int, double>> {
        if (from_ns || static_cast<int>(lines.size()) < count) return std::nullopt;
        for (int c = 0; c < plan.probes; ++c) {
          double lo = std::numeric_limits<double>::infinity(), hi = -lo;
          for (const auto& l : lines) {
            if (static_cast<int>(l.values_mm.size()) <= c) continue;
            lo = std::min(lo, l.values_mm[static_cast<std::size_t>(c)] * 1000.0);
            hi = std::max(hi, l.values_mm[static_cast<std::size_t>(c)] * 1000.0);
          }
          if (hi - lo > plan.still_um) return std::pair{c + 1, hi - lo};
        }
        return std::nullopt;
      };
      bool settled = from_ns.has_value();              // a still window seen before this one
      std::optional<std::pair<int, double>> restless;  // the last window that moved
      const auto notStill = [&] {
        return TimeoutError(
            fmt::format("{}: the probes did not hold still within {} s (channel {} moved {:.3f} um "
                        "within {} readings; still_um {})",
                        where, timeout_s, restless->first, restless->second, count, plan.still_um));
      };
      while (true) {
        if (static_cast<int>(lines.size()) >= count) {
          const auto m = moving();
          if (!m && settled) break;
          if (!m) {
            settled = true;  // still: the step's readings are the next window, still too
            lines.clear();
            continue;
          }
          restless = m;
          if (std::chrono::steady_clock::now() > deadline) throw notStill();
          lines.erase(lines.begin());
          settled = false;
        }
        device_.poll();
        if (queue.lines.empty()) {
          // Let the probe box get to the capture's last reading, counted from the lines there are.
          if (latest_ns) {
            const auto missing = static_cast<std::int64_t>(count - static_cast<int>(lines.size()));
            lock.unlock();
            clock.advanceTo(static_cast<double>(*latest_ns + missing * period_ns) * 1e-9);
            lock.lock();
            if (!queue.lines.empty()) continue;
          }
          if (queue.cv.wait_until(lock, deadline) == std::cv_status::timeout) {
            if (restless) throw notStill();
            throw TimeoutError(fmt::format("{}: {} of {} readings within {} s", where, lines.size(), count, timeout_s));
          }
          continue;
        }
        auto l = std::move(queue.lines.front());
        queue.lines.pop_front();
        latest_ns = std::max(latest_ns.value_or(l.time_ns), l.time_ns);
        if (l.time_ns < first_ns) continue;
        lines.push_back(std::move(l));
      }
      return std::make_pair(std::move(lines), latest_ns.value_or(0));
    };

    // The zeroing, once per run: the probes on the reference flat, averaged, then back.
    std::int64_t not_before_ns = std::numeric_limits<std::int64_t>::min();
    if (plan.zeroingMethod() == "reference-flat" && !storedZeroing(store_, run_id)) {
      if (!options_.reference_flat) {
        throw InputError("the plan zeroes the probes on a reference flat (\"zeroing\"): nobody to set them there");
      }
      options_.reference_flat(true);
      // The readings count once the machine is on its measured line too (those moves were
      // issued first and may still be under way); without the moves' times, once they are still.
      std::optional<std::int64_t> from;
      if (const auto at_s = line.laterOf(clock.nowS())) from = std::llround((*at_s + plan.settle_s) * 1e9);
      auto [lines, last_ns] = capture(plan.zeroing_readings, from, "zeroing on the reference flat");
      EstZeroing zeroing;
      zeroing.method = "reference-flat";
      zeroing.readings = static_cast<int>(lines.size());
      for (int c = 0; c < plan.probes; ++c) {
        const auto v = channelOf(lines, c, "zeroing on the reference flat");
        zeroing.zero_um.push_back(v.value_um);
        zeroing.s_um.push_back(v.s_um.value_or(0.0));
      }
      storeZeroing(store_, run_id, zeroing, options_.software_version);
      options_.reference_flat(false);
      not_before_ns = last_ns + std::llround(plan.settle_s * 1e9);  // nothing read on the flat counts for a step
    }

    for (int k = 0; k < plan.points; ++k) {
      if (stored.contains(k)) continue;
      if (options_.stop_requested && *options_.stop_requested) {
        outcome_ = RunOutcome::kInterrupted;
        break;
      }
      const double x = plan.positionMm(k);
      auto in_position_s = controller_.moveTo(plan.axis, x);
      if (k == 0) in_position_s = line.laterOf(in_position_s);
      // Readings count from the first line time-stamped after the carriage settled. Without an
      // in-position time, every line after the move command counts (the queue is cleared).
      std::optional<std::int64_t> from_ns;
      if (in_position_s)
        from_ns = std::max<std::int64_t>(std::llround((*in_position_s + plan.settle_s) * 1e9), not_before_ns);
      const std::string where = fmt::format("step {} at {:.3f} mm", k, x);
      const auto lines = capture(plan.readings_per_step, from_ns, where).first;
      storage::ProbeStep step;
      step.step = k;
      step.position_mm = x;
      for (int c = 0; c < plan.probes; ++c) step.channels.push_back(channelOf(lines, c, where));
      store_.addProbeStep(run_id, step);
      ++done;
      if (options_.on_progress) options_.on_progress({done, plan.points, x});
    }
    device_.stopStream();
  } catch (const std::exception& e) {
    stopAfterFailure(device_);
    const std::string message = fmt::format("run interrupted after {} of {} steps: {}", done, plan.points, e.what());
    spdlog::error("run {}: {}", run_id, message);
    recordInterruption(store_, run_id, "error", message);
    outcome_ = RunOutcome::kInterrupted;
    throw;
  }
  if (outcome_ == RunOutcome::kInterrupted) {
    recordInterruption(store_, run_id, "warning",
                       fmt::format("run interrupted by the user after {} of {} steps", done, plan.points));
  } else {
    store_.setRunStatus(run_id, storage::run_status::kCompleted);
  }
}

}  // namespace mtcal::acquisition
