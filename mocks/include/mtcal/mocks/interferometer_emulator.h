#pragma once
// Device side of the laser interferometer protocol, observing a VirtualMachine. It is fed
// the bytes the host writes and produces the bytes the host reads, so it can sit behind the
// in-process EmulatorTransport or behind umockdev's emulated USB endpoints alike.
//
// Readings: raw = n_air * (actual position - position at datum), the optical path measured
// with the vacuum wavelength, plus reading noise; this is what a real head reports before
// the host compensates it.
//
// Thread-safety: receive() and transmit() may be called from different threads.

#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <mutex>
#include <optional>
#include <span>
#include <vector>

#include "mtcal/drivers/interferometer/protocol.h"
#include "mtcal/mocks/virtual_machine.h"

namespace mtcal::mocks {

struct InterferometerEmulatorConfig {
  std::string model = "MTCAL-LI1 (emulated)";
  std::string serial = "EMU0001";
  std::string firmware = "1.0.0";
  double vacuum_wavelength_nm = 632.990577;
  Axis axis = Axis::kX;              ///< axis the beam is first aligned with
  ToolOffset beam_offset_mm{};       ///< first reflector position: offset from the tool point (Abbe)
  double noise_um = 0.02;            ///< reading noise of linear and straightness optics, 1 sigma
  double angular_noise_urad = 0.05;  ///< reading noise of angular optics, 1 sigma
  double env_noise_temp_k = 0.005, env_noise_pressure_pa = 2.0, env_noise_humidity_pct = 0.1;
  int material_sensors = 1;
  std::uint8_t signal_pct = 85;
  /// Bytes the device can hold for a host that does not read fast enough; DATA frames
  /// beyond it are dropped (a sequence gap the host counts), as a real head's FIFO does.
  std::size_t device_buffer_bytes = 1024 * 1024;
  /// When false the stream is generated as fast as it is read (benchmarks); device time
  /// then advances by 1/rate per sample regardless of the wall clock.
  bool paced = true;
};

/// Faults a test can inject at any time.
struct InterferometerFaults {
  bool disconnected = false;  ///< every transfer fails like an unplugged device
  /// Unplugged once the samples with sequence numbers below this one have been sent.
  std::optional<std::uint32_t> disconnect_at_seq;
  bool silent = false;            ///< the device stops answering and streaming
  int corrupt_next_frames = 0;    ///< flip a payload byte in the next N frames
  int drop_next_data_frames = 0;  ///< drop the next N DATA frames (lost samples)
  bool beam_blocked = false;      ///< readings flagged beam-not-ok, signal 0
  bool nak_start_stream = false;  ///< refuse START_STREAM with BEAM_LOST
};

class InterferometerEmulator {
 public:
  InterferometerEmulator(VirtualMachine& machine, InterferometerEmulatorConfig config);

  /// Bytes from the host (bulk OUT). Complete frames are executed at once.
  /// @throws TransportError when disconnected.
  void receive(std::span<const std::uint8_t> bytes);

  /// Bytes to the host (bulk IN): pending replies and due stream data, at most
  /// buffer.size(). Waits up to `timeout` for something to send.
  /// @return bytes written (0 on timeout). @throws TransportError when disconnected.
  std::size_t transmit(std::span<std::uint8_t> buffer, std::chrono::nanoseconds timeout);

  /// What an operator does before a run: aligns the beam with `axis`, mounts the optics for
  /// one error component (-1 or the axis' own direction: linear optics; another translation
  /// 0..2 along X, Y, Z: straightness optics; 3..5 rotations about X, Y, Z: angular optics)
  /// and places the moving optic on the tool at `reflector_offset_mm` from the tool point.
  void mount(Axis axis, int component, const ToolOffset& reflector_offset_mm);

  /// Changes the injected faults atomically, e.g. updateFaults([](auto& f) { f.silent = true; }).
  void updateFaults(const std::function<void(InterferometerFaults&)>& change);
  bool streaming() const;
  /// Samples dropped because the host did not read them in time (device buffer full).
  std::uint64_t samplesOverflowed() const;
  const InterferometerEmulatorConfig& config() const { return config_; }

 private:
  void execute(const drivers::interferometer::Frame& frame);
  void queueFrame(std::vector<std::uint8_t> frame);
  /// Generates the DATA frames due at world time `now` (paced) or one frame (unpaced).
  void generateDue();
  /// The reading at world time t; `settled_mm` is the machine's displacement when the
  /// caller knows it is constant (settled axis), saving its evaluation.
  drivers::interferometer::RawSample sampleAt(double t_s, const std::optional<double>& settled_mm,
                                              double air_index) const;
  /// The true air's index at t: the machine's constant air, or its thermal state's ambient.
  double airIndexAt(double t_s) const;
  /// t snapped down to the sample grid that starts at the move's in-position time.
  double gridTime(double t_s, double done_s) const;

  VirtualMachine& machine_;
  InterferometerEmulatorConfig config_;
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  drivers::interferometer::FrameDecoder decoder_;
  std::deque<std::uint8_t> out_;
  InterferometerFaults faults_;
  bool streaming_ = false;
  std::uint32_t rate_hz_ = 0;
  std::uint32_t next_seq_ = 0;
  std::uint32_t stream_first_seq_ = 0;  ///< next_seq_ when the current stream started
  double stream_start_s_ = 0.0;
  double datum_mm_ = 0.0;
  double air_index_ = 1.0;  ///< of the machine's air without a thermal state, the truth the host must compensate
  std::uint64_t env_reads_ = 0;
  std::uint64_t samples_overflowed_ = 0;
  drivers::interferometer::Optics optics_ = drivers::interferometer::Optics::kLinear;
  int mounted_component_ = -1;  ///< -1: only linear optics mounted
  Axis axis_;
  ToolOffset reflector_offset_mm_;
};

}  // namespace mtcal::mocks
