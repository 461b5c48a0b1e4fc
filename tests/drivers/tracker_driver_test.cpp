// The laser tracker: codec, driver against scripted TCP servers (exact bytes, real sockets on
// 127.0.0.1), and driver against the emulator observing the virtual machine.

#include <gtest/gtest.h>

#include <cmath>
#include <mutex>
#include <string>
#include <vector>

#include "../support/scripted_tcp_server.h"
#include "../support/time_scale.h"
#include "mtcal/drivers/registry.h"
#include "mtcal/drivers/tracker/driver.h"
#include "mtcal/error.h"
#include "mtcal/mocks/tracker_emulator.h"
#include "mtcal/processing/air_index.h"

namespace mtcal::drivers::tracker {
namespace {

using namespace std::chrono_literals;
using Server = mtcal::testing::ScriptedTcpServer;

const std::string kHello = " OK MTCAL-TRACKER PROTO 1.0 MODEL MT-LT900 SERIAL LT-7 FW 2.1\n";

std::unique_ptr<TrackerDevice> open(const Server& server, Timeouts timeouts = {}) {
  return std::make_unique<TrackerDevice>(std::make_unique<TcpTransport>("127.0.0.1", server.port()), "tcp://test",
                                         timeouts);
}

TEST(TrackerProtocol, RoundTripsAndRefusesMalformedLines) {
  EXPECT_EQ(formatRequest({7, "MEAS", {"500"}}), "7 MEAS 500\n");
  const Request r = parseRequest("12 ENV 20.5 1001.2 45\r\n");
  EXPECT_EQ(r.tag, 12u);
  EXPECT_EQ(r.verb, "ENV");
  EXPECT_EQ(r.args, (std::vector<std::string>{"20.5", "1001.2", "45"}));
  const auto err = std::get<Reply>(parseMessage("3 ERR 4 beam broken: no reflector locked"));
  EXPECT_EQ(err.kind, Reply::Kind::kError);
  EXPECT_EQ(err.error_code(), 4);
  EXPECT_EQ(err.error_text(), "beam broken: no reflector locked");
  const Point p{{1000.5, -20.25, 3.125}, 4.5, 12.75, 500};
  const Point q = parsePoint(std::get<Reply>(parseMessage(formatReply({Reply::Kind::kOk, 9, pointFields(p)}))).fields);
  EXPECT_EQ(q.xyz_mm, p.xyz_mm);
  EXPECT_EQ(q.readings, 500);
  const StreamPoint s =
      parseStreamPoint(std::get<Event>(parseMessage(formatEvent(streamPointEvent({41, 2.5, {1, 2, 3}})))));
  EXPECT_EQ(s.seq, 41u);
  EXPECT_EQ(s.xyz_mm[2], 3.0);
  for (const char* bad : {"OK", "x OK", "0 OK", "5 MAYBE", "5 ERR", "! "}) {
    EXPECT_THROW(parseMessage(bad), ProtocolError) << bad;
  }
  EXPECT_THROW(parseMessage(std::string(2000, '1') + " OK"), ProtocolError);
  EXPECT_THROW(parsePoint({"PT", "1", "2", "x", "4", "5", "6"}), ProtocolError);
  EXPECT_THROW(parsePoint({"PT", "1", "2"}), ProtocolError);
  EXPECT_THROW(parseStatus({"STATUS", "READY", "BEAM", "HALF", "REFLECTOR", "R", "ENV", "20", "1013", "50"}),
               ProtocolError);
}

TEST(TrackerProtocol, VersionNegotiationRefusesAnotherMajorAndIgnoresNewerMinorsFields) {
  const Hello h =
      parseHello({"MTCAL-TRACKER", "PROTO", "1.3", "MODEL", "M", "SERIAL", "S", "FW", "F", "FEATURES", "6DOF"});
  EXPECT_EQ(h.minor, 3);
  EXPECT_EQ(h.model, "M");
  try {
    parseHello({"MTCAL-TRACKER", "PROTO", "2.0", "MODEL", "M", "SERIAL", "S", "FW", "F"});
    FAIL();
  } catch (const ProtocolError& e) {
    EXPECT_NE(std::string(e.what()).find("protocol 2.0"), std::string::npos) << e.what();
  }
  // A 1.x point with a field appended (e.g. a temperature) still parses.
  EXPECT_EQ(parsePoint({"PT", "1", "2", "3", "4", "5", "6", "20.1"}).xyz_mm[1], 2.0);
}

TEST(TrackerDriver, SpeaksTheProtocolByteForByteAndRetriesABusyTracker) {
  Server server({Server::accept(), Server::expect("1 HELLO\n"), Server::send("1" + kHello), Server::expect("2 INIT\n"),
                 Server::send("2 BUSY\n"), Server::expect("3 INIT\n"), Server::send("3 BUSY\n"),
                 Server::expect("4 INIT\n"), Server::send("4 OK\n"), Server::expect("5 UNITS MM DEG C HPA\n"),
                 Server::send("5 OK\n"), Server::expect("6 ENV 20.40 1006.50 42.0\n"), Server::send("6 OK\n"),
                 Server::expect("7 REFLECTOR RRR1.5\n"), Server::send("7 OK\n"), Server::expect("8 MEAS 500\n"),
                 Server::send("! BEAM LOCKED\n8 OK PT 1200.5 -30.25 10 3.1 55.5 500\n"), Server::expect("9 STATUS\n"),
                 Server::send("9 OK STATUS READY BEAM LOCKED REFLECTOR RRR1.5 ENV 20.40 1006.50 42.0\n")});
  auto t = open(server);
  EXPECT_EQ(t->info().model, "MT-LT900");
  EXPECT_EQ(t->info().kind, "tracker");
  t->initialise();
  t->setUnits();
  t->setEnvironment({20.4, 1006.5, 42.0});
  t->setReflector("RRR1.5");
  const Point p = t->measure(500);
  EXPECT_DOUBLE_EQ(p.xyz_mm[0], 1200.5);
  EXPECT_DOUBLE_EQ(p.xyz_mm[1], -30.25);
  EXPECT_DOUBLE_EQ(p.time_s, 55.5);
  const Status s = t->status();
  EXPECT_TRUE(s.beam_locked);
  EXPECT_EQ(s.reflector, "RRR1.5");
  EXPECT_DOUBLE_EQ(s.pressure_hpa, 1006.5);
  EXPECT_THROW(t->measure(0), InputError);
  EXPECT_THROW(t->setEnvironment({80.0, 1000.0, 50.0}), InputError);
}

TEST(TrackerDriver, ErrorRepliesNameTheCommandAndTheTrackersReason) {
  Server server({Server::accept(), Server::expect("1 HELLO\n"), Server::send("1" + kHello),
                 Server::expect("2 MEAS 100\n"), Server::send("2 ERR 4 beam broken: no reflector locked\n")});
  auto t = open(server);
  try {
    t->measure(100);
    FAIL();
  } catch (const DeviceError& e) {
    EXPECT_STREQ(e.what(), "tcp://test: MEAS 100: error 4 (beam broken): beam broken: no reflector locked");
  }
}

TEST(TrackerDriver, AMalformedReplyIsAProtocolErrorQuotingTheLine) {
  Server server({Server::accept(), Server::expect("1 HELLO\n"), Server::send("1" + kHello),
                 Server::expect("2 MEAS 10\n"), Server::send("2 OK PT 1.0 2.0 nan 4 5 10\n")});
  auto t = open(server);
  try {
    t->measure(10);
    FAIL();
  } catch (const ProtocolError& e) {
    EXPECT_NE(std::string(e.what()).find("'nan' is not a number"), std::string::npos) << e.what();
  }
}

TEST(TrackerDriver, RefusesATrackerOfAnotherMajorVersion) {
  Server server({Server::accept(), Server::expect("1 HELLO\n"),
                 Server::send("1 OK MTCAL-TRACKER PROTO 2.0 MODEL X SERIAL Y FW Z\n")});
  EXPECT_THROW(open(server), ProtocolError);
}

TEST(TrackerDriver, ReconnectsRestoresTheSessionAndRepeatsTheCommand) {
  Server server({Server::accept(), Server::expect("1 HELLO\n"), Server::send("1" + kHello),
                 Server::expect("2 UNITS MM DEG C HPA\n"), Server::send("2 OK\n"),
                 Server::expect("3 REFLECTOR RRR0.5\n"), Server::send("3 OK\n"), Server::close(),
                 // tag 4: the MEAS lost with the connection
                 Server::accept(), Server::expect("5 HELLO\n"), Server::send("5" + kHello),
                 Server::expect("6 UNITS MM DEG C HPA\n"), Server::send("6 OK\n"),
                 Server::expect("7 REFLECTOR RRR0.5\n"), Server::send("7 OK\n"), Server::expect("8 MEAS 10\n"),
                 Server::send("8 OK PT 1 2 3 4 5 10\n")});
  auto t = open(server);
  t->setUnits();
  t->setReflector("RRR0.5");
  while (server.stepsRun() < 8) std::this_thread::sleep_for(5ms);
  EXPECT_DOUBLE_EQ(t->measure(10).xyz_mm[2], 3.0);
  EXPECT_EQ(t->reconnects(), 1);
}

TEST(TrackerDriver, ASilentTrackerTimesOut) {
  Server server({Server::accept(), Server::expect("1 HELLO\n"), Server::send("1" + kHello),
                 Server::expect("2 STATUS\n"), Server::silence()});
  Timeouts timeouts;
  timeouts.command = 300ms;
  auto t = open(server, timeouts);
  const auto before = std::chrono::steady_clock::now();
  // The server stays silent until the test ends: only the command timeout ends the wait.
  EXPECT_THROW(t->status(), TimeoutError);
  EXPECT_GE(std::chrono::steady_clock::now() - before, 300ms - 10ms);  // the timeout, within the clock's ms rounding
}

class Collect : public SampleSink {
 public:
  void push(std::span<const Sample> samples) override {
    std::lock_guard lock(mutex);
    all.insert(all.end(), samples.begin(), samples.end());
  }
  std::vector<Sample> take() {
    std::lock_guard lock(mutex);
    return all;
  }
  /// Waits until a sample time-stamped at or after `device_time_s` has arrived. @return arrived
  bool waitUntil(double device_time_s, std::chrono::milliseconds limit) {
    const auto deadline = std::chrono::steady_clock::now() + limit;
    for (;;) {
      {
        std::lock_guard lock(mutex);
        if (!all.empty() && static_cast<double>(all.back().device_time_ns) * 1e-9 >= device_time_s) return true;
      }
      if (std::chrono::steady_clock::now() > deadline) return false;
      std::this_thread::sleep_for(1ms);
    }
  }
  std::mutex mutex;
  std::vector<Sample> all;
};

TEST(TrackerDriver, ContinuousMeasurementDeliversXyzSamplesCountsGapsAndRefusesOtherCommands) {
  Server server({Server::accept(), Server::expect("1 HELLO\n"), Server::send("1" + kHello),
                 Server::expect("2 CONT 100\n"),
                 Server::send("2 OK\n! PT 0 1.00 10 20 30\n! PT 1 1.01 11 21 31\n! PT 3 1.03 13 23 33\n"),
                 Server::expect("3 CONT STOP\n"), Server::send("! PT 4 1.04 14 24 34\n3 OK\n")});
  auto t = open(server);
  Collect sink;
  t->startStream(100, sink);
  EXPECT_THROW(t->measure(10), DeviceError);
  while (sink.take().size() < 9) std::this_thread::sleep_for(5ms);
  const StreamStats stats = t->stopStream();
  const auto samples = sink.take();
  ASSERT_EQ(samples.size(), 12u);  // 4 points x 3 coordinates, the last one in flight at the stop
  EXPECT_EQ(samples[6].seq, 3u);
  EXPECT_EQ(samples[7].channel, 2);
  EXPECT_DOUBLE_EQ(samples[7].value, 23.0);
  EXPECT_EQ(samples[6].device_time_ns, 1030000000);
  EXPECT_EQ(stats.samples, 4u);
  EXPECT_EQ(stats.lost_samples, 1u);
  // Channels 1..3 are the coordinates x, y, z of a position in mm; no signal measured.
  const auto channels = t->streamChannels();
  ASSERT_EQ(channels.size(), 3u);
  for (int k = 0; k < 3; ++k) {
    const auto& c = channels[static_cast<std::size_t>(k)];
    EXPECT_EQ(c.channel, k + 1);
    EXPECT_EQ(c.name, std::string(1, static_cast<char>('x' + k)));
    EXPECT_EQ(c.quantity, "position");
    EXPECT_EQ(c.unit, "mm");
    EXPECT_EQ(c.signal_quantity, "");
    EXPECT_EQ(samples[3 + static_cast<std::size_t>(k)].channel, c.channel);
  }
}

TEST(TrackerDriver, AStalledStreamIsReported) {
  Server server({Server::accept(), Server::expect("1 HELLO\n"), Server::send("1" + kHello),
                 Server::expect("2 CONT 50\n"), Server::send("2 OK\n! PT 0 1.00 10 20 30\n"), Server::silence()});
  Timeouts timeouts;
  timeouts.stall = 200ms;
  auto t = open(server, timeouts);
  Collect sink;
  const auto started = std::chrono::steady_clock::now();
  t->startStream(50, sink);
  // Silent after the first point until the test ends: the reader reports the stall, not
  // before the stall timeout.
  bool stalled = false;
  while (!stalled) {
    try {
      t->poll();
      std::this_thread::sleep_for(5ms);
    } catch (const TimeoutError& e) {
      stalled = true;
      EXPECT_NE(std::string(e.what()).find("stalled"), std::string::npos) << e.what();
    }
  }
  EXPECT_GE(std::chrono::steady_clock::now() - started, 200ms);
  EXPECT_THROW(t->stopStream(), TimeoutError);
}

// The emulator on the virtual machine: the driver against a real TCP server. The world runs
// in lock step with the test (clock.advanceTo), and as far as the tracker's answers need.
struct World {
  explicit World(double time_scale = 50.0)
      : clock(time_scale, mocks::WorldClock::Mode::kLockStep), machine(mocks::VirtualMachineConfig::demo(3), clock) {}
  mocks::WorldClock clock;
  mocks::VirtualMachine machine;
};

mocks::TrackerEmulatorConfig emulatorConfig(const mocks::VirtualMachine& machine) {
  auto c = mocks::TrackerEmulatorConfig::forGantry(machine.config(), 11);
  c.noise.outlier_probability = 0.0;
  return c;
}

std::unique_ptr<TrackerDevice> openEmulator(const mocks::TrackerEmulator& e) {
  auto t = e.connect("tcp://emulator");
  t->initialise();
  t->setUnits();
  return t;
}

Eigen::Vector3d toTracker(const mocks::TrackerEmulator& e, const Eigen::Vector3d& bed) {
  return e.config().bedFromTracker().inverse() * bed;
}

TEST(TrackerEmulator, MeasuresTheMachineWithAnisotropicNoiseThatFallsWithIntegration) {
  World w(mtcal::testing::timeScale(200.0));
  w.machine.moveTo(mocks::Axis::kX, 300.0);
  mocks::TrackerEmulator emulator(w.machine, emulatorConfig(w.machine));
  auto t = openEmulator(emulator);
  t->setEnvironment(
      {w.machine.config().air_temp_c, w.machine.config().air_pressure_pa / 100.0, w.machine.config().humidity_pct});
  EXPECT_THROW(t->measure(100), DeviceError);  // no reflector placed yet: beam broken
  emulator.placeReflector("TB1");
  w.clock.advanceTo(3.0 + 2.0);  // the move (3 s) is over and the machine settled
  const Eigen::Vector3d truth = toTracker(emulator, emulator.truePlaceMm("TB1", w.clock.nowS()));
  const Eigen::Vector3d radial = truth.normalized();
  const auto spread = [&](int integration_ms, int n) {
    double radial2 = 0.0, transverse2 = 0.0;
    for (int i = 0; i < n; ++i) {
      const Point p = t->measure(integration_ms);
      const Eigen::Vector3d d = Eigen::Vector3d(p.xyz_mm[0], p.xyz_mm[1], p.xyz_mm[2]) - truth;
      radial2 += std::pow(d.dot(radial), 2);
      transverse2 += (d - d.dot(radial) * radial).squaredNorm() / 2.0;
    }
    return std::pair{std::sqrt(radial2 / n) * 1000.0, std::sqrt(transverse2 / n) * 1000.0};
  };
  const auto [short_radial_um, short_transverse_um] = spread(2, 60);
  const auto [long_radial_um, long_transverse_um] = spread(1000, 30);
  // The configured sigma at range L: (1 + 0.3 L) um along, (3 + 1.5 L) um across, times
  // sqrt(1 + 25/T): at 2 ms 3.67x, at 1 s 1.012x. 30-60 draws: within 35 % (chi, > 3 sigma).
  const double range_m = truth.norm() / 1000.0;
  const double along_1s = 1.0 + 0.3 * range_m, across_1s = 3.0 + 1.5 * range_m;
  EXPECT_NEAR(short_radial_um, along_1s * std::sqrt(13.5), 0.35 * along_1s * std::sqrt(13.5));
  EXPECT_NEAR(short_transverse_um, across_1s * std::sqrt(13.5), 0.35 * across_1s * std::sqrt(13.5));
  EXPECT_NEAR(long_transverse_um, across_1s * std::sqrt(1.025), 0.35 * across_1s * std::sqrt(1.025));
  EXPECT_LT(long_radial_um, long_transverse_um);
  EXPECT_GT(short_transverse_um / long_transverse_um, 3.0);
}

TEST(TrackerEmulator, AWrongEnvironmentScalesTheDistances) {
  World w(mtcal::testing::timeScale(200.0));
  auto config = emulatorConfig(w.machine);
  config.noise = {0, 0, 0, 0, 250, 0, 100, 0};  // noise-free: the scale alone
  mocks::TrackerEmulator emulator(w.machine, config);
  auto t = openEmulator(emulator);
  emulator.placeReflector("C.top");
  const auto& m = w.machine.config();
  t->setEnvironment({m.air_temp_c, m.air_pressure_pa / 100.0, m.humidity_pct});
  const Point right = t->measure(1);
  const Eigen::Vector3d truth = toTracker(emulator, emulator.truePlaceMm("C.top", 0.0, 0));
  EXPECT_LT((Eigen::Vector3d(right.xyz_mm[0], right.xyz_mm[1], right.xyz_mm[2]) - truth).norm(), 1e-6);
  t->setEnvironment({20.0, 1013.25, 50.0});  // the defaults, not the shop's air
  const Point wrong = t->measure(1);
  const Eigen::Vector3d truth2 = toTracker(emulator, emulator.truePlaceMm("C.top", 0.0, 1));
  const double n_true = processing::edlenIndex({m.air_temp_c, m.air_pressure_pa, m.humidity_pct}, 632.99);
  const double n_set = processing::edlenIndex({20.0, 101325.0, 50.0}, 632.99);
  const double ratio = Eigen::Vector3d(wrong.xyz_mm[0], wrong.xyz_mm[1], wrong.xyz_mm[2]).norm() / truth2.norm();
  EXPECT_NEAR((ratio - 1.0) * 1e6, (n_true / n_set - 1.0) * 1e6, 1e-3);
  EXPECT_GT(std::abs(ratio - 1.0) * 1e6, 1.0);  // a ppm-level error, as on a real tracker
}

TEST(TrackerEmulator, TracksAMovingGantryContinuouslyAndSurvivesABrokenBeamAndADroppedLink) {
  World w(mtcal::testing::timeScale(50.0));
  mocks::TrackerEmulator emulator(w.machine, emulatorConfig(w.machine));
  auto t = openEmulator(emulator);
  emulator.placeReflector("TB2");
  Collect sink;
  t->startStream(500, sink);
  const double start_s = w.clock.nowS();
  const double done = w.machine.moveTo(mocks::Axis::kX, 600.0);
  w.clock.advanceTo(done + 0.2);
  emulator.breakBeam();
  w.clock.advanceTo(done + 0.4);
  emulator.placeReflector("TB2");
  w.clock.advanceTo(done + 0.6);
  // Every point up to then, before the stream stops.
  ASSERT_TRUE(sink.waitUntil(done + 0.6 - 0.002, 10s));
  const StreamStats stats = t->stopStream();
  const auto samples = sink.take();
  ASSERT_EQ(samples.size() % 3, 0u);
  // 6 s of motion and 0.6 s after it at 500 points/s, on the world's grid of 2 ms: the 100
  // points of the 0.2 s without beam are lost (one more or less as the edges, computed in
  // floating point, fall on a point of the grid or beside it), the rest arrive.
  const double points_in_stream = (done + 0.6 - start_s) * 500.0;
  EXPECT_GE(stats.lost_samples, 99u);
  EXPECT_LE(stats.lost_samples, 101u);
  EXPECT_NEAR(static_cast<double>(stats.samples + stats.lost_samples), points_in_stream, 1.0);
  EXPECT_EQ(stats.samples * 3, samples.size());
  // Every point lies on the reflector's path at its time stamp, with the noise of a 2 ms
  // integration: rms sqrt(sd_along^2 + 2 sd_across^2) (within 30 %, ~90 points).
  double sum2 = 0.0, expected2 = 0.0;
  int n = 0;
  for (std::size_t i = 0; i < samples.size(); i += 3 * 25, ++n) {
    const double time_s = static_cast<double>(samples[i].device_time_ns) * 1e-9;
    const Eigen::Vector3d truth = toTracker(emulator, emulator.truePlaceMm("TB2", time_s));
    sum2 += (Eigen::Vector3d(samples[i].value, samples[i + 1].value, samples[i + 2].value) - truth).squaredNorm();
    const double range_m = truth.norm() / 1000.0, slow = std::sqrt(1.0 + 25.0 / 2.0);
    expected2 += (std::pow((1.0 + 0.3 * range_m) * slow, 2) + 2.0 * std::pow((3.0 + 1.5 * range_m) * slow, 2)) * 1e-6;
  }
  EXPECT_NEAR(std::sqrt(sum2 / n), std::sqrt(expected2 / n), 0.3 * std::sqrt(expected2 / n));
  emulator.dropConnection();  // before or after the request: either way the driver reconnects and asks again
  EXPECT_NO_THROW(t->measure(5));
  EXPECT_EQ(t->reconnects(), 1);
}

TEST(TrackerEmulator, TheSameSeedGivesTheSameMeasurements) {
  const auto measure = [] {
    World w(mtcal::testing::timeScale(500.0));
    mocks::TrackerEmulator emulator(w.machine, emulatorConfig(w.machine));
    auto t = openEmulator(emulator);
    emulator.placeReflector("A.side1");
    std::vector<double> v;
    for (int i = 0; i < 3; ++i) {
      const Point p = t->measure(20);
      v.insert(v.end(), p.xyz_mm.begin(), p.xyz_mm.end());
    }
    return v;
  };
  EXPECT_EQ(measure(), measure());
}

TEST(TrackerRegistry, TcpUrisOpenTheTracker) {
  World w(mtcal::testing::timeScale(200.0));
  mocks::TrackerEmulator emulator(w.machine, emulatorConfig(w.machine));
  Registry registry;
  registerBuiltInDrivers(registry);
  auto t = registry.openAs<TrackerDevice>("tcp://127.0.0.1:" + std::to_string(emulator.port()));
  EXPECT_EQ(t->info().serial, "LT-0042");
}

}  // namespace
}  // namespace mtcal::drivers::tracker
