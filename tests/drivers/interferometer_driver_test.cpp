#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <deque>
#include <thread>

#include "mtcal/drivers/interferometer/driver.h"
#include "mtcal/error.h"
#include "mtcal/mocks/emulator_transport.h"
#include "mtcal/mocks/interferometer_emulator.h"
#include "mtcal/processing/air_index.h"

namespace mtcal::drivers::interferometer {
namespace {

using namespace std::chrono_literals;

class CollectingSink final : public SampleSink {
 public:
  void push(std::span<const Sample> samples) override {
    std::lock_guard lock(mutex_);
    samples_.insert(samples_.end(), samples.begin(), samples.end());
  }
  std::vector<Sample> samples() const {
    std::lock_guard lock(mutex_);
    return samples_;
  }
  std::size_t size() const {
    std::lock_guard lock(mutex_);
    return samples_.size();
  }
  bool waitFor(std::size_t n, std::chrono::milliseconds timeout) const {
    const auto end = std::chrono::steady_clock::now() + timeout;
    while (size() < n) {
      if (std::chrono::steady_clock::now() > end) return false;
      std::this_thread::sleep_for(1ms);
    }
    return true;
  }

 private:
  mutable std::mutex mutex_;
  std::vector<Sample> samples_;
};

// The real driver against the device emulator through the in-process fake USB transport. The
// world runs in lock step with the test (clock.advanceTo): a stream delivers exactly the
// samples up to where the test lets it run, whatever the machine's load.
class DriverOnEmulator : public ::testing::Test {
 protected:
  explicit DriverOnEmulator(mocks::WorldClock::Mode mode = mocks::WorldClock::Mode::kLockStep)
      : clock(1.0, mode), machine(mocks::VirtualMachineConfig::demo(3), clock) {}

  std::unique_ptr<InterferometerDevice> open(bool paced = true,
                                             Timeouts timeouts = {mocks::kEmulatorReplyTimeout, 100ms,
                                                                  mocks::kEmulatorStallTimeout},
                                             std::size_t device_buffer_bytes = 256 * 1024) {
    mocks::InterferometerEmulatorConfig config;
    config.paced = paced;
    config.device_buffer_bytes = device_buffer_bytes;
    emulator = std::make_shared<mocks::InterferometerEmulator>(machine, config);
    return std::make_unique<InterferometerDevice>(std::make_unique<mocks::EmulatorTransport>(emulator),
                                                  "mock://interferometer", timeouts);
  }

  mocks::WorldClock clock;
  mocks::VirtualMachine machine;
  std::shared_ptr<mocks::InterferometerEmulator> emulator;
};

TEST_F(DriverOnEmulator, IdentifiesAndReadsTheEnvironmentUnit) {
  auto device = open();
  EXPECT_EQ(device->identity().serial, "EMU0001");
  EXPECT_NEAR(device->identity().vacuum_wavelength_nm, 632.990577, 1e-9);
  EXPECT_EQ(device->info().kind, "interferometer");
  // Linear optics (the default): the uncompensated displacement in mm, the beam signal in %.
  const auto channels = device->streamChannels();
  ASSERT_EQ(channels.size(), 1u);
  EXPECT_EQ(channels[0].channel, 0);
  EXPECT_EQ(channels[0].name, "linear");
  EXPECT_EQ(channels[0].quantity, "uncompensated displacement");
  EXPECT_EQ(channels[0].unit, "mm");
  EXPECT_EQ(channels[0].signal_quantity, "beam signal");
  EXPECT_EQ(channels[0].signal_unit, "%");
  const Environment env = device->readEnvironment();
  EXPECT_NEAR(env.air_temp_c, machine.config().air_temp_c, 0.05);
  EXPECT_NEAR(env.air_pressure_pa, machine.config().air_pressure_pa, 20.0);
  ASSERT_EQ(env.material_temps_c.size(), 1u);
  EXPECT_NEAR(env.material_temps_c[0], machine.config().material_temp_c, 0.05);
}

TEST_F(DriverOnEmulator, StreamsContiguousTimestampedSamplesAtTheRequestedRate) {
  CollectingSink sink;  // before the device: the device stops its stream before the sink goes
  auto device = open();
  device->startStream(5000, sink);
  clock.advanceTo(0.1998);  // samples every 0.2 ms from 0
  ASSERT_TRUE(sink.waitFor(1000, 10s));
  // A command while streaming is answered through the reader thread.
  EXPECT_NEAR(device->readEnvironment().humidity_pct, machine.config().humidity_pct, 1.0);
  const StreamStats stats = device->stopStream();
  const auto samples = sink.samples();
  ASSERT_EQ(samples.size(), 1000u);
  for (std::size_t i = 1; i < samples.size(); ++i) {
    ASSERT_EQ(samples[i].seq, samples[i - 1].seq + 1);
    ASSERT_EQ(samples[i].device_time_ns - samples[i - 1].device_time_ns, 200'000);  // 5 kHz
  }
  EXPECT_EQ(stats.lost_samples, 0u);
  EXPECT_EQ(stats.samples, samples.size());
  // The machine stands still at the datum: readings are noise around zero (mm).
  EXPECT_NEAR(samples.back().value, 0.0, 0.0005);
  EXPECT_TRUE(samples.back().beam_ok);
  EXPECT_FALSE(emulator->streaming());
}

// A second stream on the same device delivers at its rate at once (the device schedule
// restarts with the stream), and sequence numbers keep counting.
TEST_F(DriverOnEmulator, ARestartedStreamDeliversAtOnce) {
  CollectingSink first, second;
  auto device = open();
  device->startStream(5000, first);
  clock.advanceTo(0.4998);
  ASSERT_TRUE(first.waitFor(2500, 10s));
  device->stopStream();
  const double restart_s = clock.nowS();
  device->startStream(5000, second);
  clock.advanceTo(restart_s + 0.0998);
  ASSERT_TRUE(second.waitFor(500, 10s));
  device->stopStream();
  // Its first sample is the restart's instant, not the old schedule's next slot.
  EXPECT_EQ(second.samples().front().device_time_ns, std::llround(restart_s * 1e9));
  EXPECT_EQ(second.size(), 500u);
  EXPECT_GT(second.samples().front().seq, first.samples().back().seq);
}

TEST_F(DriverOnEmulator, ReadingsFollowTheMachineScaledByTheAirIndex) {
  CollectingSink sink;   // before the device: the device stops its stream before the sink goes
  auto device = open();  // its datum: the machine as it stands before the move
  const double datum_mm = machine.actualPositionMm(mocks::Axis::kX, {}, 0.0);
  const double done_s = machine.moveTo(mocks::Axis::kX, 100.0);
  clock.advanceTo(done_s + 0.3);
  device->startStream(1000, sink);
  clock.advanceTo(done_s + 0.349);
  ASSERT_TRUE(sink.waitFor(50, 10s));
  device->stopStream();
  // raw = n * (actual position - position at the datum), the uncompensated optical path.
  const auto& c = machine.config();
  const double n = processing::edlenIndex({c.air_temp_c, c.air_pressure_pa, c.humidity_pct, 450.0}, 632.990577);
  const Sample last = sink.samples().back();
  const double t = static_cast<double>(last.device_time_ns) * 1e-9;
  const double expected = n * (machine.actualPositionMm(mocks::Axis::kX, {}, t) - datum_mm);
  EXPECT_NEAR(last.value, expected, 1e-4);  // 0.1 um: five times the reading noise
  EXPECT_NEAR(last.value, 100.027, 0.01);   // and it is about 100 mm longer by n - 1
}

TEST_F(DriverOnEmulator, DroppedFramesAreCountedAsLostSamples) {
  CollectingSink sink;
  auto device = open(/*paced=*/false);
  device->startStream(50000, sink);
  ASSERT_TRUE(sink.waitFor(2000, 3000ms));
  emulator->updateFaults([](auto& f) { f.drop_next_data_frames = 3; });
  const std::size_t before = sink.size();
  ASSERT_TRUE(sink.waitFor(before + 5000, 3000ms));
  const StreamStats stats = device->stopStream();
  EXPECT_EQ(stats.lost_samples, 3 * kMaxSamplesPerFrame);
}

// A device streaming in real time by itself (a free-running world), as a real one does.
class DriverOnAFreeRunningEmulator : public DriverOnEmulator {
 protected:
  DriverOnAFreeRunningEmulator() : DriverOnEmulator(mocks::WorldClock::Mode::kFree) {}
};

// A host that stops reading for a while: the device's FIFO overflows, the samples it drops
// show up as lost on the host, exactly, and a command waits behind at most the device's
// buffer, not behind the whole backlog.
TEST_F(DriverOnAFreeRunningEmulator, AStalledHostLosesCountedSamplesNotCommands) {
  struct SlowOnceSink final : SampleSink {
    CollectingSink inner;
    std::atomic<bool> stalled{false};
    void push(std::span<const Sample> samples) override {
      if (!stalled.exchange(true)) std::this_thread::sleep_for(200ms);  // 10 000 samples at 50 kHz
      inner.push(samples);
    }
  } sink;
  constexpr std::size_t kBufferBytes = 16 * 1024;
  auto device = open(true, {}, kBufferBytes);
  device->startStream(50000, sink);
  ASSERT_TRUE(sink.inner.waitFor(20000, 30s));
  const std::size_t before = sink.inner.size();
  EXPECT_NO_THROW(device->readEnvironment());
  // Ahead of the reply: what the device's buffer held, plus a frame on its way.
  EXPECT_LE(sink.inner.size() - before, kBufferBytes / kSampleSize + 2 * kMaxSamplesPerFrame);
  const StreamStats stats = device->stopStream();
  EXPECT_GT(emulator->samplesOverflowed(), 0u);
  EXPECT_EQ(stats.lost_samples, emulator->samplesOverflowed());
}

TEST_F(DriverOnEmulator, CorruptFramesAreSkippedAndCounted) {
  CollectingSink sink;
  auto device = open(/*paced=*/false);
  device->startStream(50000, sink);
  ASSERT_TRUE(sink.waitFor(1000, 3000ms));
  emulator->updateFaults([](auto& f) { f.corrupt_next_frames = 2; });
  const std::size_t before = sink.size();
  ASSERT_TRUE(sink.waitFor(before + 5000, 3000ms));
  const StreamStats stats = device->stopStream();
  EXPECT_GE(stats.crc_errors, 2u);
  EXPECT_EQ(stats.lost_samples, 2 * kMaxSamplesPerFrame);
}

TEST_F(DriverOnEmulator, ARefusedStartIsADeviceErrorWithTheDevicesReason) {
  CollectingSink sink;
  auto device = open();
  emulator->updateFaults([](auto& f) { f.nak_start_stream = true; });
  try {
    device->startStream(1000, sink);
    FAIL();
  } catch (const DeviceError& e) {
    EXPECT_NE(std::string(e.what()).find("beam interrupted"), std::string::npos) << e.what();
  }
  EXPECT_THROW(device->startStream(60000, sink), InputError);
}

TEST_F(DriverOnEmulator, ADisconnectDuringTheStreamSurfacesFromPollAndStop) {
  CollectingSink sink;  // before the device: the device stops its stream before the sink goes
  auto device = open();
  device->startStream(2000, sink);
  clock.advanceTo(0.0495);
  ASSERT_TRUE(sink.waitFor(100, 10s));
  emulator->updateFaults([](auto& f) { f.disconnected = true; });
  bool thrown = false;
  for (const auto deadline = std::chrono::steady_clock::now() + 10s;
       !thrown && std::chrono::steady_clock::now() < deadline;) {
    try {
      device->poll();
      std::this_thread::sleep_for(5ms);
    } catch (const TransportError& e) {
      thrown = true;
      EXPECT_NE(std::string(e.what()).find("disconnected"), std::string::npos) << e.what();
    }
  }
  EXPECT_TRUE(thrown);
  EXPECT_THROW(device->stopStream(), TransportError);
}

TEST_F(DriverOnEmulator, ASilentDeviceTimesOutAndAStalledStreamIsReported) {
  auto device = open(true, Timeouts{200ms, 20ms, 300ms});
  emulator->updateFaults([](auto& f) { f.silent = true; });
  const auto t0 = std::chrono::steady_clock::now();
  EXPECT_THROW(device->readEnvironment(), TimeoutError);           // only the command timeout ends the wait
  EXPECT_GE(std::chrono::steady_clock::now() - t0, 200ms - 10ms);  // within the driver's ms rounding

  emulator->updateFaults([](auto& f) { f.silent = false; });
  CollectingSink sink;
  const auto started = std::chrono::steady_clock::now();
  device->startStream(1000, sink);
  clock.advanceTo(clock.nowS() + 0.009);
  ASSERT_TRUE(sink.waitFor(10, 10s));
  emulator->updateFaults([](auto& f) { f.silent = true; });
  bool stalled = false;
  while (!stalled) {
    try {
      device->poll();
      std::this_thread::sleep_for(5ms);
    } catch (const TimeoutError& e) {
      stalled = true;
      EXPECT_NE(std::string(e.what()).find("stalled"), std::string::npos) << e.what();
    }
  }
  EXPECT_GE(std::chrono::steady_clock::now() - started, 300ms);  // not before the stall timeout after the last sample
}

// gmock transport: the driver's behaviour when the device misbehaves at the byte level.
class MockTransport : public Transport {
 public:
  MOCK_METHOD(std::size_t, read, (std::span<std::uint8_t>, milliseconds), (override));
  MOCK_METHOD(void, write, (std::span<const std::uint8_t>, milliseconds), (override));
  MOCK_METHOD(std::string, describe, (), (const, override));
};

// Serves the bytes of `frames` one read at a time, then times out.
auto serve(std::deque<std::vector<std::uint8_t>> frames) {
  auto queue = std::make_shared<std::deque<std::vector<std::uint8_t>>>(std::move(frames));
  return [queue](std::span<std::uint8_t> buffer, milliseconds) -> std::size_t {
    if (queue->empty()) throw TimeoutError("mock: nothing to read");
    auto f = queue->front();
    queue->pop_front();
    std::copy(f.begin(), f.end(), buffer.begin());
    return f.size();
  };
}

TEST(DriverWithMockTransport, RejectsAnotherProtocolVersion) {
  auto transport = std::make_unique<::testing::NiceMock<MockTransport>>();
  Identity future;
  future.protocol_version = 2;
  ON_CALL(*transport, read).WillByDefault(serve({encodeAck(MessageType::kStopStream), encodeIdentity(future)}));
  EXPECT_CALL(*transport, write).Times(2);  // STOP_STREAM, IDENTIFY
  EXPECT_THROW(InterferometerDevice(std::move(transport), "usb://test"), ProtocolError);
}

TEST(DriverWithMockTransport, ANakBecomesADeviceError) {
  auto transport = std::make_unique<::testing::NiceMock<MockTransport>>();
  ON_CALL(*transport, read)
      .WillByDefault(serve({encodeAck(MessageType::kStopStream), encodeIdentity({}),
                            encodeNak({MessageType::kReadEnvironment, NakCode::kNotReady, "sensors warming up"})}));
  InterferometerDevice device(std::move(transport), "usb://test");
  try {
    device.readEnvironment();
    FAIL();
  } catch (const DeviceError& e) {
    EXPECT_NE(std::string(e.what()).find("sensors warming up"), std::string::npos) << e.what();
  }
}

TEST(DriverWithMockTransport, TheStreamChannelFollowsTheOptics) {
  auto transport = std::make_unique<::testing::NiceMock<MockTransport>>();
  ON_CALL(*transport, read)
      .WillByDefault(serve({encodeAck(MessageType::kStopStream), encodeIdentity({}), encodeAck(MessageType::kSetOptics),
                            encodeAck(MessageType::kSetOptics), encodeAck(MessageType::kSetOptics)}));
  InterferometerDevice device(std::move(transport), "usb://test");
  device.setOptics(Optics::kAngular);
  auto c = device.streamChannels().at(0);
  EXPECT_EQ(c.name, "angular");
  EXPECT_EQ(c.quantity, "angle");
  EXPECT_EQ(c.unit, "urad");
  EXPECT_EQ(c.signal_quantity, "beam signal");
  device.setOptics(Optics::kStraightnessLong);
  c = device.streamChannels().at(0);
  EXPECT_EQ(c.name, "straightness-long");
  EXPECT_EQ(c.quantity, "straightness");
  EXPECT_EQ(c.unit, "mm");
  device.setOptics(Optics::kLinear);
  EXPECT_EQ(device.streamChannels().at(0).quantity, "uncompensated displacement");
}

TEST(DriverWithMockTransport, GarbageInsteadOfAReplyTimesOut) {
  auto transport = std::make_unique<::testing::NiceMock<MockTransport>>();
  ON_CALL(*transport, read).WillByDefault([](std::span<std::uint8_t> buffer, milliseconds) -> std::size_t {
    std::fill_n(buffer.begin(), 64, 0x55);
    std::this_thread::sleep_for(5ms);
    return 64;
  });
  const auto t0 = std::chrono::steady_clock::now();
  // Bytes keep coming but never a frame: the command timeout still ends the wait.
  EXPECT_THROW(InterferometerDevice(std::move(transport), "usb://test", Timeouts{150ms, 20ms, 500ms}), TimeoutError);
  EXPECT_GE(std::chrono::steady_clock::now() - t0, 150ms - 10ms);  // within the driver's ms rounding
}

}  // namespace
}  // namespace mtcal::drivers::interferometer
