#pragma once
// Host side of the laser tracker (docs/protocols/tracker.md) over TCP. Every command has a
// deadline; a BUSY tracker is asked again until the deadline; an ERR reply becomes a
// DeviceError naming the command, the code and the tracker's text. When the link breaks the
// next command reconnects once, negotiates the protocol again, restores units, environment
// and reflector, and repeats the command (every command of the protocol can be repeated).
//
// Continuous measurement is the Instrument stream: each point becomes three Samples
// (channel 1, 2, 3 = x, y, z in mm, one seq), delivered from a reader thread. No other
// command is accepted while it runs.
//
// Thread-safety: commands from one control thread; while streaming the reader thread owns
// the connection until stopStream().

#include <atomic>
#include <chrono>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "mtcal/drivers/instrument.h"
#include "mtcal/drivers/line_decoder.h"
#include "mtcal/drivers/reader_thread.h"
#include "mtcal/drivers/tcp_transport.h"
#include "mtcal/drivers/tracker/protocol.h"

namespace mtcal::drivers::tracker {

struct Timeouts {
  std::chrono::milliseconds command{2000};      ///< write + reply of one command (integration time added)
  std::chrono::milliseconds initialise{60000};  ///< INIT and HOME, BUSY retries included
  std::chrono::milliseconds read{50};           ///< one transport read in the reader loop
  std::chrono::milliseconds stall{2000};        ///< no stream point for this long is an error
  std::chrono::milliseconds busy_retry{20};     ///< pause before asking a BUSY tracker again
};

struct Environment {
  double air_temp_c = 20.0, pressure_hpa = 1013.25, humidity_pct = 50.0;
};

class TrackerDevice final : public Instrument {
 public:
  /// Takes the connection and negotiates the protocol (HELLO).
  /// @throws TransportError, TimeoutError, ProtocolError (another major version)
  TrackerDevice(std::unique_ptr<TcpTransport> transport, std::string uri, Timeouts timeouts = {});
  ~TrackerDevice() override;

  DeviceInfo info() const override;
  const Hello& hello() const { return hello_; }

  /// INIT: the tracker's start-up (encoders referenced, ADM warmed); waits through BUSY.
  void initialise();
  /// UNITS MM DEG C HPA: the only units this driver speaks; set again after a reconnect.
  void setUnits();
  /// ENV: air for the refractive index. @throws InputError outside 0..50 C, 500..1200 hPa, 0..100 %
  void setEnvironment(const Environment& env);
  /// REFLECTOR: e.g. "RRR1.5" (1.5 inch red ring reflector).
  void setReflector(const std::string& name);
  /// HOME: the beam goes to the bird bath and locks on the reflector there.
  void goHome();
  /// MEAS: one stationary point averaged over `integration_ms` (1..60000).
  /// @throws InputError out of range, DeviceError (beam broken, not initialised)
  Point measure(int integration_ms);
  Status status();

  /// CONT <rate>: continuous measurement at 1..1000 points/s into `sink`.
  void startStream(std::uint32_t rate_hz, SampleSink& sink) override;
  StreamStats stopStream() override;
  void poll() override;
  StreamStats stats() const override;
  /// Channels 1, 2, 3: "position" x, y, z in mm (the tracker's frame). signal_pct holds
  /// nothing measured (always 100).
  std::vector<StreamChannel> streamChannels() const override;

  int reconnects() const { return reconnects_; }

 private:
  std::vector<std::string> command(const std::string& verb, std::vector<std::string> args,
                                   std::chrono::milliseconds timeout);
  Reply exchange(const std::string& verb, const std::vector<std::string>& args,
                 std::chrono::steady_clock::time_point deadline);
  std::string readLine(std::chrono::steady_clock::time_point deadline, const std::string& what);
  void reconnectAndRestore();
  void handleEvent(const Event& event);
  void readerLoop();
  void refuseWhileStreaming(const std::string& verb) const;

  std::unique_ptr<TcpTransport> transport_;
  std::string uri_;
  Timeouts timeouts_;
  Hello hello_;
  LineDecoder decoder_{kMaxLineBytes};  // the reader thread while streaming, the control thread otherwise
  std::uint32_t next_tag_ = 1;
  bool units_set_ = false;
  std::optional<Environment> environment_;
  std::string reflector_;
  int reconnects_ = 0;

  std::atomic<bool> streaming_{false};
  SampleSink* sink_ = nullptr;
  std::optional<std::uint32_t> next_seq_;
  std::atomic<std::uint64_t> samples_{0}, lost_{0}, bad_lines_{0};
  ReaderThread reader_;  // last: joined before the members its loop uses are destroyed
};

}  // namespace mtcal::drivers::tracker
