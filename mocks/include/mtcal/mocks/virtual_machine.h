#pragma once
// A virtual 3-axis machine tool with known geometric errors, used as the truth that mock
// instruments observe. Units: positions mm, translational errors um, angular errors urad,
// time s of the world clock.
//
// Its geometry is the multi-body model of processing (MultibodyModel), the same model the
// identification uses: the machine is a kinematic description (the patent CN104200063's
// vertical machining centre unless the machine file gives another) plus a true error
// function for each of its error terms (ISO 230-1 names, docs/conventions.md). What an
// instrument sees is computed by the full homogeneous-transform product: the pose of a point
// fixed to the tool (a reflector) relative to the workpiece side (where the laser stands),
// with every axis at its commanded position. Drive effects (backlash, per-approach scatter,
// settling) act on the positioning error of each axis.
//
// Thread-safety: all methods lock; the emulator's reader thread and the scheduler's
// thread use one machine concurrently.

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <nlohmann/json_fwd.hpp>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "mtcal/mocks/machine_thermal.h"
#include "mtcal/mocks/world_clock.h"
#include "mtcal/processing/compensation.h"
#include "mtcal/processing/contour_path.h"
#include "mtcal/processing/multibody.h"
#include "mtcal/processing/volumetric_compensation.h"

namespace mtcal::mocks {

/// A smooth error function of position: polynomial plus harmonics.
struct ErrorCurve {
  std::vector<double> poly;  ///< c0 + c1 p + c2 p^2 + ..., p in metres of travel (so c_k are um/m^k)
  struct Harmonic {
    double amplitude = 0.0;
    double period_mm = 0.0;
    double phase_rad = 0.0;
  };
  std::vector<Harmonic> harmonics;
  double value(double pos_mm) const;
};

enum class Axis { kX = 0, kY = 1, kZ = 2 };
Axis parseAxis(const std::string& name);  ///< "X"/"x"... @throws InputError
const char* axisName(Axis axis);

/// Travel and drive of one axis.
struct AxisDrive {
  double min_mm = 0.0, max_mm = 1000.0;
  /// Whether the axis can reach `position_mm` (1 nm of rounding allowed).
  bool reaches(double position_mm) const { return position_mm >= min_mm - 1e-9 && position_mm <= max_mm + 1e-9; }
  double backlash_um = 0.0;           ///< lost motion on reversal (half on each side)
  double positioning_sigma_um = 0.0;  ///< scatter of the position reached, per approach
  /// Contouring (followPath) only: position-loop gain (1/s; 0: the axis follows its command
  /// exactly) and the stick at a reversal: the axis lags in its new direction by this much,
  /// decaying with this time constant.
  double kv_per_s = 0.0;
  double reversal_spike_um = 0.0;
  double reversal_spike_decay_s = 0.015;
};

/// A point fixed to the tool body, as an offset (mm, tool frame) from the tool point:
/// where a reflector or a probe is mounted.
using ToolOffset = std::array<double, 3>;

struct VirtualMachineConfig {
  std::string name = "virtual-vmc";
  std::uint64_t seed = 1;
  /// Which session on the machine this is: each draws its own per-approach scatter, the same
  /// session number the same draw (0: the first).
  std::uint64_t session = 0;
  std::array<AxisDrive, 3> axes;
  /// True error functions by ISO 230-1 name: motion errors (um / urad) as functions of their
  /// joint's coordinate, static errors (squareness, urad) as constants (poly[0]). Terms of the
  /// kinematics that are not listed are zero.
  std::map<std::string, ErrorCurve> errors;
  /// Kinematic description (processing::MultibodyModel JSON); empty: the patent's VMC
  /// (examples/machines/vmc3-cn104200063.model.json). Its coordinates must include x, y, z;
  /// any others are rotary axes (degrees), moved with rotateTo. A machine file gives it as an
  /// object or as the name of a model file next to it.
  std::string kinematics_json;
  double settle_time_constant_s = 0.05;  ///< first-order settling after a move
  double feed_mm_per_min = 6000.0;       ///< rapid used to time moves
  double rotary_speed_deg_per_s = 30.0;  ///< rapid of the rotary axes (positioned exactly, no drive error)
  double expansion_per_k = 11.5e-6;      ///< scale expansion coefficient
  double material_temp_c = 20.0;         ///< machine (scale) temperature
  double air_temp_c = 20.0, air_pressure_pa = 101325.0, humidity_pct = 50.0;
  /// The spindle's and structure's thermal behaviour (the machine file's "thermal" object);
  /// none: the machine has no thermal drift.
  std::optional<MachineThermalConfig> thermal;
  /// The controller's compensation table of an axis and how the controller applies it.
  struct AxisCompensation {
    processing::CompensationTable table;
    processing::TableRules rules;
  };
  /// Per axis (X, Y, Z); none: the axis runs uncompensated. The controller adds the table's
  /// correction at the commanded position, for the commanded direction of travel (the last
  /// one at rest), to the axis' command; nothing before the axis' first move.
  std::array<std::optional<AxisCompensation>, 3> compensation;
  /// A volumetric compensation (processing::VolumetricTable): the controller evaluates it at
  /// the commanded position of every axis and adds the correction of the tool point's error
  /// to the linear axes' commands, whatever the direction. None: the machine has none.
  std::optional<processing::VolumetricTable> volumetric;

  /// Reads a machine description (examples/machines/*.json). @throws InputError naming key and why
  static VirtualMachineConfig fromJson(const nlohmann::json& j, const std::string& source);
  /// The machine used by `mtcal demo`: a VMC with realistic error magnitudes.
  static VirtualMachineConfig demo(std::uint64_t seed);
  /// The kinematics this configuration uses. @throws InputError
  processing::MultibodyModel kinematics() const;
  /// The true value of one error term at a joint coordinate (mm or deg); 0 when not listed.
  double trueError(const std::string& name, double coordinate) const;
};

class VirtualMachine {
 public:
  /// @throws InputError when an error name is not a term of the kinematics or the
  ///         kinematics lack an x, y or z coordinate.
  VirtualMachine(VirtualMachineConfig config, WorldClock& clock);

  const VirtualMachineConfig& config() const { return config_; }
  const processing::MultibodyModel& kinematics() const { return model_; }
  WorldClock& clock() { return clock_; }

  /// Commands a move of one axis. Returns the world time at which the axis is in position
  /// (the move takes distance / feed; the settling transient continues after it).
  /// @throws InputError outside the travel.
  double moveTo(Axis axis, double target_mm);

  /// Executes a contouring move (the CNC interpolator's output, every 1 ms) from the axes'
  /// commanded position, which must be the path's start. Each axis follows its command
  /// through a first-order position loop (kv_per_s), its lost motion (a play of backlash_um)
  /// and the stick at each reversal; geometric errors act as everywhere else. The path
  /// starts at the next 0.1 s of world time (so samples of instruments streaming at rates
  /// that divide 1 kHz meet it at the same phase whatever the wall clock did: reproducible).
  /// @return {start, end} world times; at `end` the axes are settled at the path's end.
  /// @throws InputError when the path leaves the travel or does not start where the axes are.
  std::pair<double, double> followPath(const processing::ContourPath& path);

  /// Commands a move of a rotary axis (a coordinate of the kinematics other than x, y, z) to
  /// an angle (deg). Returns the world time at which it is in position (|angle| / rotary
  /// speed); errors are those of the model at the angle, no drive error.
  /// @throws InputError for a coordinate that is not a rotary axis of the machine.
  double rotateTo(const std::string& coordinate, double angle_deg);

  /// Commanded position of every axis.
  std::array<double, 3> commanded() const;
  /// Nominal position of every axis at world time t (interpolated during moves).
  std::array<double, 3> positionsAt(double t_s) const;

  /// Actual minus ideal position (um) of a point on the tool, in the workpiece frame, at
  /// world time t: every error term at the axes' positions (interpolated during moves) plus
  /// backlash, positioning scatter and the settling transient. What straightness optics see.
  Eigen::Vector3d pointErrorUm(const ToolOffset& offset_mm, double t_s) const;

  /// Rotation (urad) of the tool relative to the workpiece at world time t, about X, Y, Z:
  /// what angular optics see.
  Eigen::Vector3d rotationErrorUrad(double t_s) const;

  /// Actual position (mm) of that point along the axis at world time t, including the
  /// thermal expansion of the scales at the machine temperature: what linear optics see.
  double actualPositionMm(Axis measured, const ToolOffset& offset_mm, double t_s) const;

  /// Actual position (mm, workpiece frame) of that point at world time t, scales' expansion
  /// included: what a ballbar or tracker between tool and table sees.
  Eigen::Vector3d actualPointMm(const ToolOffset& offset_mm, double t_s) const;

  /// Static error (um) of that point with axis `moving` at rest at `position_mm`, approached
  /// in `direction` (+1/-1), the other axes at their commanded positions, without the
  /// per-approach scatter: the truth a calibration should find. Along `component` (0..2:
  /// X, Y, Z; -1: along the moving axis itself).
  double staticErrorUm(Axis moving, const ToolOffset& offset_mm, double position_mm, int direction,
                       int component = -1) const;

  /// Time after a move's in-position time from which the settling transient is exactly
  /// zero (40 time constants: e^-40 is 4e-18 of the move): the position is constant then.
  double settledAfterS() const { return 40.0 * config_.settle_time_constant_s; }

  /// The last move (of any axis) started at or before t: its index + 1, and the time from
  /// which the whole machine is in position (every axis' last move by then done; 0 and time
  /// 0 before the first move). Keys reproducible noise to the move; anchoring readings to the
  /// machine's rest, not to the last move's end, makes them independent of how the wall
  /// clock spaced moves issued together.
  std::pair<std::uint64_t, double> moveEpoch(double t_s) const;

  /// Number of moves commanded so far.
  std::uint64_t moveCount() const;

  /// The thermal state (spindle program, temperatures, drift); nullptr when the machine has
  /// none. Its drift moves the tool relative to the table in pointErrorUm and actualPointMm.
  MachineThermal* thermal() const { return thermal_.get(); }

 private:
  struct Move {
    std::uint64_t index;
    Axis axis;
    double start_time_s, done_time_s;
    double machine_done_s;  ///< when every axis' last move so far is in position
    double from_mm, to_mm;
    int direction;      ///< +1 / -1 (the last direction of travel when no motion)
    double scatter_um;  ///< realised positioning scatter of this approach
    int contour = -1;   ///< index in contours_ for a contouring move
    int rotary = -1;    ///< coordinate index of a rotary move (axis unused then)
  };
  /// A contouring move: each axis' position and drive error (lost motion + reversal stick, um)
  /// every dt from start until settled.
  struct Contour {
    double start_s = 0.0, dt_s = 0.001;
    std::vector<std::array<double, 3>> position_mm, drive_um;
  };
  /// Coordinates and error values at world time t (caller holds the lock).
  struct State {
    Eigen::VectorXd q, errors;             ///< errors (with_errors only) include the settling transients
    std::array<double, 3> drive_um{};      ///< each axis' backlash and scatter on its positioning error
    std::array<double, 3> transient_um{};  ///< each axis' settling transient on its positioning error
    std::uint64_t epoch = 0;               ///< index + 1 of the last move started (0: none)
    bool at_rest = true;                   ///< every axis' last move is done: q is constant
  };
  /// A point on the tool with the machine at rest after a move: its position without the
  /// settling transients and how each axis' positioning error moves it (first order; the
  /// transient is at most 0.5 % of a move, its second-order terms below 1e-8 um). Evaluated
  /// once per move and point, so a stream over a settling machine costs no model product per
  /// sample.
  struct RestPoint {
    std::uint64_t epoch = 0;
    ToolOffset offset{};
    bool scaled = false;  ///< q scaled by the scale expansion (linear optics)
    Eigen::Vector3d actual_mm, ideal_mm;
    std::array<Eigen::Vector3d, 3> per_positioning_um;  ///< dP (um) per um of each axis' positioning error
  };
  /// Point position relative to ideal (um) and actual (mm), with the lock held.
  const RestPoint& restPoint(const State& s, const ToolOffset& offset_mm, bool scaled) const;
  Eigen::Vector3d transientUm(const RestPoint& r, const State& s) const;
  State stateAt(double t_s, bool with_errors = true) const;
  /// The last move of any axis started at or before t (nullptr before the first).
  const Move* lastMoveStarted(double t_s) const;
  /// The last move of a rotary coordinate started at or before t (nullptr before the first).
  const Move* lastRotaryMoveBefore(int coordinate, double t_s) const;
  /// Error values of every term with the axes at q, plus `drive_um` on each axis' positioning term.
  Eigen::VectorXd errorsAt(const Eigen::VectorXd& q, const std::array<double, 3>& drive_um) const;
  const Move* lastMoveBefore(Axis axis, double t_s) const;
  Eigen::Vector3d toolPoint(const ToolOffset& offset_mm) const;

  VirtualMachineConfig config_;
  processing::MultibodyModel model_;
  WorldClock& clock_;
  std::array<int, 3> coordinate_of_axis_{};  ///< index in model_.coordinates() of x, y, z
  /// The compensation the controller adds to axis `a`'s command at `position_mm` for
  /// `direction` (+1/-1), um (0 for an uncompensated axis).
  double compensationUm(int a, double position_mm, int direction) const;
  /// Adds the volumetric compensation at the commanded q to each linear axis' drive error.
  void addVolumetric(const Eigen::VectorXd& q, std::array<double, 3>& drive_um) const;
  std::array<int, 3> positioning_term_{};         ///< term index of EXX, EYY, EZZ
  std::vector<const ErrorCurve*> curve_of_term_;  ///< nullptr: zero
  std::vector<int> coordinate_of_term_;           ///< -1 for static terms
  mutable std::mutex mutex_;
  std::array<double, 3> commanded_{};
  std::array<int, 3> last_direction_{{1, 1, 1}};
  std::array<bool, 3> moved_{};  ///< an axis has moved (its compensation applies from then on)
  std::array<double, 3> last_done_s_{};
  double last_rotary_done_s_ = 0.0;
  std::vector<double> rotary_commanded_deg_;  ///< by coordinate index (x, y, z unused)
  std::vector<Move> moves_;
  std::vector<Contour> contours_;
  mutable std::vector<RestPoint> rest_points_;  ///< of the current epoch only
  std::unique_ptr<MachineThermal> thermal_;
  /// The thermal drift at t (um), zero without a thermal state.
  Eigen::Vector3d thermalDriftUm(double t_s) const;
};

}  // namespace mtcal::mocks
