#include <gtest/gtest.h>

#include <mutex>
#include <thread>

#include "../support/time_scale.h"
#include "mtcal/drivers/probes/driver.h"
#include "mtcal/drivers/probes/protocol.h"
#include "mtcal/drivers/serial_transport.h"
#include "mtcal/error.h"
#include "mtcal/mocks/probe_emulator.h"

namespace mtcal::drivers::probes {
namespace {

// The codec, with byte literals (docs/protocols/probes.md).
TEST(ProbeProtocol, CommandsAndRepliesAsDocumented) {
  EXPECT_EQ(encodeIdentify(), "*IDN?\r\n");
  EXPECT_EQ(encodeRead(0), "READ? ALL\r\n");
  EXPECT_EQ(encodeRead(2), "READ? 2\r\n");
  EXPECT_EQ(encodeZero(0), "ZERO ALL\r\n");
  EXPECT_EQ(encodeRate(500), "RATE 500\r\n");
  EXPECT_EQ(encodeStream(false), "STREAM OFF\r\n");
  EXPECT_EQ(formatValues({{0.0123456, ChannelStatus::kOk}, {-1.05, ChannelStatus::kUnderRange}}),
            "VAL 0.0123456 OK -1.0500000 UR\r\n");
  EXPECT_EQ(formatStreamLine({7, 1500000, {{0.001, ChannelStatus::kOk}}}), "D 7 1500000 0.0010000 OK\r\n");
  EXPECT_EQ(formatStreamLine({2, 60000000, {{-0.5, ChannelStatus::kOk}}, true}), "L 2 60000000 -0.5000000 OK\r\n");
  EXPECT_EQ(encodeTrigger(true), "TRIG ON\r\n");
  EXPECT_EQ(parseCommand("TRIG OFF").kind, Command::Kind::kTrigger);
  EXPECT_TRUE(parseStreamLine("L 3 60000000 0.1 OK", 1).latched);
  EXPECT_TRUE(isStreamLine("L 3 60000000 0.1 OK"));
  const auto v = parseValues("VAL 0.0123456 OK -1.0500000 UR", 2);
  EXPECT_DOUBLE_EQ(v[0].value_mm, 0.0123456);
  EXPECT_EQ(v[1].status, ChannelStatus::kUnderRange);
  const auto id = parseIdentity("IDN MTCAL,PB3,SN7,1.2.0");
  EXPECT_EQ(id.serial, "SN7");
  const auto ch = parseChannels("CH 3 1.000");
  EXPECT_EQ(ch.count, 3);
  const auto s = parseStreamLine("D 12 34567 0.5 OK 0.25 NP", 2);
  EXPECT_EQ(s.seq, 12u);
  EXPECT_EQ(s.time_us, 34567);
  EXPECT_EQ(s.channels[1].status, ChannelStatus::kNoProbe);
  EXPECT_THROW(parseValues("VAL 0.1 OK", 2), ProtocolError);          // a channel missing
  EXPECT_THROW(parseValues("VAL 0.1x OK 0.2 OK", 2), ProtocolError);  // not a number
  EXPECT_THROW(parseValues("VAL 0.1 XX 0.2 OK", 2), ProtocolError);   // unknown status
  EXPECT_THROW(parseOk("ERR 3 rate must be 1..1000 Hz"), DeviceError);
  EXPECT_EQ(parseCommand("READ? 3").channel, 3);
  EXPECT_EQ(parseCommand("RATE 250").rate_hz, 250u);
  EXPECT_THROW(parseCommand("READ? 0"), ProtocolError);
  EXPECT_THROW(parseCommand("LAUNCH"), ProtocolError);
}

TEST(ProbeProtocol, LineDecoderSplitsAndDropsOverlongLines) {
  drivers::LineDecoder d(kMaxLineBytes);
  const std::string text = "OK\r\nVAL 1 OK\nparti";
  d.feed({reinterpret_cast<const std::uint8_t*>(text.data()), text.size()});
  EXPECT_EQ(*d.next(), "OK");
  EXPECT_EQ(*d.next(), "VAL 1 OK");
  EXPECT_FALSE(d.next());
  const std::string rest = "al\r\n" + std::string(600, 'x') + "\r\nOK\r\n";
  d.feed({reinterpret_cast<const std::uint8_t*>(rest.data()), rest.size()});
  EXPECT_EQ(*d.next(), "partial");
  EXPECT_EQ(*d.next(), "OK");
  EXPECT_EQ(d.overlongLines(), 1u);
}

// The real serial path: Boost.Asio's serial_port on a pseudo-terminal, the emulated box behind
// it observing the virtual machine.
class ProbeBoxOverPty : public ::testing::Test {
 protected:
  ProbeBoxOverPty()
      : machine_(config(), clock_),
        emulator_(machine_, mocks::ProbeBoxEmulatorConfig{}),
        link_([this](auto bytes) { emulator_.receive(bytes); },
              [this](auto buffer, auto timeout) { return emulator_.transmit(buffer, timeout); }) {}
  static mocks::VirtualMachineConfig config() {
    auto c = mocks::VirtualMachineConfig::demo(5);
    for (auto& a : c.axes) a.positioning_sigma_um = 0.0;
    return c;
  }
  std::unique_ptr<ProbeBoxDevice> open(Timeouts timeouts = {mocks::kEmulatorReplyTimeout,
                                                            std::chrono::milliseconds(100),
                                                            mocks::kEmulatorStallTimeout}) {
    return std::make_unique<ProbeBoxDevice>(std::make_unique<SerialTransport>(link_.slavePath(), 115200),
                                            "serial://" + link_.slavePath(), timeouts);
  }
  // The world runs in lock step with the test: as far as it lets it run, whatever the load.
  mocks::WorldClock clock_{mtcal::testing::timeScale(100.0), mocks::WorldClock::Mode::kLockStep};
  mocks::VirtualMachine machine_;
  mocks::ProbeBoxEmulator emulator_;
  mocks::PtyLink link_;
};

TEST_F(ProbeBoxOverPty, IdentifiesReadsAndZeroes) {
  auto box = open();
  EXPECT_EQ(box->info().model, "MTCAL-PB3 (emulated)");
  EXPECT_EQ(box->info().kind, "probes");
  EXPECT_EQ(box->channels().count, 3);
  const auto channels = box->streamChannels();
  ASSERT_EQ(channels.size(), 3u);
  for (int c = 1; c <= 3; ++c) {
    const auto& d = channels[static_cast<std::size_t>(c - 1)];
    EXPECT_EQ(d.channel, c);
    EXPECT_EQ(d.name, "ch" + std::to_string(c));
    EXPECT_EQ(d.quantity, "displacement");
    EXPECT_EQ(d.unit, "mm");
    EXPECT_EQ(d.signal_quantity, "");
  }
  clock_.advanceTo(5.0);  // let the settling of the start die out
  const auto values = box->readAll();
  ASSERT_EQ(values.size(), 3u);
  for (int c = 1; c <= 3; ++c) {
    // 5 sigma of the 0.02 um noise.
    EXPECT_NEAR(values[static_cast<std::size_t>(c - 1)] * 1000.0, emulator_.trueReadingUm(c, 0.0), 0.1) << c;
  }
  box->zero(0);
  for (double v : box->readAll()) EXPECT_NEAR(v * 1000.0, 0.0, 0.1);
}

TEST_F(ProbeBoxOverPty, StreamsEveryChannelWithContiguousSequence) {
  auto box = open();
  struct Sink : SampleSink {
    std::mutex m;
    std::vector<Sample> got;
    void push(std::span<const Sample> s) override {
      std::lock_guard lock(m);
      got.insert(got.end(), s.begin(), s.end());
    }
  } sink;
  const auto size = [&] {
    std::lock_guard lock(sink.m);
    return sink.got.size();
  };
  const auto waitFor = [&](std::size_t n) {
    for (const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
         size() < n && std::chrono::steady_clock::now() < deadline;) {
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
  };
  const double start_s = clock_.nowS();
  box->startStream(200, sink);
  clock_.advanceTo(start_s + 30.0);  // 30 s: lines at 0, 5 ms, ... 30 s after the start
  waitFor(6001 * 3);
  const auto stats = box->stopStream();
  EXPECT_EQ(stats.lost_samples, 0u);
  std::unique_lock lock(sink.m);
  ASSERT_EQ(sink.got.size(), 6001u * 3u);
  EXPECT_EQ(sink.got.size() % 3, 0u);
  for (std::size_t i = 0; i < sink.got.size(); ++i) {
    EXPECT_EQ(sink.got[i].channel, static_cast<int>(i % 3) + 1);
    EXPECT_EQ(sink.got[i].seq, sink.got[0].seq + i / 3);
  }
  // Commands work again after the stream, and a second stream starts at once where the
  // sequence left off.
  EXPECT_EQ(box->readAll().size(), 3u);
  const auto first_run = sink.got.size();
  const auto last_seq = sink.got.back().seq;
  lock.unlock();
  const double restart_s = clock_.nowS();
  box->startStream(200, sink);
  clock_.advanceTo(restart_s + 10.0);
  waitFor(first_run + 2001 * 3);
  EXPECT_EQ(box->stopStream().lost_samples, 0u);
  lock.lock();
  ASSERT_EQ(sink.got.size(), first_run + 2001u * 3u);
  EXPECT_GT(sink.got[first_run].seq, last_seq);
}

// Triggered latching: the latches come when the trigger does, as rarely as a logger's
// records, and the silence between them is not a stalled link even when it is many times the
// stall timeout of a stream.
TEST_F(ProbeBoxOverPty, ATriggeredBoxWaitsForItsTriggerWithoutStalling) {
  auto box = open({mocks::kEmulatorReplyTimeout, std::chrono::milliseconds(20), std::chrono::milliseconds(100)});
  struct Sink : SampleSink {
    std::mutex m;
    std::vector<Sample> got;
    void push(std::span<const Sample> s) override {
      std::lock_guard lock(m);
      got.insert(got.end(), s.begin(), s.end());
    }
    std::size_t size() {
      std::lock_guard lock(m);
      return got.size();
    }
  } sink;
  box->startTriggered(sink);
  for (int pulse = 0; pulse < 2; ++pulse) {
    emulator_.trigger(clock_.nowS());
    for (const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
         sink.size() < 3u * (pulse + 1) && std::chrono::steady_clock::now() < deadline;) {
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    ASSERT_EQ(sink.size(), 3u * (pulse + 1));
    // Five stall timeouts without a line (a loaded machine can only make the reader look later).
    std::this_thread::sleep_for(std::chrono::milliseconds(500));
    EXPECT_NO_THROW(box->poll());
  }
  const auto stats = box->stopStream();
  EXPECT_EQ(stats.samples, 2u);
  EXPECT_EQ(stats.lost_samples, 0u);
  std::lock_guard lock(sink.m);
  EXPECT_EQ(sink.got[3].seq, 1u);
}

TEST_F(ProbeBoxOverPty, FaultsAreNamed) {
  auto box = open({std::chrono::milliseconds(300), std::chrono::milliseconds(50), std::chrono::milliseconds(500)});
  emulator_.updateFaults([](auto& f) { f.over_range_channel = 2; });
  try {
    box->readAll();
    FAIL();
  } catch (const DeviceError& e) {
    EXPECT_NE(std::string(e.what()).find("channel 2: over range"), std::string::npos) << e.what();
  }
  emulator_.updateFaults([](auto& f) {
    f.over_range_channel = 0;
    f.no_probe_channel = 3;
  });
  try {
    box->readAll();
    FAIL();
  } catch (const DeviceError& e) {
    EXPECT_NE(std::string(e.what()).find("channel 3: no probe"), std::string::npos) << e.what();
  }
  emulator_.updateFaults([](auto& f) {
    f.no_probe_channel = 0;
    f.garble_next_lines = 1;
  });
  EXPECT_THROW(box->readAll(), ProtocolError);
  EXPECT_EQ(box->readAll().size(), 3u);  // the next line is fine again
  emulator_.updateFaults([](auto& f) { f.silent = true; });
  EXPECT_THROW(box->readAll(), TimeoutError);
}

TEST(SerialTransport, AMissingPortIsNamed) {
  try {
    SerialTransport t("/dev/mtcal-no-such-port", 115200);
    FAIL();
  } catch (const TransportError& e) {
    EXPECT_NE(std::string(e.what()).find("/dev/mtcal-no-such-port"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace mtcal::drivers::probes
