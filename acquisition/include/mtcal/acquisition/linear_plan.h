#pragma once
// The linear positioning plan (ISO 230-2 test cycle): targets, cycles, approach directions,
// capture settings and compensation settings. Loaded from JSON and validated; an error
// names the file, the key and why.

#include <array>
#include <cstdint>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace mtcal::acquisition {

struct LinearPlan {
  std::string name = "linear positioning";
  std::string axis = "X";
  double start_mm = 50.0;
  double end_mm = 600.0;
  double step_mm = 20.0;
  int repeats = 9;  ///< cycles j = 1..n (ISO 230-2 asks for at least 5)
  bool bidirectional = true;
  double overrun_mm = 5.0;  ///< move beyond the end targets before reversing
  double dwell_s = 0.5;     ///< wait after reaching a target before capturing
  double window_s = 0.2;    ///< averaging window of one capture
  std::uint32_t sample_rate_hz = 1000;
  double stability_threshold_um = 1.0;  ///< max s and max drift within a window (urad for angular runs)
  double stability_timeout_s = 5.0;     ///< give up on a target that does not settle
  double random_offset_mm = 0.0;        ///< ISO 230-2 5.3.2: random component of each target
  std::uint64_t random_seed = 1;
  double datum_mm = 50.0;                 ///< machine position at which the laser is zeroed
  double expansion_per_k = 11.5e-6;       ///< of the machine scale / workpiece, for NTC to 20 degC
  std::string air_index_model = "edlen";  ///< edlen | ciddor
  double co2_ppm = 450.0;
  double feed_mm_min = 2000.0;       ///< for the generated part program
  double trigger_timeout_s = 120.0;  ///< triggered runs: longest wait for the machine at a target
  /// ISO 230-1 name of the error measured along the axis: E<a><a> positioning (linear
  /// optics, the default), another translation (straightness optics) or a rotation E[ABC]<a>
  /// (angular optics). Empty means positioning.
  std::string measures;
  std::string gcode_dialect = "iso";  ///< iso (G4 P seconds) | fanuc (G04 X seconds)
  /// The measured line: where the other axes stand during the run (e.g. {"Y": 100, "Z": 50});
  /// axes not named stay where they are. Controlled runs and the part program move them first.
  std::map<std::string, double> line_position_mm;
  /// Where the moving optic (reflector, straightness or angular optic) sits on the tool:
  /// offset from the tool point in mm, in the machine's X, Y, Z. Sets the Abbe arms.
  std::array<double, 3> reflector_offset_mm{};

  /// @throws InputError naming `source`, the key and the reason.
  static LinearPlan fromJson(const nlohmann::json& j, const std::string& source);
  /// Reads and validates a plan file. @throws InputError
  static LinearPlan load(const std::string& path);
  nlohmann::json toJson() const;
  /// The plan of `mtcal demo`: X axis, 50 to 600 mm, a node every 20 mm, 9 repeats, both ways.
  static LinearPlan demo();

  /// Target positions P_i, ascending (the end is included even off the step grid).
  std::vector<double> targetPositions() const;
};

/// A plan's `line_position_mm`: axis names (X, Y, Z) to mm. @throws InputError naming the key
std::map<std::string, double> parseLinePosition(const nlohmann::json& line, const std::string& source);

struct PlannedTarget {
  std::int64_t seq = 0;  ///< 0-based order of capture
  double target_mm = 0.0;
  int direction = 1;  ///< +1 approached upwards, -1 downwards
  int cycle = 1;
};

/// One commanded move of the test cycle; `capture` moves end at a target to measure.
struct PlannedMove {
  double position_mm = 0.0;
  bool capture = false;
  PlannedTarget target;  ///< valid when capture
};

/// The ISO 230-2 linear test cycle: per cycle, all targets upwards after an overrun below the
/// first, then (bidirectional) all downwards after an overrun above the last.
std::vector<PlannedMove> linearMoves(const LinearPlan& plan);
std::vector<PlannedTarget> linearTargets(const LinearPlan& plan);

/// The component a plan measures: 0..2 translation along X, Y, Z, 3..5 rotation about X, Y, Z.
/// @throws InputError when `measures` is not one of the six errors of the plan's axis
int measuredComponent(const LinearPlan& plan);
/// Whether the plan measures the positioning error of its axis (E<a><a>).
bool measuresPositioning(const LinearPlan& plan);
/// The name of the error the plan measures (E<a><a> when `measures` is empty).
std::string measuredError(const LinearPlan& plan);

/// Triggered runs: a reading within this distance of a target (and stable) is the machine
/// holding that target. A quarter of the smallest gap between targets or of the overrun.
double triggerToleranceMm(const LinearPlan& plan);

/// The CNC part program for the plan: the same moves with dwells, for a real machine whose
/// positions are captured by stability triggering.
std::string linearGcode(const LinearPlan& plan);

}  // namespace mtcal::acquisition
