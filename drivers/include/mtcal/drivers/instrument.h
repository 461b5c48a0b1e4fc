#pragma once
// The one interface every opened instrument offers, and the sample stream it produces.

#include <cstdint>
#include <span>
#include <string>

namespace mtcal::drivers {

struct DeviceInfo {
  std::string uri;
  std::string kind;  ///< interferometer, ballbar, probes, tracker
  std::string model, serial, firmware;
};

/// One streamed reading, converted to engineering units by the driver.
struct Sample {
  std::uint32_t seq = 0;            ///< device sequence number; gaps mean lost samples
  std::int64_t device_time_ns = 0;  ///< device clock
  double value = 0.0;               ///< mm (linear optics, uncompensated; probes), urad (angular)
  int signal_pct = 0;               ///< beam signal strength 0..100
  bool beam_ok = true;              ///< interferometer: beam intact; probes: channel status OK
  int channel = 0;                  ///< multi-channel instruments: 1..n, one Sample per channel
};

/// Receives samples on the instrument's reader thread. It must not block for long;
/// whatever it throws stops the stream and is rethrown by poll() / stopStream().
class SampleSink {
 public:
  virtual ~SampleSink() = default;
  virtual void push(std::span<const Sample> samples) = 0;
};

struct StreamStats {
  std::uint64_t samples = 0;          ///< delivered to the sink
  std::uint64_t lost_samples = 0;     ///< sequence-number gaps
  std::uint64_t crc_errors = 0;       ///< frames dropped by the decoder
  std::uint64_t discarded_bytes = 0;  ///< bytes skipped while resynchronising
};

class Instrument {
 public:
  virtual ~Instrument() = default;
  virtual DeviceInfo info() const = 0;
  /// Starts streaming into `sink` from a reader thread. @throws DeviceError, TransportError
  virtual void startStream(std::uint32_t rate_hz, SampleSink& sink) = 0;
  /// Stops streaming, joins the reader and rethrows what it failed with, if anything.
  virtual StreamStats stopStream() = 0;
  /// Rethrows the reader thread's error, if any; cheap, call it from the consumer loop.
  virtual void poll() = 0;
  virtual StreamStats stats() const = 0;
};

}  // namespace mtcal::drivers
