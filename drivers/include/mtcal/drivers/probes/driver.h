#pragma once
// Host side of the inductive probe interface box (docs/protocols/probes.md) over any
// Transport (a serial line for the real box). Values are delivered in mm as the box reports
// them; a channel whose status is not OK is an error when read (reads name the channel and
// the status) and is flagged in streamed samples (Sample::beam_ok false).
//
// Thread-safety: commands from one control thread; while streaming, the reader thread
// only calls the sink and hands command replies to the control thread.

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <deque>
#include <exception>
#include <memory>
#include <mutex>
#include <thread>

#include "mtcal/drivers/instrument.h"
#include "mtcal/drivers/line_decoder.h"
#include "mtcal/drivers/probes/protocol.h"
#include "mtcal/drivers/transport.h"

namespace mtcal::drivers::probes {

struct Timeouts {
  std::chrono::milliseconds command{1000};  ///< write + reply of one command
  std::chrono::milliseconds read{100};      ///< one transport read in the reader loop
  std::chrono::milliseconds stall{2000};    ///< no stream line for this long is an error
};

class ProbeBoxDevice final : public Instrument {
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
  StreamStats stopStream() override;
  void poll() override;
  StreamStats stats() const override;

 private:
  std::string transact(const std::string& command);
  std::string readLine(std::chrono::steady_clock::time_point deadline, const std::string& command);
  void readerLoop();

  std::unique_ptr<Transport> transport_;
  std::string uri_;
  Timeouts timeouts_;
  Identity identity_;
  ChannelInfo channels_;
  LineDecoder decoder_{kMaxLineBytes};  // reader thread while streaming, the control thread otherwise

  std::mutex command_mutex_;
  std::mutex reply_mutex_;  // guards replies_ and reader_error_
  std::condition_variable reply_cv_;
  std::deque<std::string> replies_;
  std::exception_ptr reader_error_;

  std::thread reader_;
  std::atomic<bool> streaming_{false}, stop_reader_{false};
  SampleSink* sink_ = nullptr;
  std::optional<std::uint32_t> next_seq_;
  std::atomic<std::uint64_t> samples_{0}, lost_{0}, bad_lines_{0};
};

}  // namespace mtcal::drivers::probes
