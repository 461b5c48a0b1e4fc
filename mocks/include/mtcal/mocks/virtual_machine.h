#pragma once
// A virtual 3-axis machine tool with known geometric errors, used as the truth that mock
// instruments observe. Units: positions mm, translational errors um, angular errors urad,
// time s of the world clock.
//
// The 21 geometric errors follow ISO 230-1 names (docs/conventions.md): per axis a in
// {X,Y,Z} the positioning error E<a><a>, two straightness errors, and the rotations EA<a>,
// EB<a>, EC<a> about X, Y, Z; plus the squareness errors EC0Y, EB0Z, EA0Z.
//
// Thread-safety: all methods lock; the emulator's reader thread and the scheduler's
// thread use one machine concurrently.

#include <array>
#include <cstdint>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json_fwd.hpp>

#include "mtcal/mocks/world_clock.h"

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

struct AxisModel {
  double min_mm = 0.0, max_mm = 1000.0;
  /// Translations along X, Y, Z (um) and rotations about X, Y, Z (urad), ISO 230-1 order:
  /// for axis X: EXX, EYX, EZX, EAX, EBX, ECX.
  std::array<ErrorCurve, 3> translation_um;
  std::array<ErrorCurve, 3> rotation_urad;
  double backlash_um = 0.0;                ///< lost motion on reversal (half on each side)
  double positioning_sigma_um = 0.0;       ///< scatter of the position reached, per approach
};

struct VirtualMachineConfig {
  std::string name = "virtual-vmc";
  std::uint64_t seed = 1;
  std::array<AxisModel, 3> axes;
  double squareness_c0y_urad = 0.0;  ///< EC0Y: Y axis to X axis
  double squareness_b0z_urad = 0.0;  ///< EB0Z: Z axis to X axis
  double squareness_a0z_urad = 0.0;  ///< EA0Z: Z axis to Y axis
  double settle_time_constant_s = 0.05;  ///< first-order settling after a move
  double feed_mm_per_min = 6000.0;       ///< rapid used to time moves
  double expansion_per_k = 11.5e-6;      ///< scale expansion coefficient
  double material_temp_c = 20.0;         ///< machine (scale) temperature
  double air_temp_c = 20.0, air_pressure_pa = 101325.0, humidity_pct = 50.0;

  /// Reads a machine description (examples/machines/*.json). @throws InputError naming key and why
  static VirtualMachineConfig fromJson(const nlohmann::json& j, const std::string& source);
  /// The machine used by `mtcal demo`: a VMC with realistic error magnitudes.
  static VirtualMachineConfig demo(std::uint64_t seed);
};

class VirtualMachine {
 public:
  VirtualMachine(VirtualMachineConfig config, WorldClock& clock);

  const VirtualMachineConfig& config() const { return config_; }
  WorldClock& clock() { return clock_; }

  /// Commands a move of one axis. Returns the world time at which the axis is in position
  /// (the move takes distance / feed; the settling transient continues after it).
  /// @throws InputError outside the travel.
  double moveTo(Axis axis, double target_mm);

  /// Commanded position of every axis.
  std::array<double, 3> commanded() const;

  /// Displacement (um) along `measured` of a point fixed to the moving carriage of that axis,
  /// offset `offset_mm` from the axis reference point, relative to the ideal commanded
  /// position, at world time t: the error the instrument would see, at 20 degC.
  /// This includes the 6 errors of the axis (Abbe terms from the rotations), backlash,
  /// positioning scatter and the settling transient.
  double pointErrorUm(Axis measured, const std::array<double, 3>& offset_mm, double t_s) const;

  /// Static error (um) of that point with the axis at rest at `position_mm`, approached in
  /// `direction` (+1/-1), without the per-approach scatter: the truth a calibration should find.
  double staticErrorUm(Axis measured, const std::array<double, 3>& offset_mm, double position_mm, int direction) const;

  /// One of the six error components of an axis at world time t (at the commanded position,
  /// interpolated during a move): translations of the offset point (um, components 0..2:
  /// along X, Y, Z, with the Abbe terms) or rotations of the carriage (urad, 3..5: about X,
  /// Y, Z). What straightness and angular optics see.
  double errorComponentAt(Axis axis, int component, const std::array<double, 3>& offset_mm, double t_s) const;

  /// Actual position (mm) of that point along the axis at world time t, including the
  /// thermal expansion of the scale at the machine temperature.
  double actualPositionMm(Axis measured, const std::array<double, 3>& offset_mm, double t_s) const;

  /// Time after a move's in-position time from which the settling transient is exactly
  /// zero (40 time constants: e^-40 is 4e-18 of the move): the position is constant then.
  double settledAfterS() const { return 40.0 * config_.settle_time_constant_s; }

  /// The last move of `axis` started at or before t: its index and in-position time
  /// (index 0 and time 0 before the first move). Keys reproducible noise to the move.
  std::pair<std::uint64_t, double> moveEpoch(Axis axis, double t_s) const;

  /// Number of moves commanded so far.
  std::uint64_t moveCount() const;

 private:
  struct Move {
    std::uint64_t index;
    Axis axis;
    double start_time_s, done_time_s;
    double from_mm, to_mm;
    int direction;            ///< +1 / -1 / 0 (no motion)
    double scatter_um;        ///< realised positioning scatter of this approach
  };
  const Move* lastMoveBefore(Axis axis, double t_s) const;
  /// Ideal (commanded, interpolated during the move) position at t; `move` from lastMoveBefore.
  double nominalPosition(const Move* move, int axis_index, double t_s) const;
  double geometricErrorUm(Axis measured, const std::array<double, 3>& offset_mm, double position_mm) const;
  /// Translation (um) of the offset point by the axis' errors at a position: delta + eps x r.
  std::array<double, 3> pointDisplacementUm(Axis axis, const std::array<double, 3>& offset_mm, double position_mm) const;

  VirtualMachineConfig config_;
  WorldClock& clock_;
  mutable std::mutex mutex_;
  std::array<double, 3> commanded_{};
  std::array<int, 3> last_direction_{{1, 1, 1}};
  std::vector<Move> moves_;
};

}  // namespace mtcal::mocks
