#pragma once
// Host side of the inductive probe interface box (docs/protocols/probes.md) over any
// Transport (a serial line for the real box). Values are delivered in mm as the box reports
// them; a channel whose status is not OK is an error when read (reads name the channel and
// the status) and is flagged in streamed samples (Sample::beam_ok false).
//
// Thread-safety: commands from one control thread; while streaming, the reader thread
// only calls the sink and hands command replies to the control thread.

#include <memory>

#include "mtcal/drivers/line_device.h"
#include "mtcal/drivers/probes/protocol.h"

namespace mtcal::drivers::probes {

using Timeouts = LineTimeouts;

/// The longest wait for the next latch of a triggered box before the link counts as stalled:
/// a trigger as rare as a logger's record, a day, plus a minute.
inline constexpr std::chrono::milliseconds kMaxTriggerGap{(86400LL + 60) * 1000};

class ProbeBoxDevice final : public LineDevice {
 public:
  /// Takes the transport, stops a stream a previous session may have left running,
  /// identifies the box and reads its channel count.
  /// @throws TransportError, TimeoutError, ProtocolError
  ProbeBoxDevice(std::unique_ptr<Transport> transport, std::string uri, Timeouts timeouts = {});
  ~ProbeBoxDevice() override;

  DeviceInfo info() const override;
  const ChannelInfo& channels() const { return channels_; }

  /// Every channel once, mm. @throws DeviceError naming a channel whose status is not OK
  /// (over range, under range, no probe), TimeoutError, ProtocolError
  std::vector<double> readAll();
  /// Sets the current readings as zero (channel 0: all). @throws DeviceError, TimeoutError
  void zero(int channel);

  /// Streams at `rate_hz` (1..1000): one Sample per channel per line, `channel` set,
  /// the same seq for the channels of one line.
  void startStream(std::uint32_t rate_hz, SampleSink& sink) override;
  /// Latches every channel on each pulse of the box's trigger input (e.g. a data logger's
  /// record output): one Sample per channel per pulse, seq counting pulses from 0. Stopped by
  /// stopStream().
  void startTriggered(SampleSink& sink);
  StreamStats stopStream() override;
  /// Channels 1..count: "displacement" in mm, named "ch1"..; streamed and triggered alike.
  /// signal_pct holds nothing (0).
  std::vector<StreamChannel> streamChannels() const override;

 private:
  bool isStreamLine(const std::string& line) const override;
  void onStreamLine(const std::string& line) override;

  Identity identity_;
  ChannelInfo channels_;
  std::vector<Sample> samples_buffer_;  // reader thread
  bool triggered_ = false;              ///< the current stream is latched by the trigger
};

}  // namespace mtcal::drivers::probes
