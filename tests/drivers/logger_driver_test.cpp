#include <gtest/gtest.h>

#include <cmath>
#include <mutex>
#include <thread>

#include "mtcal/drivers/logger/driver.h"
#include "mtcal/drivers/serial_transport.h"
#include "mtcal/error.h"
#include "mtcal/mocks/logger_emulator.h"
#include "mtcal/mocks/probe_emulator.h"

// The temperature logger's driver over a real serial port (a pseudo-terminal, Boost.Asio's
// serial_port) against the emulator reading a warming virtual machine.
namespace mtcal::drivers::logger {
namespace {

struct Bench {
  // The world runs in lock step with the test: as far as it lets it run, whatever the load.
  explicit Bench(double time_scale) : clock(time_scale, mocks::WorldClock::Mode::kLockStep), machine(config(), clock) {}
  static mocks::VirtualMachineConfig config() {
    auto c = mocks::VirtualMachineConfig::demo(3);
    c.thermal = mocks::MachineThermalConfig{};
    return c;
  }
  mocks::WorldClock clock;
  mocks::VirtualMachine machine;
  mocks::LoggerEmulator emulator{machine, mocks::LoggerEmulatorConfig{}};
  mocks::PtyLink link{[this](auto b) { emulator.receive(b); },
                      [this](auto b, auto t) { return emulator.transmit(b, t); }};
  std::unique_ptr<TemperatureLoggerDevice> open(LineTimeouts timeouts = {mocks::kEmulatorReplyTimeout,
                                                                         std::chrono::milliseconds(100),
                                                                         mocks::kEmulatorStallTimeout}) {
    return std::make_unique<TemperatureLoggerDevice>(std::make_unique<SerialTransport>(link.slavePath(), 115200),
                                                     "serial://logger", timeouts);
  }
};

struct Collect final : SampleSink {
  void push(std::span<const Sample> s) override {
    std::lock_guard lock(mutex);
    samples.insert(samples.end(), s.begin(), s.end());
  }
  std::mutex mutex;
  std::vector<Sample> samples;
};

TEST(LoggerDriver, ReadsTheSitesAndReportsASensorOutAsMissing) {
  Bench b(100.0);
  b.machine.thermal()->startProgram({{3600.0, 2000.0}}, 0.0);
  auto logger = b.open();
  EXPECT_EQ(logger->channels().count, 16);
  EXPECT_EQ(logger->info().kind, "logger");
  // Every channel a temperature in degC; signal_pct carries nothing.
  const auto channels = logger->streamChannels();
  ASSERT_EQ(channels.size(), 16u);
  for (std::size_t i = 0; i < channels.size(); ++i) {
    EXPECT_EQ(channels[i].channel, static_cast<int>(i) + 1);
    EXPECT_EQ(channels[i].name, "ch" + std::to_string(i + 1));
    EXPECT_EQ(channels[i].quantity, "temperature");
    EXPECT_EQ(channels[i].unit, "degC");
    EXPECT_EQ(channels[i].signal_quantity, "");
    EXPECT_EQ(channels[i].signal_unit, "");
  }
  b.clock.advanceTo(30.0);  // the bearings warm
  const Record r = logger->read();
  ASSERT_EQ(r.channels.size(), 16u);
  const double t = static_cast<double>(r.time_ms) / 1000.0;
  for (int c = 1; c <= 16; ++c) {
    // 0.01 K rounding and 0.005 K noise (5 sigma)
    EXPECT_NEAR(r.channels[static_cast<std::size_t>(c - 1)].value_c, b.emulator.trueReadingC(c, t), 0.03) << c;
    EXPECT_EQ(r.channels[static_cast<std::size_t>(c - 1)].status, SensorStatus::kOk);
  }
  EXPECT_GT(r.channels[0].value_c, b.emulator.trueReadingC(8, t) - 0.1);  // the front bearing is not below the air

  b.emulator.updateFaults([](mocks::LoggerFaults& f) { f.dropouts.push_back({3, 0.0, 1e9}); });
  EXPECT_EQ(logger->read().channels[2].status, SensorStatus::kOpen);

  // Logged every second of the logger's clock: consecutive records, channel 3 NaN and flagged.
  Collect sink;
  logger->startLogging(std::chrono::seconds(1), sink);
  b.clock.advanceTo(49.0);  // records at 30, 31, ... 49 s (from the next whole second)
  for (const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
       std::chrono::steady_clock::now() < deadline;) {
    std::lock_guard lock(sink.mutex);
    if (sink.samples.size() >= 20 * 16) break;
  }
  const auto stats = logger->stopStream();
  EXPECT_EQ(stats.samples, 20u);
  EXPECT_EQ(stats.lost_samples, 0u);
  std::lock_guard lock(sink.mutex);
  ASSERT_EQ(sink.samples.size(), 20u * 16u);
  EXPECT_EQ(sink.samples.front().device_time_ns, 30'000'000'000);
  ASSERT_EQ(sink.samples.size() % 16, 0u);
  for (std::size_t i = 0; i < sink.samples.size(); ++i) {
    const auto& s = sink.samples[i];
    EXPECT_EQ(s.seq, i / 16);
    EXPECT_EQ(s.channel, static_cast<int>(i % 16) + 1);
    EXPECT_EQ(s.channel, channels[i % 16].channel);  // the samples are those the description names
    if (s.channel == 3) {
      EXPECT_FALSE(s.beam_ok);
      EXPECT_TRUE(std::isnan(s.value));
    } else {
      EXPECT_TRUE(s.beam_ok);
      EXPECT_NEAR(s.value, b.emulator.trueReadingC(s.channel, s.device_time_ns * 1e-9), 0.03);
    }
    if (i >= 16) {
      EXPECT_EQ(s.device_time_ns - sink.samples[i - 16].device_time_ns, 1'000'000'000);  // whole seconds apart
    }
  }
  EXPECT_THROW(logger->startStream(10, sink), InputError);  // a logger is not faster than 1 Hz
}

TEST(LoggerDriver, ASilentLoggerTimesOut) {
  Bench b(10.0);
  b.emulator.updateFaults([](mocks::LoggerFaults& f) { f.silent = true; });
  LineTimeouts timeouts;
  timeouts.command = std::chrono::milliseconds(200);
  EXPECT_THROW(b.open(timeouts), TimeoutError);
}

TEST(LoggerProtocol, RoundTripsAndRefusesMalformedLines) {
  Record r{7, 12345, {{21.37, SensorStatus::kOk}, {0.0, SensorStatus::kOpen}, {25.0, SensorStatus::kOverRange}}};
  std::string line = formatRecord(r);
  line.resize(line.size() - 2);  // the CR LF
  const Record back = parseRecord(line, 3);
  EXPECT_EQ(back.index, 7u);
  EXPECT_EQ(back.time_ms, 12345);
  EXPECT_DOUBLE_EQ(back.channels[0].value_c, 21.37);
  EXPECT_EQ(back.channels[1].status, SensorStatus::kOpen);
  EXPECT_THROW(parseRecord("R 1 2 21.0 OK", 3), ProtocolError);
  EXPECT_THROW(parseRecord("R 1 2 21.0 XX 1 OK 2 OK", 3), ProtocolError);
  EXPECT_THROW(parseChannels("CH 12 0.01"), ProtocolError);
  EXPECT_THROW(parseOk("ERR 1 unknown or malformed command"), DeviceError);
  EXPECT_EQ(parseCommand("LOG 60").interval_s, 60u);
  EXPECT_EQ(parseCommand("LOG OFF").interval_s, 0u);
  EXPECT_THROW(parseCommand("LOG 0"), ProtocolError);
  EXPECT_THROW(parseCommand("LOG 100000"), ProtocolError);
}

}  // namespace
}  // namespace mtcal::drivers::logger
