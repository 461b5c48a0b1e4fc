#pragma once
// Device side of the telescoping ballbar (docs/protocols/ballbar.md), observing a
// VirtualMachine. The bar joins a ball on the tool (at `tool_ball_offset_mm` from the tool
// point) to a ball fixed on the table; it reports the centre-to-centre length minus the
// reference length it was zeroed to:
//
//   deviation = (|P_tool(t) - P_centre| + zero offset - reference) + noise       (um)
//
// P_tool the actual position of the tool ball (every geometric error of the model, servo
// lag, lost motion and reversal sticks of VirtualMachine::followPath), P_centre where the
// table ball was placed (the actual tool-ball position when the operator set it, machine at
// rest at the circle centre). In its calibrator the bar's length is the calibrator's true
// length (nominal + calibrator_error_um). Samples lie on a grid of the world clock (sample k
// at k / rate); noise is keyed to the seed, the machine's last move and the sample's place
// after that move's end: the same seed, the same readings along a path.
//
// Thread-safety: every method locks; a transport's reader and control threads may share it.

#include <Eigen/Core>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <mutex>
#include <span>
#include <string>
#include <vector>

#include "mtcal/drivers/ballbar/protocol.h"
#include "mtcal/drivers/hid_transport.h"
#include "mtcal/mocks/virtual_machine.h"

namespace mtcal::mocks {

struct BallbarEmulatorConfig {
  std::string model = "MTCAL-BB";
  std::string serial = "BB0001";
  std::string firmware = "1.2.0";
  int nominal_length_mm = 100;
  int range_um = 1000;               ///< +- measuring range of the transducer
  double noise_um = 0.1;             ///< per sample, 1 sigma
  double calibrator_error_um = 0.0;  ///< calibrator's true length - its certified length
  double temperature_c = 20.3;
  int battery_pct = 87;
  std::size_t fifo_reports = 256;    ///< the device's report buffer; older reports are dropped
  ToolOffset tool_ball_offset_mm{};  ///< from the tool point
};

struct BallbarFaults {
  int drop_next_reports = 0;    ///< lose the next N reports (the sequence numbers jump)
  int garble_next_reports = 0;  ///< send the next N reports with a bad count byte
  bool unplugged = false;       ///< every transfer fails
};

class BallbarEmulator {
 public:
  BallbarEmulator(VirtualMachine& machine, BallbarEmulatorConfig config);

  // Operator actions of a set-up.
  /// Fits the extensions for a bar of this nominal length (mm; 50, 100, 150 ...).
  void fitLength(int nominal_length_mm);
  /// Puts the bar in its calibrator (its length is the calibrator's true length).
  void placeInCalibrator();
  /// Sets the table ball where the tool ball is now (the machine at rest at the circle's
  /// centre) and mounts the bar between the two.
  void mountOnMachine();

  // The USB HID side.
  /// @throws ProtocolError for an unknown report or a bad length (hidraw: the ioctl fails),
  ///         TransportError when unplugged
  void setFeature(std::span<const std::uint8_t> report);
  std::size_t getFeature(std::span<std::uint8_t> buffer);
  /// The next input report, waiting up to `timeout` (wall time). @return its size; 0: none in time
  /// @throws TransportError when unplugged
  std::size_t readInput(std::span<std::uint8_t> buffer, std::chrono::nanoseconds timeout);
  /// Whether an input report is ready within `timeout` (what poll() on the node says).
  bool waitInput(std::chrono::nanoseconds timeout);

  void updateFaults(const std::function<void(BallbarFaults&)>& change);
  const BallbarEmulatorConfig& config() const { return config_; }
  /// Noise-free bar length (mm) at world time t, for tests.
  double trueLengthMm(double t_s) const;

 private:
  double lengthMm(double t_s) const;  // caller holds the lock
  /// Generates every report whose samples are all due by world time `now_s`.
  void produce(double now_s);
  drivers::ballbar::Status status() const;
  int samplesPerReport() const;

  VirtualMachine& machine_;
  BallbarEmulatorConfig config_;
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  BallbarFaults faults_;
  bool mounted_ = false;
  Eigen::Vector3d centre_mm_ = Eigen::Vector3d::Zero();
  double reference_mm_ = 0.0, zero_offset_mm_ = 0.0;
  bool zeroed_ = false;
  bool streaming_ = false;
  std::uint32_t rate_hz_ = 100;
  std::uint64_t next_k_ = 0;  ///< grid index of the next sample to send
  std::uint32_t next_seq_ = 0;
  std::uint32_t dropped_ = 0;
  bool overflowed_ = false;
  std::deque<std::vector<std::uint8_t>> fifo_;
  drivers::ballbar::ReportId last_command_ = drivers::ballbar::ReportId::kStatus;
  drivers::ballbar::Result last_result_ = drivers::ballbar::Result::kOk;
};

/// The in-process HID transport onto a BallbarEmulator (what hidraw would carry).
class EmulatorHidTransport final : public drivers::HidTransport {
 public:
  explicit EmulatorHidTransport(std::shared_ptr<BallbarEmulator> device) : device_(std::move(device)) {}
  std::size_t read(std::span<std::uint8_t> buffer, drivers::milliseconds timeout) override;
  void write(std::span<const std::uint8_t> data, drivers::milliseconds timeout) override;
  void setFeature(std::span<const std::uint8_t> report) override;
  std::size_t getFeature(std::span<std::uint8_t> buffer) override;
  std::string describe() const override { return "emulated ballbar (in-process HID)"; }

 private:
  std::shared_ptr<BallbarEmulator> device_;
};

}  // namespace mtcal::mocks
