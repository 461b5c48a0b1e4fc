#include "mtcal/acquisition/thermal_run.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <nlohmann/json.hpp>
#include <sstream>

#include "../support/temp_dir.h"
#include "../support/time_scale.h"
#include "mtcal/acquisition/thermal_data.h"
#include "mtcal/drivers/registry.h"
#include "mtcal/mocks/simulation.h"
#include "mtcal/services/workshop.h"

// A thermal monitoring run on the simulated machine through the real logger and probe
// drivers (pseudo-terminals) into SQLite: interrupted, a sensor out, resumed, a logger lost.
namespace mtcal::acquisition {
namespace {

class VirtualSpindle final : public SpindleController {
 public:
  explicit VirtualSpindle(mocks::MachineThermal& thermal) : thermal_(thermal) {}
  void startProgram(const std::vector<ThermalPhase>& phases, double start_s) override {
    std::vector<mocks::SpindlePhase> program;
    for (const auto& p : phases) program.push_back({p.duration_s, p.speed_rpm});
    started.push_back({start_s, phases.empty() ? 0.0 : phases.front().duration_s});
    thermal_.startProgram(program, start_s);
  }
  std::vector<std::pair<double, double>> started;  ///< start time, first phase's duration

 private:
  mocks::MachineThermal& thermal_;
};

struct Session {
  Session() {
    auto config = mocks::VirtualMachineConfig::demo(9);
    config.thermal = mocks::MachineThermalConfig{};
    world = std::make_unique<mocks::SimulatedWorld>(config, mocks::InterferometerEmulatorConfig{},
                                                    mtcal::testing::timeScale(3000.0));
    run_clock = std::make_unique<services::WorldRunClock>(world->clock);
    mocks::registerMockDrivers(registry, *world);
    world->probes.setMeasuring(2);
    logger = registry.openAs<drivers::logger::TemperatureLoggerDevice>("mock://logger");
    probes = registry.openAs<drivers::probes::ProbeBoxDevice>("mock://probes");
    const auto machine = store.ensureMachine("virtual", "", "{}");
    storage::NewRun run;
    run.campaign_id = store.addCampaign(machine, "thermal");
    run.kind = "thermal";
    run.name = plan.name;
    run_id = store.addRun(run);
  }
  static ThermalPlan makePlan() {
    ThermalPlan p;
    p.interval_s = 60;
    p.phases = {{"warm-up", 1800.0, 2000.0}, {"cool-down", 1800.0, 0.0}};
    p.sensors = {"front_bearing",  "rear_bearing", "spindle_nose", "headstock_front",
                 "headstock_rear", "column_front", "column_rear",  "ambient"};
    return p;
  }
  mtcal::testing::TempDir dir;
  storage::Store store{dir.file("t.sqlite")};
  drivers::Registry registry;
  std::unique_ptr<mocks::SimulatedWorld> world;
  std::unique_ptr<services::WorldRunClock> run_clock;  ///< the world runs in lock step with the run
  std::unique_ptr<drivers::logger::TemperatureLoggerDevice> logger;
  std::unique_ptr<drivers::probes::ProbeBoxDevice> probes;
  ThermalPlan plan = makePlan();
  storage::Id run_id = 0;
};

TEST(ThermalRun, InterruptedResumedWithASensorOutStoredAsMissing) {
  Session s;
  s.plan.displacement_trigger = true;  // the probe box latched by the logger's records
  VirtualSpindle spindle(*s.world->machine.thermal());
  std::atomic<bool> stop{false};
  ThermalRunOptions options;
  options.run_clock = s.run_clock.get();
  options.stop_requested = &stop;
  options.record_timeout = std::chrono::milliseconds(5000);
  options.on_progress = [&](std::int64_t done, std::int64_t, double) {
    if (done == 20) stop = true;
  };
  const auto first = runThermalMonitoring(s.plan, {*s.logger, s.probes.get()}, spindle, s.store, s.run_id, options);
  EXPECT_FALSE(first.complete);
  EXPECT_EQ(first.samples, 20);
  EXPECT_EQ(first.stopped_because, "stopped by the operator");
  EXPECT_EQ(s.store.run(s.run_id).status, storage::run_status::kInterrupted);
  ASSERT_EQ(s.store.thermalSamples(s.run_id).size(), 20u);

  // Channel 2 (rear_bearing) is out for the rest of the test; the run goes on.
  s.world->logger.updateFaults([](mocks::LoggerFaults& f) { f.dropouts.push_back({2, 0.0, 1e12}); });
  stop = false;
  options.on_progress = nullptr;
  const auto resumed = runThermalMonitoring(s.plan, {*s.logger, s.probes.get()}, spindle, s.store, s.run_id, options);
  EXPECT_TRUE(resumed.complete) << resumed.stopped_because;
  EXPECT_EQ(resumed.samples, 61);
  EXPECT_EQ(resumed.missing_values, 41);  // rear_bearing in each of the 41 resumed samples
  EXPECT_EQ(s.store.run(s.run_id).status, storage::run_status::kCompleted);
  EXPECT_EQ(s.store.thermalChannels(s.run_id).size(), 10u);  // channels stored once
  const auto samples = s.store.thermalSamples(s.run_id);
  ASSERT_EQ(samples.size(), 61u);
  for (std::size_t i = 0; i < samples.size(); ++i) {
    EXPECT_EQ(samples[i].index, static_cast<std::int64_t>(i));
    EXPECT_DOUBLE_EQ(samples[i].time_s, 60.0 * static_cast<double>(i));  // the logger's clock, the schedule kept
    EXPECT_EQ(samples[i].values[1].has_value(), i < 20) << i;            // missing, never 0
    EXPECT_TRUE(samples[i].values[0].has_value());
    EXPECT_TRUE(samples[i].values[8].has_value());
    EXPECT_DOUBLE_EQ(*samples[i].values[9], i < 30 ? 2000.0 : 0.0);
  }
  // The resumed program ran the rest of the warm-up (10 min) first.
  ASSERT_EQ(spindle.started.size(), 2u);
  EXPECT_DOUBLE_EQ(spindle.started[0].second, 1800.0);
  EXPECT_DOUBLE_EQ(spindle.started[1].second, 600.0);
  EXPECT_LT(*samples[29].values[8], *samples[1].values[8] - 1.0);  // the tool drifted towards the table
}

TEST(ThermalRun, ALostLoggerInterruptsAndKeepsTheSamples) {
  Session s;
  VirtualSpindle spindle(*s.world->machine.thermal());
  ThermalRunOptions options;
  options.run_clock = s.run_clock.get();
  options.record_timeout = std::chrono::milliseconds(500);
  options.on_progress = [&](std::int64_t done, std::int64_t, double) {
    if (done == 5) s.world->logger.updateFaults([](mocks::LoggerFaults& f) { f.silent = true; });
  };
  const auto summary = runThermalMonitoring(s.plan, {*s.logger, s.probes.get()}, spindle, s.store, s.run_id, options);
  EXPECT_FALSE(summary.complete);
  EXPECT_EQ(summary.samples, 5);
  EXPECT_NE(summary.stopped_because.find("no record within 500 ms"), std::string::npos) << summary.stopped_because;
  EXPECT_EQ(s.store.thermalSamples(s.run_id).size(), 5u);
  EXPECT_EQ(s.store.run(s.run_id).status, storage::run_status::kInterrupted);
  const auto events = s.store.events(s.run_id);
  ASSERT_FALSE(events.empty());
  EXPECT_NE(events.back().message.find("thermal run interrupted"), std::string::npos);
  // The logger answers again: the run resumes, in a new segment, to its last sample.
  s.world->logger.updateFaults([](mocks::LoggerFaults& f) { f.silent = false; });
  options.on_progress = {};
  options.record_timeout = std::chrono::seconds(30);
  const auto resumed = runThermalMonitoring(s.plan, {*s.logger, s.probes.get()}, spindle, s.store, s.run_id, options);
  EXPECT_TRUE(resumed.complete) << resumed.stopped_because;
  const auto samples = s.store.thermalSamples(s.run_id);
  ASSERT_EQ(static_cast<std::int64_t>(samples.size()), s.plan.sampleCount());
  EXPECT_EQ(samples[4].segment, 0);
  EXPECT_EQ(samples[5].segment, 1);
  // Its export keeps the segments, and reads back exactly.
  std::stringstream csv;
  writeThermalCsv(s.store, s.run_id, csv);
  const auto back = parseThermalCsv(csv, "export", {});
  ASSERT_EQ(back.samples.size(), samples.size());
  for (std::size_t k = 0; k < samples.size(); ++k) {
    EXPECT_EQ(back.samples[k].segment, samples[k].segment) << k;
    EXPECT_EQ(back.samples[k].time_s, samples[k].time_s) << k;
    EXPECT_EQ(back.samples[k].values, samples[k].values) << k;
  }
  // Taken up again after its last sample (its process killed before it closed the run): it
  // is closed, with no gap and no new segment.
  s.store.setRunStatus(s.run_id, storage::run_status::kInterrupted);
  const auto gaps = [&] {
    const auto events = s.store.events(s.run_id);
    return std::count_if(events.begin(), events.end(),
                         [](const auto& e) { return e.message.find("gap") != std::string::npos; });
  };
  const auto gaps_before = gaps();
  EXPECT_TRUE(runThermalMonitoring(s.plan, {*s.logger, s.probes.get()}, spindle, s.store, s.run_id, options).complete);
  EXPECT_EQ(s.store.thermalSamples(s.run_id).size(), samples.size());
  EXPECT_EQ(gaps(), gaps_before);
  EXPECT_EQ(s.store.run(s.run_id).status, storage::run_status::kCompleted);
}

TEST(ThermalPlan, ReadsAndRefuses) {
  const auto p = ThermalPlan::fromJson(nlohmann::json::parse(R"({"type": "thermal", "interval_s": 30,
      "phases": [{"duration_min": 10, "speed_rpm": 1500}, {"name": "off", "duration_min": 5, "speed_rpm": 0}]})"),
                                       "p.json");
  EXPECT_EQ(p.sampleCount(), 31);
  EXPECT_DOUBLE_EQ(p.speedAt(599.0), 1500.0);
  EXPECT_DOUBLE_EQ(p.speedAt(600.0), 0.0);
  EXPECT_EQ(p.phasesFrom(300.0).size(), 2u);
  EXPECT_DOUBLE_EQ(p.phasesFrom(300.0)[0].duration_s, 300.0);
  EXPECT_EQ(ThermalPlan::fromJson(p.toJson(), "again").sampleCount(), 31);
  const auto refuses = [](const char* text, const char* why) {
    try {
      ThermalPlan::fromJson(nlohmann::json::parse(text), "bad.json");
      ADD_FAILURE() << text;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(why), std::string::npos) << e.what();
    }
  };
  refuses(R"({"type": "thermal", "phases": []})", "key 'phases'");
  refuses(R"({"type": "thermal", "interval_s": 0, "phases": [{"duration_min": 1, "speed_rpm": 0}]})",
          "key 'interval_s'");
  refuses(R"({"type": "thermal", "phases": [{"duration_min": 1, "speed_rpm": -5}]})", "phases[0].speed_rpm");
  refuses(R"({"type": "thermal", "phases": [{"duration_min": 1, "speed_rpm": 5}], "displacement": {"axis": "X"}})",
          "displacement.axis");
  // A phase of 1e9 min (1900 years) is no plan; a month is the longest.
  refuses(R"({"type": "thermal", "phases": [{"duration_min": 1e9, "speed_rpm": 0}]})",
          "key 'phases[0].duration_min': must be > 0 and at most 43200 (30 days)");
  // Two channels of one name would be one channel in the store: refused before anything runs.
  refuses(R"({"type": "thermal", "phases": [{"duration_min": 1, "speed_rpm": 0}], "sensors": ["spindle", "spindle"]})",
          "key 'sensors[1]': 'spindle' is already the name of sensors[0]: every channel needs its own");
  refuses(R"({"type": "thermal", "phases": [{"duration_min": 1, "speed_rpm": 0}], "sensors": ["bed"],
              "displacement": {"name": "bed"}})",
          "key 'displacement.name': 'bed' is already the name of sensors[0]");
  refuses(R"({"type": "thermal", "phases": [{"duration_min": 1, "speed_rpm": 0}], "displacement": {"name": "T3"}})",
          "'T3' is already the name of unnamed sensor 3");
  refuses(R"({"type": "thermal", "phases": [{"duration_min": 1, "speed_rpm": 0}], "sensors": ["spindle_rpm"]})",
          "key 'sensors[0]': 'spindle_rpm' is already the name of the spindle's speed");
  refuses(R"({"type": "thermal", "phases": [{"duration_min": 1, "speed_rpm": 0}], "sensors": ["air_temp_c"],
              "environment": true})",
          "'air_temp_c' is already the name of the environment unit's air temperature");
}

}  // namespace
}  // namespace mtcal::acquisition
