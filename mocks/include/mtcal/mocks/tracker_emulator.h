#pragma once
// A laser tracker observing the virtual machine, behind a real TCP server on 127.0.0.1 (an
// ephemeral port) speaking the tracker protocol (docs/protocols/tracker.md) through the
// driver's own codec.
//
// What it measures: the centre of its reflector wherever the (simulated) operator placed it:
// on a nest fixed to the tool side of the machine (targets TB1..TBn on the A body, a nest at
// the tool point), on a face of one of the bed's corner blocks (each stationary measurement
// a new spot of the face, the reflector touching it), or in the bird bath. Machine points
// come from VirtualMachine::actualPointMm (every error of the model, moves interpolated), in
// the tracker's frame (its station on the floor).
//
// Its errors, seeded and keyed to the measurement, as a real tracker's: anisotropic noise
// (distance along the beam far better than the angles across it), a standard deviation
// sigma(T) = sigma_1s * sqrt(1 + T_c / T) falling with the integration time T, occasional
// transverse outliers on short integrations, and the refractive index of the environment the
// host set (ENV) against the true air: a wrong ENV scales the distances.
//
// Thread-safety: the server runs its own thread; placeReflector() and the fault switches may
// be called from any thread.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <atomic>
#include <cstdint>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "mtcal/drivers/line_decoder.h"
#include "mtcal/drivers/tracker/driver.h"
#include "mtcal/drivers/tracker/protocol.h"
#include "mtcal/mocks/virtual_machine.h"

namespace mtcal::mocks {

/// A block at a corner of the bed (bed frame, mm): top face at top_z; side_1 is its face
/// across X, side_2 its face across Y, both facing away from the bed's centre.
struct BedBlock {
  std::string name;
  double x_min_mm = 0, x_max_mm = 200, y_min_mm = 0, y_max_mm = 200;
  double top_z_mm = 0, bottom_z_mm = -300;
};

struct TrackerNoise {
  double distance_um = 1.0, distance_um_per_m = 0.3;      ///< standard deviation at 1 s
  double transverse_um = 3.0, transverse_um_per_m = 1.5;  ///< standard deviation at 1 s
  double integration_constant_ms = 25.0;                  ///< T_c
  double outlier_probability = 0.003;                     ///< per measurement shorter than below
  double outlier_below_ms = 100.0;
  double outlier_um = 80.0;
};

struct TrackerEmulatorConfig {
  std::string model = "MT-LT900", serial = "LT-0042", firmware = "1.0.0";
  int protocol_major = drivers::tracker::kProtocolMajor, protocol_minor = drivers::tracker::kProtocolMinor;
  std::uint64_t seed = 1;
  /// The tracker's station in the bed frame: position (mm) and heading (deg about +Z), with
  /// a small levelling error (urad about X and Y).
  Eigen::Vector3d position_mm{-2500.0, 1500.0, -700.0};
  double heading_deg = 25.0;
  double level_x_urad = 40.0, level_y_urad = -25.0;
  std::vector<BedBlock> blocks;                  ///< empty: none
  std::map<std::string, ToolOffset> tool_nests;  ///< on the tool body, offsets from the tool point
  TrackerNoise noise;
  double init_s = 3.0, home_s = 1.0;  ///< world time INIT and HOME take

  /// The gantry of examples/machines: four 200 mm blocks just outside the X/Y travel with
  /// tops 1200 mm under the ram's zero, TB1..TB5 on the swivel head, a tool-point nest.
  static TrackerEmulatorConfig forGantry(const VirtualMachineConfig& machine, std::uint64_t seed);
  /// The tracker's pose: p_bed = bed_from_tracker * p_tracker.
  Eigen::Isometry3d bedFromTracker() const;
};

class TrackerEmulator {
 public:
  /// Starts the server on 127.0.0.1, an ephemeral port. @throws TransportError
  TrackerEmulator(VirtualMachine& machine, TrackerEmulatorConfig config);
  ~TrackerEmulator();
  TrackerEmulator(const TrackerEmulator&) = delete;
  TrackerEmulator& operator=(const TrackerEmulator&) = delete;

  std::uint16_t port() const { return port_; }
  const TrackerEmulatorConfig& config() const { return config_; }
  /// A driver for it on 127.0.0.1, waiting as long as an emulator may need (world_clock.h).
  std::unique_ptr<drivers::tracker::TrackerDevice> connect(const std::string& uri) const;

  /// The operator puts the reflector on a nest ("TB1", "TCP"), a face ("A.top", "A.side1")
  /// or in the bird bath ("home"); the beam locks on it. @throws InputError for an unknown place
  void placeReflector(const std::string& place);
  std::vector<std::string> places() const;

  /// Where the reflector's centre is (bed frame, mm) at world time t, noise-free: the truth.
  /// Faces: the spot of measurement `index`.
  Eigen::Vector3d truePlaceMm(const std::string& place, double t_s, std::uint64_t index = 0) const;

  // Faults.
  void breakBeam();             ///< until the reflector is placed again
  void dropConnection();        ///< closes the client's connection (it may connect again)
  void setSilent(bool silent);  ///< stop answering and streaming (a hung tracker)

  std::uint64_t measurements() const;

 private:
  /// A stationary measurement being integrated: answered when it is over.
  struct Pending {
    std::uint32_t tag = 0;
    int integration_ms = 0;
    double start_s = 0.0;
  };
  void serve();
  std::vector<std::string> handle(const std::string& line);
  std::string measureReply(std::uint32_t tag, int integration_ms, double start_s);
  Eigen::Vector3d observed(const Eigen::Vector3d& bed_mm, double integration_ms, std::uint64_t stream,
                           std::uint64_t index) const;
  Eigen::Vector3d placePoint(const std::string& place, double t_s, std::uint64_t index) const;
  /// n(true air) / n(the host's ENV): how the distances are scaled. Computed when ENV changes.
  double distanceScale() const;

  VirtualMachine& machine_;
  TrackerEmulatorConfig config_;
  Eigen::Isometry3d tracker_from_bed_;
  int listener_ = -1;
  std::uint16_t port_ = 0;
  std::atomic<bool> stop_{false}, drop_{false}, silent_{false};
  std::thread thread_;
  std::optional<Pending> pending_;  // the server thread only

  mutable std::mutex mutex_;  // everything below
  std::string place_;         // empty: no reflector
  bool beam_locked_ = false;
  /// Where the reflector was from a world time on, and whether the beam held it: a stream's
  /// point at time t sees the reflector as it was at t, however late the server makes it.
  struct ReflectorState {
    double from_s;
    std::string place;
    bool locked;
  };
  std::vector<ReflectorState> reflector_history_;
  const ReflectorState* reflectorAt(double t_s) const;  ///< nullptr before anything was placed
  void recordReflector();                               ///< the current place and beam, from now on
  bool initialised_ = false;
  double busy_until_s_ = -1.0;
  std::string reflector_ = "RRR1.5";
  double reflector_radius_mm_ = 19.05;
  double host_temp_c_ = 20.0, host_pressure_hpa_ = 1013.25, host_humidity_pct_ = 50.0;
  double distance_scale_ = 1.0;  // distanceScale() of the ENV above
  std::uint64_t measurement_index_ = 0;
  bool streaming_ = false;
  double stream_start_s_ = 0.0, stream_rate_hz_ = 0.0;
  std::uint64_t stream_next_ = 0;
};

}  // namespace mtcal::mocks
