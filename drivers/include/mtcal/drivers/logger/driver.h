#pragma once
// Host side of the temperature data logger (docs/protocols/logger.md) over any Transport (a
// serial line for the real logger). Readings are degC; a sensor that is out (open circuit)
// or over range is never a number: read() reports its status, logged samples carry NaN and
// beam_ok false.

#include <chrono>
#include <memory>

#include "mtcal/drivers/line_device.h"
#include "mtcal/drivers/logger/protocol.h"

namespace mtcal::drivers::logger {

class TemperatureLoggerDevice final : public LineDevice {
 public:
  /// Stops logging a previous session may have left running, identifies the logger and reads
  /// its channel count. @throws TransportError, TimeoutError, ProtocolError
  TemperatureLoggerDevice(std::unique_ptr<Transport> transport, std::string uri, LineTimeouts timeouts = {});
  ~TemperatureLoggerDevice() override;

  DeviceInfo info() const override;
  const ChannelInfo& channels() const { return channels_; }

  /// Every channel now. @throws DeviceError, TimeoutError, ProtocolError
  Record read();
  /// Logs every `interval` (1 s .. 1 day) from the logger's next whole second: one Sample per
  /// channel per record (seq = record index, value degC or NaN, beam_ok = sensor OK). The
  /// stall timeout must exceed the interval.
  void startLogging(std::chrono::seconds interval, SampleSink& sink);
  /// Instrument: logging once a second (rate_hz 1; a logger is not faster).
  void startStream(std::uint32_t rate_hz, SampleSink& sink) override;
  StreamStats stopStream() override;
  /// Channels 1..count: "temperature" in degC, named "ch1".. (the logger knows no sites).
  /// signal_pct holds nothing (0).
  std::vector<StreamChannel> streamChannels() const override;

 private:
  bool isStreamLine(const std::string& line) const override;
  void onStreamLine(const std::string& line) override;

  Identity identity_;
  ChannelInfo channels_;
  std::vector<Sample> samples_buffer_;  // reader thread
};

}  // namespace mtcal::drivers::logger
