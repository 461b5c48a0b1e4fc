#pragma once
// Host side of the laser interferometer: commands, environment unit and the sample
// stream, over any Transport (USB bulk for the real instrument).
//
// Thread-safety: command methods may be called from one control thread while the
// stream runs; the reader thread only calls the sink.

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <optional>

#include "mtcal/drivers/instrument.h"
#include "mtcal/drivers/interferometer/protocol.h"
#include "mtcal/drivers/reader_thread.h"
#include "mtcal/drivers/transport.h"

namespace mtcal::drivers::interferometer {

inline constexpr std::uint16_t kUsbVendorId = 0x1209;   ///< pid.codes open-hardware vendor id
inline constexpr std::uint16_t kUsbProductId = 0xC417;  ///< mtcal development product id (not allocated)

struct Timeouts {
  std::chrono::milliseconds command{1000};  ///< write + reply of one command
  std::chrono::milliseconds read{100};      ///< one transport read in the reader loop
  std::chrono::milliseconds stall{2000};    ///< no data while streaming for this long is an error
};

class InterferometerDevice final : public Instrument {
 public:
  /// Takes the transport, identifies the device and checks the protocol version.
  /// @throws TransportError, TimeoutError, ProtocolError (unsupported protocol version)
  InterferometerDevice(std::unique_ptr<Transport> transport, std::string uri, Timeouts timeouts = {});
  ~InterferometerDevice() override;

  const Identity& identity() const { return identity_; }
  DeviceInfo info() const override;

  /// @throws DeviceError when the device refuses (NAK), TimeoutError, TransportError
  void setOptics(Optics optics);
  void setDatum();
  Environment readEnvironment();

  /// Starts the stream at `rate_hz` (1..50000). Values are delivered in mm (linear optics).
  void startStream(std::uint32_t rate_hz, SampleSink& sink) override;
  StreamStats stopStream() override;
  void poll() override;
  StreamStats stats() const override;
  /// One channel (0) as the optics are set: linear "uncompensated displacement" mm (the air
  /// index is the host's to apply), angular "angle" urad, straightness mm; signal_pct is the
  /// beam signal.
  std::vector<StreamChannel> streamChannels() const override;

 private:
  Frame transact(const std::vector<std::uint8_t>& request, MessageType expected);
  void readerLoop();
  void handleData(const Frame& frame);
  void deliverReply(Frame frame);

  std::unique_ptr<Transport> transport_;
  std::string uri_;
  Timeouts timeouts_;
  Identity identity_;
  Optics optics_ = Optics::kLinear;
  FrameDecoder decoder_;  // reader thread only while streaming, caller otherwise

  std::mutex command_mutex_;  // one command at a time
  // Guards reply_; waited on for a reply or the reader's failure. poll() takes the reader's
  // error under it, so a command woken by the failure still finds it.
  std::mutex reply_mutex_;
  std::condition_variable reply_cv_;
  std::optional<Frame> reply_;

  std::atomic<bool> streaming_{false};
  SampleSink* sink_ = nullptr;
  std::optional<std::uint32_t> next_seq_;
  std::atomic<std::uint64_t> samples_{0}, lost_{0}, crc_errors_{0}, discarded_bytes_{0};
  std::vector<Sample> scratch_;
  ReaderThread reader_;  // last: joined before the members its loop uses are destroyed
};

}  // namespace mtcal::drivers::interferometer
