#include <gtest/gtest.h>

#include <mutex>
#include <thread>

#include "../support/time_scale.h"
#include "mtcal/drivers/ballbar/driver.h"
#include "mtcal/drivers/ballbar/protocol.h"
#include "mtcal/error.h"
#include "mtcal/mocks/ballbar_emulator.h"

namespace mtcal::drivers::ballbar {
namespace {

using namespace std::chrono_literals;

// The report layouts, with byte literals (docs/protocols/ballbar.md).
TEST(BallbarProtocol, ReportsAsDocumented) {
  auto zero = encodeZero(100.0);  // 1 000 000 tenths of a micrometre = 0x000F4240
  ASSERT_EQ(zero.size(), kFeatureReportSize);
  EXPECT_EQ((std::vector<std::uint8_t>(zero.begin(), zero.begin() + 5)),
            (std::vector<std::uint8_t>{0x11, 0x40, 0x42, 0x0F, 0x00}));
  EXPECT_DOUBLE_EQ(parseZero(zero), 100.0);
  const auto rate = encodeRate(1000);
  EXPECT_EQ(rate[0], 0x12);
  EXPECT_EQ(rate[1], 0xE8);
  EXPECT_EQ(rate[2], 0x03);
  EXPECT_EQ(encodeStream(true)[1], 1);
  EXPECT_TRUE(parseStream(encodeStream(true)));

  SampleBlock b;
  b.first_seq = 0x01020304;
  b.device_time_us = 5000;
  b.period_us = 1000;
  b.flags = kStreaming;
  b.temperature_c = 20.37;
  b.battery_pct = 80;
  b.deviation_um = {1.2, -0.3, std::nullopt};
  const auto report = encodeSamples(b);
  ASSERT_EQ(report.size(), kInputReportSize);
  const std::vector<std::uint8_t> head{0x01, 0x04, 0x03, 0x02,       0x01, 0x88, 0x13, 0x00, 0x00,
                                       0xE8, 0x03, 3,    kStreaming, 0xF5, 0x07, 80};  // 20.37 degC = 2037 = 0x07F5
  EXPECT_EQ(std::vector<std::uint8_t>(report.begin(), report.begin() + 16), head);
  EXPECT_EQ(report[16], 12);    // 1.2 um = 12 counts
  EXPECT_EQ(report[20], 0xFD);  // -3 counts
  EXPECT_EQ(report[27], 0x80);  // INT32_MIN: over range
  const SampleBlock back = parseSamples(report);
  EXPECT_EQ(back.first_seq, b.first_seq);
  EXPECT_NEAR(back.temperature_c, 20.37, 1e-12);
  ASSERT_EQ(back.deviation_um.size(), 3u);
  EXPECT_NEAR(*back.deviation_um[0], 1.2, 1e-12);
  EXPECT_NEAR(*back.deviation_um[1], -0.3, 1e-12);
  EXPECT_FALSE(back.deviation_um[2]);

  Identity id{kProtocolVersion, "1.2.3", "BB42", "MTCAL-BB", 150, 1000};
  const Identity id_back = parseIdentity(encodeIdentity(id));
  EXPECT_EQ(id_back.firmware, "1.2.3");
  EXPECT_EQ(id_back.serial, "BB42");
  EXPECT_EQ(id_back.nominal_length_mm, 150);
  Status st;
  st.last_command = ReportId::kRate;
  st.result = Result::kBusy;
  st.reference_length_mm = 100.0012;
  const Status st_back = parseStatus(encodeStatus(st));
  EXPECT_EQ(st_back.result, Result::kBusy);
  EXPECT_NEAR(st_back.reference_length_mm, 100.0012, 1e-9);
}

TEST(BallbarProtocol, MalformedReportsAreRejectedNamingWhy) {
  SampleBlock b;
  b.deviation_um = {0.5};
  auto report = encodeSamples(b);
  auto wrong_id = report;
  wrong_id[0] = 0x02;
  EXPECT_THROW(parseSamples(wrong_id), ProtocolError);
  auto short_report = report;
  short_report.resize(20);
  EXPECT_THROW(parseSamples(short_report), ProtocolError);
  auto bad_count = report;
  bad_count[11] = 13;
  try {
    parseSamples(bad_count);
    FAIL() << "a count of 13 must be refused";
  } catch (const ProtocolError& e) {
    EXPECT_NE(std::string(e.what()).find("count 13"), std::string::npos) << e.what();
  }
  auto bad_battery = report;
  bad_battery[15] = 101;
  EXPECT_THROW(parseSamples(bad_battery), ProtocolError);
  auto bad_version = encodeIdentity({});
  bad_version[1] = 9;
  EXPECT_THROW(parseIdentity(bad_version), ProtocolError);
  auto bad_result = encodeStatus({});
  bad_result[2] = 7;
  EXPECT_THROW(parseStatus(bad_result), ProtocolError);
  EXPECT_THROW(encodeZero(-1.0), InputError);
}

class Collect : public SampleSink {
 public:
  void push(std::span<const Sample> samples) override {
    std::lock_guard lock(mutex);
    received.insert(received.end(), samples.begin(), samples.end());
  }
  std::size_t size() {
    std::lock_guard lock(mutex);
    return received.size();
  }
  std::mutex mutex;
  std::vector<Sample> received;
};

class BallbarDriver : public ::testing::Test {
 protected:
  BallbarDriver() {
    config_.noise_um = 0.0;
    config_.calibrator_error_um = 0.4;
    emulator_ = std::make_shared<mocks::BallbarEmulator>(machine_, config_);
  }
  std::unique_ptr<BallbarDevice> open() {
    return std::make_unique<BallbarDevice>(std::make_unique<mocks::EmulatorHidTransport>(emulator_), "mock://ballbar",
                                           Timeouts{std::chrono::milliseconds(20), mocks::kEmulatorStallTimeout});
  }
  bool waitFor(Collect& sink, std::size_t n) {
    const auto deadline = std::chrono::steady_clock::now() +
                          std::chrono::duration_cast<std::chrono::milliseconds>(5s * mtcal::testing::slowdown());
    while (sink.size() < n) {
      if (std::chrono::steady_clock::now() > deadline) return false;
      std::this_thread::sleep_for(2ms);
    }
    return true;
  }
  // The world runs in lock step with the test: a stream delivers exactly the samples up to
  // where the test lets it run, whatever the machine's load.
  mocks::WorldClock clock_{1.0, mocks::WorldClock::Mode::kLockStep};
  mocks::VirtualMachine machine_{mocks::VirtualMachineConfig::demo(3), clock_};
  mocks::BallbarEmulatorConfig config_;
  std::shared_ptr<mocks::BallbarEmulator> emulator_;
};

TEST_F(BallbarDriver, IdentifiesZeroesInTheCalibratorAndStreams) {
  auto bar = open();
  EXPECT_EQ(bar->info().kind, "ballbar");
  EXPECT_EQ(bar->info().serial, "BB0001");
  EXPECT_EQ(bar->identity().nominal_length_mm, 100);
  EXPECT_FALSE(bar->status().reference_length_mm > 0.0);
  bar->zero(100.0);
  EXPECT_DOUBLE_EQ(bar->status().reference_length_mm, 100.0);
  // In the calibrator after the zero the bar reads 0; on the machine at the centre + 100 mm
  // of X it reads what the machine does to the 100 mm.
  Collect sink;
  bar->startStream(1000, sink);
  clock_.advanceTo(0.049);  // samples at 0, 1, ... 49 ms
  ASSERT_TRUE(waitFor(sink, 50));
  const auto stats = bar->stopStream();
  EXPECT_EQ(stats.lost_samples, 0u);
  EXPECT_EQ(sink.size(), 50u);
  std::lock_guard lock(sink.mutex);
  for (const auto& s : sink.received) {
    EXPECT_TRUE(s.beam_ok);
    EXPECT_NEAR(s.value, 0.0, 1e-7);
  }
  for (std::size_t i = 1; i < sink.received.size(); ++i) {
    EXPECT_EQ(sink.received[i].seq, sink.received[i - 1].seq + 1);
    EXPECT_EQ(sink.received[i].device_time_ns - sink.received[i - 1].device_time_ns, 1000000);
  }
  EXPECT_TRUE(bar->condition().zeroed);
  EXPECT_NEAR(bar->condition().temperature_c, 20.3, 1e-9);
  // One channel: the length deviation in mm, with the battery in signal_pct.
  const auto channels = bar->streamChannels();
  ASSERT_EQ(channels.size(), 1u);
  EXPECT_EQ(channels[0].channel, 0);
  EXPECT_EQ(channels[0].quantity, "length deviation");
  EXPECT_EQ(channels[0].unit, "mm");
  EXPECT_EQ(channels[0].signal_quantity, "battery");
  EXPECT_EQ(channels[0].signal_unit, "%");
  for (const auto& s : sink.received) {
    EXPECT_EQ(s.channel, channels[0].channel);
    EXPECT_EQ(s.signal_pct, bar->condition().battery_pct);
  }
}

TEST_F(BallbarDriver, RefusedCommandsAreDeviceErrorsNamingTheReason) {
  auto bar = open();
  EXPECT_THROW(bar->startStream(0, *std::make_unique<Collect>()), InputError);
  Collect sink;
  bar->startStream(100, sink);
  EXPECT_THROW(bar->zero(100.0), DeviceError);  // not while streaming (checked by the driver)
  bar->stopStream();
  // The device's own refusal, read back from the status report.
  emulator_->setFeature(encodeRate(5000));
  EXPECT_EQ(bar->status().result, Result::kBadValue);
}

TEST_F(BallbarDriver, LostReportsAreCountedAndMalformedOnesSkipped) {
  auto bar = open();
  Collect sink;
  bar->startStream(1000, sink);
  clock_.advanceTo(0.029);  // 3 reports of 10 samples
  ASSERT_TRUE(waitFor(sink, 30));
  emulator_->updateFaults([](mocks::BallbarFaults& f) {
    f.drop_next_reports = 3;  // 3 reports of 10 samples
    f.garble_next_reports = 0;
  });
  clock_.advanceTo(0.129);  // 10 reports, 3 of them dropped
  ASSERT_TRUE(waitFor(sink, 100));
  emulator_->updateFaults([](mocks::BallbarFaults& f) { f.garble_next_reports = 2; });
  clock_.advanceTo(0.329);  // 20 reports, 2 of them malformed
  ASSERT_TRUE(waitFor(sink, 280));
  const auto stats = bar->stopStream();
  EXPECT_EQ(sink.size(), 280u);
  EXPECT_EQ(stats.crc_errors, 2u);
  EXPECT_EQ(stats.lost_samples, 50u);  // 30 dropped + 20 in the two malformed reports
}

TEST_F(BallbarDriver, AnUnpluggedBarStopsTheStreamWithATransportError) {
  auto bar = open();
  Collect sink;
  bar->startStream(1000, sink);
  clock_.advanceTo(0.019);
  ASSERT_TRUE(waitFor(sink, 20));
  emulator_->updateFaults([](mocks::BallbarFaults& f) { f.unplugged = true; });
  const auto deadline = std::chrono::steady_clock::now() +
                        std::chrono::duration_cast<std::chrono::milliseconds>(5s * mtcal::testing::slowdown());
  bool failed = false;
  while (!failed && std::chrono::steady_clock::now() < deadline) {
    try {
      bar->poll();
      std::this_thread::sleep_for(2ms);
    } catch (const TransportError& e) {
      failed = true;
      EXPECT_NE(std::string(e.what()).find("unplugged"), std::string::npos) << e.what();
    }
  }
  EXPECT_TRUE(failed);
  EXPECT_THROW(bar->stopStream(), TransportError);
  const std::size_t kept = sink.size();
  EXPECT_EQ(kept, 20u);  // what arrived before stays delivered
}

}  // namespace
}  // namespace mtcal::drivers::ballbar
