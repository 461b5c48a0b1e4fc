#pragma once
// The one interface every opened instrument offers, and the sample stream it produces.

#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace mtcal::drivers {

struct DeviceInfo {
  std::string uri;
  std::string kind;  ///< interferometer, ballbar, probes, tracker
  std::string model, serial, firmware;
};

/// One streamed reading, converted to engineering units by the driver. What `value` and
/// `signal_pct` are, and in which unit, is the StreamChannel of its `channel`.
struct Sample {
  std::uint32_t seq = 0;            ///< device sequence number; gaps mean lost samples
  std::int64_t device_time_ns = 0;  ///< device clock
  double value = 0.0;               ///< in its StreamChannel's unit: mm, urad, degC
  int signal_pct = 0;               ///< 0..100 %: beam signal strength; the ballbar's battery
  bool beam_ok = true;              ///< valid: beam intact; probe or sensor OK; ballbar in range
  int channel = 0;                  ///< multi-channel instruments: 1..n, one Sample per channel
};

/// What one channel of a stream carries: the quantity and unit of Sample::value in the
/// samples with this `channel`, and what their Sample::signal_pct holds. The words are fixed
/// (compare them): quantity "displacement", "uncompensated displacement" (the interferometer's
/// linear reading, air index not applied), "angle", "straightness", "length deviation",
/// "position", "temperature"; unit "mm", "urad", "degC"; signal "beam signal", "battery".
struct StreamChannel {
  int channel = 0;              ///< the Sample::channel it describes: 0 single-channel, else 1..n
  std::string name;             ///< short label: "x", "ch3", "linear", "deviation"
  std::string quantity;         ///< what Sample::value measures
  std::string unit;             ///< Sample::value's unit
  std::string signal_quantity;  ///< what Sample::signal_pct holds; empty: nothing measured
  std::string signal_unit;      ///< "%" with a signal_quantity, else empty
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
  /// The stream's channels as the instrument is set up now (the interferometer's follow its
  /// optics), in Sample::channel order: ask when the stream starts. Control thread.
  virtual std::vector<StreamChannel> streamChannels() const = 0;
};

}  // namespace mtcal::drivers
