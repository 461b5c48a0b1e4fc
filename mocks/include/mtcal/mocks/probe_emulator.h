#pragma once
// Device side of the inductive probe interface box (docs/protocols/probes.md), observing a
// VirtualMachine. Probe i (0-based) is fixed to the tool at `base_offset_mm` + i * spacing
// along the stepping axis and reads the guideway below it along `measuring` (Y or Z):
//
//   reading_i = S(x + i * spacing) - d(probe i) + zero_i + noise          (um, reported in mm)
//
// S the guideway's profile (the part, set here), d the tool's displacement at the probe tip
// along the measuring direction (the machine's straightness, and its yaw or pitch through the
// lever arm i * spacing: the paper's R and -l gamma), zero_i the probe's mounting offset
// (ZERO tares it). Noise is keyed to the seed, the move and the reading's slot after it: the
// same seed, the same readings.
//
// Thread-safety: receive() and transmit() may be called from different threads.

#include <array>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <mutex>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "mtcal/drivers/line_decoder.h"
#include "mtcal/drivers/probes/protocol.h"
#include "mtcal/mocks/virtual_machine.h"

namespace mtcal::mocks {

struct ProbeBoxEmulatorConfig {
  std::string model = "MTCAL-PB3 (emulated)";
  std::string serial = "PB0001";
  std::string firmware = "1.0.0";
  int channels = 3;
  double range_mm = 1.0;
  double noise_um = 0.02;                       ///< per reading, 1 sigma
  std::vector<double> zero_um{0.0, 2.5, -1.8};  ///< mounting offsets of the probes
  double spacing_mm = 20.0;                     ///< between neighbouring probes
  Axis axis = Axis::kX;                         ///< the carriage the probes ride on
  int measuring = 1;                            ///< 1: along Y, 2: along Z
  ToolOffset base_offset_mm{};                  ///< probe 1's tip, from the tool point
  /// The guideway's profile S(x), um over the axis position in mm.
  ErrorCurve profile_um{{0.0, 0.0, 12.0}, {{1.5, 160.0, 0.3}, {0.4, 45.0, 1.1}}};
};

struct ProbeBoxFaults {
  int over_range_channel = 0;  ///< this channel (1..n) reports over range
  int no_probe_channel = 0;    ///< this channel reports no probe
  int garble_next_lines = 0;   ///< corrupt the next N lines sent
  bool silent = false;         ///< answers nothing
};

class ProbeBoxEmulator {
 public:
  ProbeBoxEmulator(VirtualMachine& machine, ProbeBoxEmulatorConfig config);

  /// Bytes from the host.
  void receive(std::span<const std::uint8_t> bytes);
  /// Bytes to the host, waiting up to `timeout` for some. @return bytes written (0: none)
  std::size_t transmit(std::span<std::uint8_t> buffer, std::chrono::nanoseconds timeout);

  void updateFaults(const std::function<void(ProbeBoxFaults&)>& change);
  const ProbeBoxEmulatorConfig& config() const { return config_; }
  /// A pulse on the box's trigger input at world time t (wired to a logger's record output):
  /// in triggered mode (TRIG ON) the box latches every channel at t and sends an L line.
  void trigger(double t_s);
  /// Sets the direction the probes read along (1: Y, 2: Z), e.g. a thermal test's probe on a
  /// test mandrel. @throws InputError for another
  void setMeasuring(int component);
  /// The probes set on (true) or taken off (false) a reference flat: on it, they read a straight
  /// surface (no profile) with the carriage's pose and their zeros, as a zeroing measures them.
  void setOnReferenceFlat(bool on);
  /// The true value probe `channel` (1..n) reads at axis position x (no noise, no tare), um:
  /// S(x_i) - d_i + zero_i with the machine at rest there. For tests.
  double trueReadingUm(int channel, double x_mm) const;

 private:
  void execute(const std::string& line);
  void send(std::string line);
  /// Every channel as the box reads it at world time t (a command's time, or a stream
  /// line's own time stamp, whenever the line is generated).
  std::vector<drivers::probes::Reading> readAll(double t_s, std::optional<std::uint64_t> latch = std::nullopt);
  /// Noise-free readings (um, before the tare) at world time t.
  std::vector<double> noiseFreeUm(double t_s) const;
  ToolOffset probeOffset(int index) const;

  VirtualMachine& machine_;
  ProbeBoxEmulatorConfig config_;
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  drivers::LineDecoder decoder_{drivers::probes::kMaxLineBytes};
  std::deque<std::uint8_t> out_;
  ProbeBoxFaults faults_;
  std::vector<double> tare_um_;
  /// Once the machine is settled after a move, the readings are constant but for noise: they
  /// are computed once per move (keyed by the move's epoch), which keeps a stream cheap.
  std::pair<std::uint64_t, double> cached_epoch_{~std::uint64_t{0}, 0.0};
  std::vector<double> cached_um_;
  bool streaming_ = false;
  bool triggered_ = false;
  bool on_reference_flat_ = false;
  std::uint32_t next_latch_ = 0;
  std::uint32_t rate_hz_ = 100, next_seq_ = 0;
  std::uint32_t stream_first_seq_ = 0;  ///< next_seq_ when the current stream started
  double stream_start_s_ = 0.0;
};

/// A pseudo-terminal with a device emulator behind it: the host opens slavePath() as a
/// serial port (the real SerialTransport code path); a pump thread moves bytes between the
/// pty master and the emulator. @throws TransportError when no pty can be opened
class PtyLink {
 public:
  using Receive = std::function<void(std::span<const std::uint8_t>)>;
  using Transmit = std::function<std::size_t(std::span<std::uint8_t>, std::chrono::nanoseconds)>;
  PtyLink(Receive receive, Transmit transmit);
  ~PtyLink();
  PtyLink(const PtyLink&) = delete;
  PtyLink& operator=(const PtyLink&) = delete;
  const std::string& slavePath() const { return slave_path_; }

 private:
  void pump();
  Receive receive_;
  Transmit transmit_;
  int master_ = -1, slave_ = -1;
  std::string slave_path_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

}  // namespace mtcal::mocks
