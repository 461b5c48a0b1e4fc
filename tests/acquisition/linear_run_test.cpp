#include "mtcal/acquisition/linear_run.h"

#include <gtest/gtest.h>

#include <optional>
#include <set>

#include "../support/temp_dir.h"
#include "../support/time_scale.h"
#include "mtcal/error.h"
#include "mtcal/mocks/gcode_player.h"
#include "mtcal/services/workshop.h"

namespace mtcal::acquisition {
namespace {

namespace ifm = drivers::interferometer;

// Runs linear plans on the simulated machine through the real driver, emulator and store.
class LinearRunTest : public ::testing::Test {
 protected:
  void SetUp() override {
    plan_.start_mm = 50;
    plan_.end_mm = 90;
    plan_.step_mm = 20;
    plan_.repeats = 3;
    plan_.datum_mm = 50;
    plan_.dwell_s = 0.5;  // 10 settling time constants of the demo machine
    plan_.window_s = 0.05;
    plan_.sample_rate_hz = 1000;
  }
  // At most 400 world seconds per second (a 1 kHz stream is then 400 000 samples/s of wall
  // time). The world runs in lock step with the run: the pace changes how long a test takes,
  // never what it measures.
  std::unique_ptr<services::Simulation> simulation(mocks::VirtualMachineConfig config, double time_scale = 400.0) {
    return std::make_unique<services::Simulation>(std::move(config), services::demoInterferometer(),
                                                  mtcal::testing::timeScale(time_scale));
  }
  // The demo machine without positioning scatter: every capture is then comparable with
  // the truth within the instrument noise.
  static mocks::VirtualMachineConfig exactMachine() {
    auto c = mocks::VirtualMachineConfig::demo(5);
    for (auto& a : c.axes) a.positioning_sigma_um = 0.0;
    return c;
  }

  // Options of a run on the simulated world: it runs in lock step with the run.
  static LinearRunOptions lockStep(services::Simulation& sim) {
    LinearRunOptions options;
    options.run_clock = &sim.run_clock;
    return options;
  }

  storage::Id campaign(storage::Store& store) { return store.addCampaign(store.ensureMachine("vm", "", "{}"), "c"); }

  // The true error the run should have measured at a target: the machine's static error at
  // the target and approach direction, relative to the datum approached upwards.
  static double truthUm(const services::Simulation& sim, const storage::TargetRecord& t) {
    const auto& machine = sim.world.machine;
    const auto offset = sim.world.interferometer->config().beam_offset_mm;
    return machine.staticErrorUm(mocks::Axis::kX, offset, t.target_mm, t.direction) -
           machine.staticErrorUm(mocks::Axis::kX, offset, 50.0, +1);
  }

  // The message of the DeviceError a run of plan_ fails with.
  std::string failure(LinearRun& run, storage::Store& store) {
    try {
      run.start(plan_, campaign(store), std::nullopt);
    } catch (const DeviceError& e) {
      return e.what();
    }
    ADD_FAILURE() << "the run did not fail";
    return {};
  }

  mtcal::testing::TempDir dir_;
  std::string db_path_ = dir_.file("run.sqlite");
  LinearPlan plan_;
};

TEST_F(LinearRunTest, CapturesEveryTargetWithItsRawSamplesAndMatchesTheTruth) {
  auto sim = simulation(exactMachine());
  storage::Store store(db_path_);
  auto device = sim->registry.openAs<ifm::InterferometerDevice>("mock://interferometer");
  std::vector<LinearProgress> progress;
  LinearRunOptions options;
  options.run_clock = &sim->run_clock;
  options.on_progress = [&](const LinearProgress& p) { progress.push_back(p); };
  LinearRun run(store, *device, &sim->controller, options);
  const storage::Id id = run.start(plan_, campaign(store), std::nullopt);
  EXPECT_EQ(run.outcome(), RunOutcome::kCompleted);
  EXPECT_EQ(store.run(id).status, "completed");
  const auto targets = store.targets(id);
  ASSERT_EQ(targets.size(), 18u);
  ASSERT_EQ(progress.size(), 18u);
  EXPECT_EQ(progress.back().done, 18u);
  EXPECT_EQ(progress.back().total, 18u);

  const auto& machine = sim->world.machine;
  for (const auto& t : targets) {
    // Instrument noise 0.02 um / sqrt(50) and the environment sensors' noise: 0.02 um is ample.
    EXPECT_NEAR(t.deviation_um, truthUm(*sim, t), 0.02) << t.target_mm << " " << t.direction << " " << t.cycle;
    EXPECT_EQ(t.sample_count, 50);
    EXPECT_TRUE(t.air_index.has_value());
    EXPECT_NEAR(*t.material_temp_c, machine.config().material_temp_c, 0.05);
    const auto samples = store.samplesOfTarget(id, t.seq);
    ASSERT_EQ(samples.size(), 50u);
    EXPECT_EQ(samples.back().device_seq - samples.front().device_seq, 49);
  }
  // One environment reading per target, with the material sensor.
  storage::Statement env(store.database(), "SELECT COUNT(*), MIN(material_temp1_c) FROM environment WHERE run_id = ?");
  env.bind(1, id);
  ASSERT_TRUE(env.step());
  EXPECT_EQ(env.getInt(0), 18);
  EXPECT_NEAR(env.getDouble(1), machine.config().material_temp_c, 0.05);
  // The backlash of the demo machine shows as the reversal: up - down = -2.5 um.
  EXPECT_NEAR(targets[1].deviation_um - targets[4].deviation_um, -2.5, 0.05);  // 70 mm up vs down, cycle 1
}

TEST_F(LinearRunTest, InterruptedRunKeepsItsTargetsAndResumes) {
  auto sim = simulation(exactMachine());
  storage::Store store(db_path_);
  auto device = sim->registry.openAs<ifm::InterferometerDevice>("mock://interferometer");
  std::atomic<bool> stop{false};
  LinearRunOptions options;
  options.run_clock = &sim->run_clock;
  options.stop_requested = &stop;
  options.on_progress = [&](const LinearProgress& p) {
    if (p.done == 5) stop = true;
  };
  LinearRun run(store, *device, &sim->controller, options);
  const storage::Id id = run.start(plan_, campaign(store), std::nullopt);
  EXPECT_EQ(run.outcome(), RunOutcome::kInterrupted);
  EXPECT_EQ(store.run(id).status, "interrupted");
  EXPECT_EQ(store.targets(id).size(), 5u);

  stop = false;
  options.on_progress = nullptr;
  LinearRun again(store, *device, &sim->controller, options);
  again.resume(id);
  EXPECT_EQ(again.outcome(), RunOutcome::kCompleted);
  EXPECT_EQ(store.run(id).status, "completed");
  const auto targets = store.targets(id);
  ASSERT_EQ(targets.size(), 18u);
  std::set<std::int64_t> seqs;
  for (const auto& t : targets) seqs.insert(t.seq);
  EXPECT_EQ(seqs.size(), 18u);
  // The resumed part approached each target from the planned side: its reversal is right.
  EXPECT_NEAR(targets[13].deviation_um - targets[16].deviation_um, -2.5, 0.05);  // 70 mm, cycle 3
  EXPECT_THROW(again.resume(id), InputError);                                    // already completed
}

TEST_F(LinearRunTest, ADisconnectMarksTheRunInterruptedAndKeepsCompletedTargets) {
  auto sim = simulation(exactMachine());
  storage::Store store(db_path_);
  auto device = sim->registry.openAs<ifm::InterferometerDevice>("mock://interferometer");
  LinearRunOptions options;
  options.run_clock = &sim->run_clock;
  options.on_progress = [&](const LinearProgress& p) {
    if (p.done == 4) {
      sim->world.interferometer->updateFaults([](auto& f) { f.disconnected = true; });
    }
  };
  LinearRun run(store, *device, &sim->controller, options);
  const storage::Id c = campaign(store);
  EXPECT_THROW(run.start(plan_, c, std::nullopt), TransportError);
  const auto runs = store.listRuns();
  ASSERT_EQ(runs.size(), 1u);
  EXPECT_EQ(runs[0].status, "interrupted");
  EXPECT_EQ(store.targets(runs[0].id).size(), 4u);
  const auto events = store.events(runs[0].id);
  EXPECT_EQ(events.back().level, "error");
  EXPECT_NE(events.back().message.find("disconnected"), std::string::npos) << events.back().message;
}

// A device that goes silent mid-run (it neither answers nor streams), then is back: the run
// stops naming the device and the stall, keeps its targets, and resumes to completion.
TEST_F(LinearRunTest, ASilentInterferometerStopsTheRunWhichResumesWhenItIsBack) {
  auto sim = simulation(exactMachine());
  storage::Store store(db_path_);
  const storage::Id c = campaign(store);
  storage::Id id = 0;
  std::vector<storage::TargetRecord> kept;
  {
    auto device = sim->registry.openAs<ifm::InterferometerDevice>("mock://interferometer");
    LinearRunOptions options;
    options.run_clock = &sim->run_clock;
    options.on_progress = [&](const LinearProgress& p) {
      if (p.done == 4) sim->world.interferometer->updateFaults([](auto& f) { f.silent = true; });
    };
    LinearRun run(store, *device, &sim->controller, options);
    try {
      run.start(plan_, c, std::nullopt);
      FAIL() << "a silent device went unnoticed";
    } catch (const TransportError& e) {
      // The device and what happened (the emulators' stall timeout is 30 s: a loaded host never trips it).
      EXPECT_NE(std::string(e.what()).find("mock://interferometer: stream stalled"), std::string::npos) << e.what();
    }
    id = store.listRuns().front().id;
    EXPECT_EQ(store.run(id).status, "interrupted");
    kept = store.targets(id);
    EXPECT_EQ(kept.size(), 4u);
  }
  sim->world.interferometer->updateFaults([](auto& f) { f = {}; });
  auto device = sim->registry.openAs<ifm::InterferometerDevice>("mock://interferometer");
  LinearRunOptions options;
  options.run_clock = &sim->run_clock;
  LinearRun again(store, *device, &sim->controller, options);
  again.resume(id);
  EXPECT_EQ(again.outcome(), RunOutcome::kCompleted);
  const auto all = store.targets(id);
  EXPECT_EQ(all.size(), linearTargets(plan_).size());
  for (std::size_t k = 0; k < kept.size(); ++k) EXPECT_EQ(all[k].deviation_um, kept[k].deviation_um);
}

TEST_F(LinearRunTest, AReadingThatNeverSettlesIsReportedWithItsNumbers) {
  auto config = exactMachine();
  config.settle_time_constant_s = 5.0;  // a sluggish axis
  auto sim = simulation(config);
  storage::Store store(db_path_);
  auto device = sim->registry.openAs<ifm::InterferometerDevice>("mock://interferometer");
  plan_.dwell_s = 0.0;
  plan_.stability_threshold_um = 0.1;
  plan_.stability_timeout_s = 1.0;
  LinearRun run(store, *device, &sim->controller, lockStep(*sim));
  const std::string error = failure(run, store);
  EXPECT_NE(error.find("not stable within 1 s"), std::string::npos) << error;
}

TEST_F(LinearRunTest, ABlockedBeamIsNamed) {
  auto sim = simulation(exactMachine());
  sim->world.interferometer->updateFaults([](auto& f) { f.beam_blocked = true; });
  storage::Store store(db_path_);
  auto device = sim->registry.openAs<ifm::InterferometerDevice>("mock://interferometer");
  plan_.stability_timeout_s = 0.5;
  LinearRun run(store, *device, &sim->controller, lockStep(*sim));
  const std::string error = failure(run, store);
  EXPECT_NE(error.find("beam lost"), std::string::npos) << error;
}

// The real-machine workflow: no controller; the virtual CNC runs the plan's own part program
// (started when mtcal is ready, like an operator pressing cycle start) and every target is
// captured when the machine holds it.
TEST_F(LinearRunTest, ATriggeredRunFollowsThePartProgram) {
  auto sim = simulation(exactMachine());
  storage::Store store(db_path_);
  auto device = sim->registry.openAs<ifm::InterferometerDevice>("mock://interferometer");
  std::optional<mocks::CncProgramRun> cnc;  // cycle start when the run waits for the program
  LinearRunOptions options;
  options.run_clock = &sim->run_clock;
  options.on_waiting_for_program = [&] { cnc.emplace(sim->world.machine, mocks::parseGcode(linearGcode(plan_))); };
  LinearRun run(store, *device, nullptr, options);
  const storage::Id id = run.start(plan_, campaign(store), std::nullopt);
  const auto targets = store.targets(id);
  ASSERT_EQ(targets.size(), 18u);
  for (const auto& t : targets) {
    EXPECT_NEAR(t.deviation_um, truthUm(*sim, t), 0.02) << t.target_mm << " " << t.direction << " " << t.cycle;
  }
  EXPECT_THROW(LinearRun(store, *device, nullptr, {}).resume(id), InputError);
}

TEST_F(LinearRunTest, ATriggeredRunNamesTheTargetTheMachineNeverReached) {
  auto sim = simulation(exactMachine());
  storage::Store store(db_path_);
  auto device = sim->registry.openAs<ifm::InterferometerDevice>("mock://interferometer");
  // A program that stops after the first target: 70 mm is never held.
  auto program = mocks::parseGcode(linearGcode(plan_));
  program.resize(6);  // approach, datum, dwell, overrun, target 50, dwell
  // 10 s of world time are 0.2 s of wall time at 50x: room for a loaded test machine to
  // capture 50 mm before the timeout that must name 70 mm.
  plan_.trigger_timeout_s = 10.0;
  std::optional<mocks::CncProgramRun> cnc;  // cycle start when the run waits for the program
  LinearRunOptions options;
  options.run_clock = &sim->run_clock;
  options.on_waiting_for_program = [&] { cnc.emplace(sim->world.machine, program); };
  LinearRun run(store, *device, nullptr, options);
  const std::string error = failure(run, store);
  EXPECT_NE(error.find("target 70.000 mm (up, cycle 1): the machine did not hold still"), std::string::npos) << error;
  EXPECT_EQ(store.targets(store.listRuns()[0].id).size(), 1u);  // 50 mm was captured and kept
}

// A program whose holds are too short: with a dwell of 0.2 s and a 0.3 s window, after a
// 20 mm move the hold is seen about 0.53 s after the machine arrives (settling takes about
// 0.23 s), but averaging would need until about 0.73 s, and the program holds 0.6 s. The machine leaves before
// the capture; the run must stop with that reason instead of storing the reading of wherever
// the machine went next.
TEST_F(LinearRunTest, ATriggeredCaptureNeverTakesAnotherPosition) {
  auto sim = simulation(exactMachine());
  storage::Store store(db_path_);
  auto device = sim->registry.openAs<ifm::InterferometerDevice>("mock://interferometer");
  plan_.dwell_s = 0.2;
  plan_.window_s = 0.3;
  plan_.trigger_timeout_s = 5.0;
  auto program = mocks::parseGcode(linearGcode(plan_));
  for (auto& block : program) {
    if (block.kind == mocks::GcodeBlock::Kind::kDwell) block.value = 0.6;
  }
  std::optional<mocks::CncProgramRun> cnc;  // cycle start when the run waits for the program
  LinearRunOptions options;
  options.run_clock = &sim->run_clock;
  options.on_waiting_for_program = [&] { cnc.emplace(sim->world.machine, program); };
  LinearRun run(store, *device, nullptr, options);
  const std::string error = failure(run, store);
  // Short moves (5 mm to the datum and the first target) settle in time; the first 20 mm move
  // (to 70 mm) does not.
  EXPECT_NE(error.find("the machine left the position before it could be averaged (moved 20.0"), std::string::npos)
      << error;
  for (const auto& t : store.targets(store.listRuns()[0].id)) EXPECT_NEAR(t.deviation_um, 0.0, 5.0);  // none misplaced
}

TEST_F(LinearRunTest, TheSameSeedGivesTheSameCampaign) {
  auto deviations = [&](const std::string& db) {
    auto sim = simulation(mocks::VirtualMachineConfig::demo(21));  // with positioning scatter
    storage::Store store(db);
    auto device = sim->registry.openAs<ifm::InterferometerDevice>("mock://interferometer");
    LinearRun run(store, *device, &sim->controller, lockStep(*sim));
    const auto id = run.start(plan_, campaign(store), std::nullopt);
    std::vector<double> v;
    for (const auto& t : store.targets(id)) v.push_back(t.deviation_um);
    return v;
  };
  const auto a = deviations(dir_.file("a.sqlite"));
  const auto b = deviations(dir_.file("b.sqlite"));
  ASSERT_EQ(a.size(), 18u);
  EXPECT_EQ(a, b);  // bit for bit
}

}  // namespace
}  // namespace mtcal::acquisition
