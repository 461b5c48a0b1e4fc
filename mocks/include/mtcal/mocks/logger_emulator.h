#pragma once
// Device side of the temperature data logger (docs/protocols/logger.md), reading the sensor
// sites of the virtual machine's thermal state (channel i: site i of the model; without a
// thermal state every channel reads the machine's air temperature). Each reading is the
// site's temperature plus the sensor's calibration offset (seeded, within +-0.05 K) and noise
// (keyed to the seed, the channel and the conversion), rounded to 0.01 K.
//
// Records are converted on the logger's clock (the world clock): the first at the next whole
// second after LOG, then every interval; their values depend on that time only, so the same
// seed and program give the same records.
//
// Thread-safety: receive() and transmit() may be called from different threads.

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <mutex>
#include <span>
#include <string>
#include <vector>

#include "mtcal/drivers/line_decoder.h"
#include "mtcal/drivers/logger/protocol.h"
#include "mtcal/mocks/virtual_machine.h"

namespace mtcal::mocks {

struct LoggerEmulatorConfig {
  std::string model = "MTCAL-TL16 (emulated)";
  std::string serial = "TL0001";
  std::string firmware = "1.0.0";
  int channels = 16;       ///< 8 or 16
  double noise_k = 0.005;  ///< per reading, 1 sigma
  double offset_k = 0.05;  ///< calibration offsets up to this
};

struct LoggerFaults {
  /// Channel (1..n) out (open circuit) from world time `from_s` to `to_s`.
  struct Dropout {
    int channel = 0;
    double from_s = 0.0, to_s = 0.0;
  };
  std::vector<Dropout> dropouts;
  bool silent = false;  ///< answers nothing, logs nothing (unplugged)
};

class LoggerEmulator {
 public:
  LoggerEmulator(VirtualMachine& machine, LoggerEmulatorConfig config);
  void receive(std::span<const std::uint8_t> bytes);
  std::size_t transmit(std::span<std::uint8_t> buffer, std::chrono::nanoseconds timeout);
  void updateFaults(const std::function<void(LoggerFaults&)>& change);
  const LoggerEmulatorConfig& config() const { return config_; }
  /// The host has told it to log (LOG n) and not to stop.
  bool logging() const;
  /// The logger's trigger output: called with the world time of every logged record (a
  /// probe box's trigger input wired to it). Set before logging starts.
  void setTriggerOutput(std::function<void(double t_s)> output);
  /// Channel `channel`'s (1..n) noise-free temperature at world time t, degC (offset included).
  double trueReadingC(int channel, double t_s) const;

 private:
  void execute(const std::string& line);
  drivers::logger::Record convert(double t_s, std::uint64_t key) const;

  VirtualMachine& machine_;
  LoggerEmulatorConfig config_;
  std::vector<double> offset_c_;
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  drivers::LineDecoder decoder_{drivers::logger::kMaxLineBytes};
  std::deque<std::uint8_t> out_;
  LoggerFaults faults_;
  bool logging_ = false;
  std::uint32_t interval_s_ = 60, next_index_ = 0;
  double first_record_s_ = 0.0;
  std::function<void(double)> trigger_output_;
};

}  // namespace mtcal::mocks
