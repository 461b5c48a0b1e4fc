#pragma once
// Host side of the telescoping ballbar (docs/protocols/ballbar.md) over any HidTransport
// (hidapi on hidraw for the real bar). Every set feature is confirmed by reading the status
// report: a refused command is a DeviceError naming the command and the device's reason.
// Streamed samples are length deviations in mm (Sample::value; 0.1 um resolution); a sample
// over range has beam_ok false. Lost samples (sequence gaps, the device's own FIFO drops
// included) are counted in StreamStats::lost_samples, never hidden.
//
// Thread-safety: commands from one control thread; while streaming, the reader thread only
// reads input reports and calls the sink.

#include <atomic>
#include <chrono>
#include <memory>
#include <mutex>
#include <optional>

#include "mtcal/drivers/ballbar/protocol.h"
#include "mtcal/drivers/hid_transport.h"
#include "mtcal/drivers/instrument.h"
#include "mtcal/drivers/reader_thread.h"

namespace mtcal::drivers::ballbar {

struct Timeouts {
  std::chrono::milliseconds read{20};     ///< one input report read in the reader loop
  std::chrono::milliseconds stall{2000};  ///< no report for this long while streaming is an error
};

/// What the last sample report said about the bar itself.
struct Condition {
  double temperature_c = 20.0;
  int battery_pct = 100;
  bool battery_low = false;
  bool zeroed = false;
};

class BallbarDevice final : public Instrument {
 public:
  /// Takes the transport, stops a stream a previous session may have left running and
  /// identifies the bar. @throws TransportError, ProtocolError, DeviceError
  BallbarDevice(std::unique_ptr<HidTransport> transport, std::string uri, Timeouts timeouts = {});
  ~BallbarDevice() override;

  DeviceInfo info() const override;
  const Identity& identity() const { return identity_; }
  Status status();

  /// Zeroes the bar in its calibrator: the current length becomes `reference_length_mm` (the
  /// calibrator's certified length). Not while streaming. @throws DeviceError, InputError
  void zero(double reference_length_mm);

  /// Streams at `rate_hz` (1..1000) into `sink`. @throws DeviceError, InputError
  void startStream(std::uint32_t rate_hz, SampleSink& sink) override;
  StreamStats stopStream() override;
  void poll() override;
  StreamStats stats() const override;
  /// One channel (0): "length deviation" in mm; signal_pct is the battery, %.
  std::vector<StreamChannel> streamChannels() const override;
  Condition condition() const;

 private:
  /// Sends a set feature and confirms it from the status report. @throws DeviceError
  void command(const std::vector<std::uint8_t>& report, const char* what);
  /// Discards input reports left from an earlier stream.
  void flushInput();
  void readerLoop();

  std::unique_ptr<HidTransport> transport_;
  std::string uri_;
  Timeouts timeouts_;
  Identity identity_;

  std::atomic<bool> streaming_{false};
  SampleSink* sink_ = nullptr;
  std::optional<std::uint32_t> next_seq_;
  std::optional<std::uint32_t> last_time_us_;  ///< reader thread only
  std::int64_t time_epoch_us_ = 0;
  std::atomic<std::uint64_t> samples_{0}, lost_{0}, bad_reports_{0};
  mutable std::mutex state_mutex_;  // guards condition_
  Condition condition_;
  ReaderThread reader_;  // last: joined before the members its loop uses are destroyed
};

}  // namespace mtcal::drivers::ballbar
