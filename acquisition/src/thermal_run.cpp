#include "mtcal/acquisition/thermal_run.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <cmath>
#include <condition_variable>
#include <deque>
#include <map>
#include <mutex>

#include "mtcal/acquisition/gcode.h"
#include "mtcal/error.h"
#include "mtcal/processing/air_index.h"
#include "plan_json.h"
#include "stop_after_failure.h"

namespace mtcal::acquisition {
namespace {

/// Collects the logger's samples into whole records (every channel of one record index).
class RecordCollector final : public drivers::SampleSink {
 public:
  explicit RecordCollector(int channels) : channels_(channels) {}
  void push(std::span<const drivers::Sample> samples) override {
    std::lock_guard lock(mutex_);
    for (const auto& s : samples) {
      auto& r = partial_[s.seq];
      r.index = s.seq;
      r.time_ns = s.device_time_ns;
      r.values.resize(static_cast<std::size_t>(channels_));
      if (s.beam_ok && std::isfinite(s.value)) r.values[static_cast<std::size_t>(s.channel - 1)] = s.value;
      if (++r.seen == channels_) {
        ready_.push_back(r);
        partial_.erase(s.seq);
      }
    }
    cv_.notify_all();
  }
  struct Record {
    std::uint32_t index = 0;
    std::int64_t time_ns = 0;  ///< the device's clock
    std::vector<std::optional<double>> values;
    int seen = 0;
  };
  /// The next whole record, or nothing within `timeout`.
  std::optional<Record> next(std::chrono::milliseconds timeout) {
    std::unique_lock lock(mutex_);
    if (!cv_.wait_for(lock, timeout, [&] { return !ready_.empty(); })) return std::nullopt;
    Record r = std::move(ready_.front());
    ready_.pop_front();
    return r;
  }

 private:
  int channels_;
  std::mutex mutex_;
  std::condition_variable cv_;
  std::map<std::uint32_t, Record> partial_;
  std::deque<Record> ready_;
};

/// A short window of the interferometer's stream: its mean (mm, raw optical path) or nothing
/// when the beam was broken or nothing came.
class StreamWindow final : public drivers::SampleSink {
 public:
  void push(std::span<const drivers::Sample> samples) override {
    std::lock_guard lock(mutex_);
    for (const auto& s : samples) {
      if (!s.beam_ok) broken_ = true;
      sum_ += s.value;
      ++count_;
    }
    cv_.notify_all();
  }
  std::optional<double> mean(std::size_t wanted, std::chrono::milliseconds timeout) {
    std::unique_lock lock(mutex_);
    cv_.wait_for(lock, timeout, [&] { return count_ >= wanted; });
    if (broken_ || count_ == 0) return std::nullopt;
    return sum_ / static_cast<double>(count_);
  }

 private:
  std::mutex mutex_;
  std::condition_variable cv_;
  double sum_ = 0.0;
  std::size_t count_ = 0;
  bool broken_ = false;
};

constexpr std::uint32_t kWindowRateHz = 100;
constexpr std::size_t kWindowSamples = 10;

/// The interferometer's displacement now (um along its axis, compensated with the air it
/// reads), or nothing when its beam was broken.
std::optional<double> interferometerUm(drivers::interferometer::InterferometerDevice& ifm,
                                       const drivers::interferometer::Environment& env, RunClock& clock) {
  StreamWindow window;
  const auto start_s = clock.nowS();
  ifm.startStream(kWindowRateHz, window);
  if (start_s) clock.advanceTo(*start_s + static_cast<double>(kWindowSamples - 1) / kWindowRateHz);
  const auto raw_mm = window.mean(kWindowSamples, std::chrono::milliseconds(2000));
  ifm.stopStream();
  if (!raw_mm || !env.air_temp_ok || !env.pressure_ok || !env.humidity_ok) return std::nullopt;
  const double n = processing::airIndex(processing::AirIndexModel::kEdlen,
                                        {env.air_temp_c, env.air_pressure_pa, env.humidity_pct, 450.0},
                                        ifm.identity().vacuum_wavelength_nm);
  return processing::compensateWavelength(*raw_mm, n) * 1000.0;
}

}  // namespace

/// The longest phase of a plan: a month.
constexpr double kLongestPhaseS = 30.0 * 86400.0;

ThermalPlan ThermalPlan::fromJson(const nlohmann::json& j, const std::string& source) {
  using plan_json::bad;
  plan_json::checkTypeAndKeys(j, source, "thermal");
  ThermalPlan p;
  plan_json::read(j, "name", p.name, source);
  plan_json::read(j, "interval_s", p.interval_s, source);
  if (p.interval_s < 1 || p.interval_s > drivers::logger::kMaxIntervalS) bad(source, "interval_s", "must be 1..86400");
  if (!j.contains("phases") || !j["phases"].is_array() || j["phases"].empty()) {
    bad(source, "phases", "must be a non-empty list of {name, duration_min, speed_rpm}");
  }
  for (std::size_t i = 0; i < j["phases"].size(); ++i) {
    const auto& ph = j["phases"][i];
    const std::string key = fmt::format("phases[{}]", i);
    if (!ph.is_object() || !ph.contains("duration_min") || !ph["duration_min"].is_number() ||
        !ph.contains("speed_rpm") || !ph["speed_rpm"].is_number()) {
      bad(source, key, "needs duration_min and speed_rpm (numbers)");
    }
    ThermalPhase phase{ph.value("name", fmt::format("phase {}", i + 1)), ph["duration_min"].get<double>() * 60.0,
                       ph["speed_rpm"].get<double>()};
    if (!(phase.duration_s > 0.0 && phase.duration_s <= kLongestPhaseS))
      bad(source, key + ".duration_min",
          fmt::format("must be > 0 and at most {:.0f} (30 days)", kLongestPhaseS / 60.0));
    if (phase.speed_rpm < 0.0 || phase.speed_rpm > 30000.0) bad(source, key + ".speed_rpm", "must be 0..30000");
    p.phases.push_back(phase);
  }
  if (j.contains("sensors")) {
    if (!j["sensors"].is_array()) bad(source, "sensors", "must be a list of names for the logger's channels 1..n");
    for (const auto& s : j["sensors"]) {
      if (!s.is_string() || s.get<std::string>().empty()) bad(source, "sensors", "names must be non-empty strings");
      p.sensors.push_back(s.get<std::string>());
    }
    if (p.sensors.size() > 16) bad(source, "sensors", "a logger has at most 16 channels");
  }
  if (j.contains("displacement")) {
    const auto& d = j["displacement"];
    if (!d.is_object()) bad(source, "displacement", "must be an object {name, channel, axis, sign}");
    plan_json::read(d, "name", p.displacement_name, source);
    plan_json::read(d, "device", p.displacement_device, source);
    if (p.displacement_device != "probes" && p.displacement_device != "interferometer") {
      bad(source, "displacement.device", "must be probes or interferometer");
    }
    if (p.displacement_device == "interferometer" && !d.contains("sign"))
      p.displacement_sign = 1.0;  // the reflector rides on the tool
    plan_json::read(d, "channel", p.displacement_channel, source);
    plan_json::read(d, "axis", p.displacement_axis, source);
    plan_json::read(d, "sign", p.displacement_sign, source);
    plan_json::read(d, "trigger", p.displacement_trigger, source);
    if (p.displacement_channel < 1 || p.displacement_channel > 16) bad(source, "displacement.channel", "must be 1..16");
    if (p.displacement_axis != "Y" && p.displacement_axis != "Z") bad(source, "displacement.axis", "must be Y or Z");
    if (p.displacement_sign != 1.0 && p.displacement_sign != -1.0) bad(source, "displacement.sign", "must be 1 or -1");
    if (p.displacement_trigger && p.displacement_device != "probes")
      bad(source, "displacement.trigger", "only a probe box is triggered");
  }
  plan_json::read(j, "environment", p.environment, source);
  // Every channel of the run under its own name: the speed, the environment unit's, the sensors
  // (T1..T16 unnamed) and the displacement.
  std::map<std::string, std::string> keys_of_name;
  const auto channel = [&](const std::string& name, const std::string& key) {
    const auto [at, fresh] = keys_of_name.emplace(name, key);
    if (!fresh)
      bad(source, key, fmt::format("'{}' is already the name of {}: every channel needs its own", name, at->second));
  };
  channel("spindle_rpm", "the spindle's speed");
  if (p.environment) {
    channel("air_temp_c", "the environment unit's air temperature");
    for (int m = 1; m <= 16; ++m) channel(fmt::format("material_temp_{}", m), "an environment unit's material sensor");
  }
  for (std::size_t c = 0; c < (p.sensors.empty() ? 16 : p.sensors.size()); ++c)
    channel(p.sensors.empty() ? fmt::format("T{}", c + 1) : p.sensors[c],
            p.sensors.empty() ? fmt::format("unnamed sensor {}", c + 1) : fmt::format("sensors[{}]", c));
  channel(p.displacement_name, "displacement.name");
  return p;
}

nlohmann::json ThermalPlan::toJson() const {
  nlohmann::json phase_list = nlohmann::json::array();
  for (const auto& ph : phases) {
    phase_list.push_back({{"name", ph.name}, {"duration_min", ph.duration_s / 60.0}, {"speed_rpm", ph.speed_rpm}});
  }
  nlohmann::json j = {{"type", "thermal"},
                      {"name", name},
                      {"interval_s", interval_s},
                      {"phases", phase_list},
                      {"environment", environment},
                      {"displacement",
                       {{"name", displacement_name},
                        {"device", displacement_device},
                        {"channel", displacement_channel},
                        {"axis", displacement_axis},
                        {"sign", displacement_sign},
                        {"trigger", displacement_trigger}}}};
  if (!sensors.empty()) j["sensors"] = sensors;
  return j;
}

double ThermalPlan::durationS() const {
  double t = 0.0;
  for (const auto& p : phases) t += p.duration_s;
  return t;
}

std::int64_t ThermalPlan::sampleCount() const {
  return static_cast<std::int64_t>(std::floor(durationS() / interval_s + 1e-9)) + 1;
}

double ThermalPlan::speedAt(double t_s) const {
  double end = 0.0;
  for (const auto& p : phases) {
    end += p.duration_s;
    if (t_s < end) return p.speed_rpm;
  }
  return 0.0;
}

std::vector<ThermalPhase> ThermalPlan::phasesFrom(double offset_s) const {
  std::vector<ThermalPhase> out;
  double start = 0.0;
  for (const auto& p : phases) {
    const double end = start + p.duration_s;
    if (end > offset_s) out.push_back({p.name, end - std::max(start, offset_s), p.speed_rpm});
    start = end;
  }
  return out;
}

std::string thermalGcode(const ThermalPlan& plan) {
  std::string out = fmt::format("(mtcal thermal plan {}: start it when mtcal says so; the logger samples every {} s)\n",
                                gcodeCommentText(plan.name), plan.interval_s) +
                    gcodeDwellComment("iso");
  for (const auto& p : plan.phases) {
    out += fmt::format("({}: {:.0f} min at {:.0f} rpm)\n", gcodeCommentText(p.name), p.duration_s / 60.0, p.speed_rpm);
    out += p.speed_rpm > 0.0 ? fmt::format("M3 S{:.0f}\n", p.speed_rpm) : "M5\n";
    out += gcodeDwell("iso", p.duration_s) + "\n";
  }
  return out + "M5\nM30\n";
}

ThermalRunSummary runThermalMonitoring(const ThermalPlan& plan, const ThermalInstruments& instruments,
                                       SpindleController& spindle, storage::Store& store, storage::Id run_id,
                                       const ThermalRunOptions& options) {
  auto& logger = instruments.logger;
  const bool by_probe = plan.displacement_device == "probes";
  if (by_probe && !instruments.probes)
    throw InputError("the plan reads the displacement with a probe box: none is given");
  if ((!by_probe || plan.environment) && !instruments.interferometer) {
    throw InputError("the plan reads the " + std::string(by_probe ? "environment" : "displacement") +
                     " with an interferometer: none is given");
  }
  const int logger_channels = logger.channels().count;
  const auto sensor_count = plan.sensors.empty() ? logger_channels : static_cast<int>(plan.sensors.size());
  if (sensor_count > logger_channels) {
    throw InputError(
        fmt::format("the plan names {} sensors, the logger has {} channels", sensor_count, logger_channels));
  }
  if (by_probe && plan.displacement_channel > instruments.probes->channels().count) {
    throw InputError(fmt::format("displacement channel {}: the probe box has {} channels", plan.displacement_channel,
                                 instruments.probes->channels().count));
  }
  // The environment unit's material sensors: as many channels as it has.
  const std::size_t material_sensors =
      plan.environment ? instruments.interferometer->readEnvironment().material_temps_c.size() : 0;
  ThermalRunSummary summary;
  summary.samples = store.thermalSampleCount(run_id);
  const std::int64_t total = plan.sampleCount();
  if (summary.samples == 0) {
    std::vector<storage::ThermalChannel> channels;
    for (int c = 0; c < sensor_count; ++c) {
      channels.push_back({plan.sensors.empty() ? fmt::format("T{}", c + 1) : plan.sensors[static_cast<std::size_t>(c)],
                          "temperature", "degC"});
    }
    if (plan.environment) {
      channels.push_back({"air_temp_c", "temperature", "degC"});
      for (std::size_t m = 0; m < material_sensors; ++m)
        channels.push_back({fmt::format("material_temp_{}", m + 1), "temperature", "degC"});
    }
    channels.push_back({plan.displacement_name, "displacement", "um"});
    channels.push_back({"spindle_rpm", "speed", "rpm"});
    store.addThermalChannels(run_id, channels);
    // The drift counts from the cold machine.
    if (by_probe) {
      instruments.probes->zero(plan.displacement_channel);
    } else {
      instruments.interferometer->setOptics(drivers::interferometer::Optics::kLinear);
      instruments.interferometer->setDatum();
    }
  }
  store.setRunStatus(run_id, storage::run_status::kRunning);
  const std::int64_t first = summary.samples;
  // A resumed run continues in a new segment: the machine's state after the gap is not
  // continuous with the samples before it.
  int segment = 0;
  if (first > 0 && first < total) {
    segment = store.thermalSamples(run_id).back().segment + 1;
    store.logEvent(run_id, "warning",
                   fmt::format("gap: the run continues at sample {} in segment {}; the machine's state is not taken as "
                               "continuous across the gap (each segment has its own level in fits)",
                               first, segment));
  }
  const double offset_s = static_cast<double>(first) * plan.interval_s;
  RecordCollector collector(logger_channels);
  const bool triggered = by_probe && plan.displacement_trigger;
  RecordCollector latches(by_probe ? instruments.probes->channels().count : 1);
  const auto missingDisplacement = [&](std::int64_t k, const std::string& why) {
    spdlog::warn("sample {}: displacement missing: {}", k, why);
    store.logEvent(run_id, "warning", fmt::format("sample {}: displacement missing: {}", k, why));
  };
  RunClock& clock = options.run_clock ? *options.run_clock : realTime();
  try {
    if (triggered) instruments.probes->startTriggered(latches);
    // The logger logs from the next whole second of its clock.
    const auto now_s = clock.nowS();
    const auto first_record_s = now_s ? std::optional(std::ceil(*now_s)) : std::nullopt;
    logger.startLogging(std::chrono::seconds(plan.interval_s), collector);
    bool started = false;
    std::int64_t t0_ns = 0;
    for (std::int64_t k = first; k < total; ++k) {
      if (first_record_s) clock.advanceTo(*first_record_s + static_cast<double>((k - first) * plan.interval_s));
      std::optional<RecordCollector::Record> record;
      const auto deadline = std::chrono::steady_clock::now() + options.record_timeout;
      while (!record) {
        logger.poll();  // the reader's error, if any
        if (options.stop_requested && *options.stop_requested) break;
        if (std::chrono::steady_clock::now() > deadline) {
          throw TimeoutError(
              fmt::format("{}: no record within {} ms", logger.info().uri, options.record_timeout.count()));
        }
        record = collector.next(std::chrono::milliseconds(50));
      }
      if (!record) {
        summary.stopped_because = "stopped by the operator";
        break;
      }
      if (!started) {
        t0_ns = record->time_ns;
        spindle.startProgram(plan.phasesFrom(offset_s), static_cast<double>(t0_ns) / 1e9);
        started = true;
      }
      storage::ThermalSample sample;
      sample.index = k;
      sample.segment = segment;
      sample.time_s = offset_s + static_cast<double>(record->time_ns - t0_ns) / 1e9;  // exact for whole seconds
      for (int c = 0; c < sensor_count; ++c) sample.values.push_back(record->values[static_cast<std::size_t>(c)]);
      drivers::interferometer::Environment env;
      if (instruments.interferometer) env = instruments.interferometer->readEnvironment();
      if (plan.environment) {
        sample.values.push_back(env.air_temp_ok ? std::optional(env.air_temp_c) : std::nullopt);
        for (std::size_t m = 0; m < material_sensors; ++m) {
          sample.values.push_back(m < env.material_temps_c.size() ? std::optional(env.material_temps_c[m])
                                                                  : std::nullopt);
        }
      }
      std::optional<double> displacement;
      try {
        if (triggered) {
          // The box latched at the record's pulse: the k-th latch of this session is the k-th record's.
          const auto latch = latches.next(options.record_timeout);
          if (!latch)
            throw TimeoutError(
                fmt::format("{}: no latched reading for record {}", instruments.probes->info().uri, record->index));
          if (latch->index != record->index) {
            throw DeviceError(fmt::format("trigger pulses and records out of step: latch {} for record {}",
                                          latch->index, record->index));
          }
          const auto& v = latch->values[static_cast<std::size_t>(plan.displacement_channel - 1)];
          if (v) displacement = *v * 1000.0;
        } else if (by_probe) {
          displacement =
              instruments.probes->readAll()[static_cast<std::size_t>(plan.displacement_channel - 1)] * 1000.0;
        } else {
          displacement = interferometerUm(*instruments.interferometer, env, clock);
        }
        if (displacement)
          *displacement *= plan.displacement_sign;
        else
          missingDisplacement(k, "out of range, beam broken or air not read");
      } catch (const DeviceError& e) {  // over range, no probe: missing, never 0
        missingDisplacement(k, e.what());
      }
      sample.values.push_back(displacement);
      sample.values.push_back(plan.speedAt(sample.time_s));
      for (const auto& v : sample.values) summary.missing_values += v ? 0 : 1;
      store.addThermalSamples(run_id, std::span(&sample, 1));
      summary.samples = k + 1;
      if (options.on_progress) options.on_progress(k + 1, total, displacement.value_or(std::nan("")));
    }
    logger.stopStream();
    if (triggered) instruments.probes->stopStream();
  } catch (const Error& e) {
    summary.stopped_because = e.what();
    stopAfterFailure(logger);
    if (triggered) stopAfterFailure(*instruments.probes);
    recordInterruption(store, run_id, "error", std::string("thermal run interrupted: ") + e.what());
    return summary;
  }
  summary.complete = summary.samples >= total;
  if (summary.complete) {
    store.setRunStatus(run_id, storage::run_status::kCompleted);
  } else {
    recordInterruption(store, run_id, "warning",
                       fmt::format("thermal run interrupted after {} of {} samples: {}", summary.samples, total,
                                   summary.stopped_because));
  }
  return summary;
}

}  // namespace mtcal::acquisition
