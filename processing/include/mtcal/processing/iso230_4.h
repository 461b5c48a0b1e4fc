#pragma once
// ISO 230-4 circular tests and the ballbar diagnosis of machine errors from them.
// Units: radii mm, deviations um, angles rad inside (deg at the edges), feeds mm/min.
//
// A circular test gives, per direction, the radial deviation of the tool path from the
// nominal circle at angles theta in the plane (measured from its first axis toward the
// second: XY from +X toward +Y). ISO 230-4 figures use the least-squares circle of each path:
//   G   circular deviation: max - min radius about the LSQ centre, per direction;
//   G(b) bidirectional circular deviation: the same over both paths about their common LSQ
//        centre; H  bidirectional circular hysteresis: the largest radial difference of the
//        two paths at the same angle (about that common centre);
//   radius deviation F: LSQ radius - nominal; centre offset: LSQ centre from the nominal one.

#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

namespace mtcal::processing {

/// Geometric (orthogonal distance) least-squares circle: minimises sum (|p_i - c| - r)^2 by
/// Gauss-Newton from the algebraic (Kasa) fit. @throws InputError for < 3 points or
/// collinear points.
struct CircleFit {
  Eigen::Vector2d centre;
  double radius = 0.0;
  double rms_residual = 0.0;  ///< of the orthogonal distances
  int iterations = 0;
};
CircleFit fitCircle(const std::vector<Eigen::Vector2d>& points);

enum class CircleDirection { kCcw = 1, kCw = -1 };
const char* directionName(CircleDirection d);             ///< "ccw" / "cw"
CircleDirection parseDirection(const std::string& text);  ///< "ccw"/"cw" (any case). @throws InputError

struct CirclePoint {
  CircleDirection direction = CircleDirection::kCcw;
  double angle_rad = 0.0;
  double deviation_um = 0.0;  ///< radial, from the nominal radius (+ outward)
};

struct CircularPathResult {
  int points = 0;
  double angle_span_deg = 0.0;                           ///< covered by the points (360 for a full circle)
  double g_um = 0.0;                                     ///< circular deviation
  double radius_deviation_um = 0.0;                      ///< LSQ radius - nominal
  double centre_first_um = 0.0, centre_second_um = 0.0;  ///< LSQ centre, plane axes
  double rms_um = 0.0;                                   ///< of the radial residual about the LSQ circle
};

struct CircularTestResult {
  double radius_mm = 0.0;
  std::optional<CircularPathResult> ccw, cw;
  std::optional<double> g_b_um, h_um;                    ///< need both directions
  double centre_first_um = 0.0, centre_second_um = 0.0;  ///< common LSQ centre (both paths)
};

/// Evaluates one circular test. @throws InputError when a direction has < 3 points or the
/// radius is not > 0.
CircularTestResult evaluateCircularTest(double radius_mm, const std::vector<CirclePoint>& points);

/// What the signature fit found, in the units users know; nullopt: not detected (below the
/// detection threshold or not estimable from the data, e.g. one direction only).
struct BallbarDiagnosis {
  /// The angle between the + directions of the plane's axes minus 90 deg (ISO 230-1 sense,
  /// = EC0Y for XY on the shipped VMC, docs/conventions.md): an error of the first axis'
  /// position a * (second axis position) gives -a.
  std::optional<double> squareness_urad;
  std::optional<double> servo_mismatch_ms;  ///< + : the first axis lags the second by this much
  std::optional<double> scale_mismatch_first_ppm, scale_mismatch_second_ppm;  ///< needs a zeroed (calibrated) bar
  std::optional<double> backlash_first_um, backlash_second_um;                ///< lost motion at each axis' reversal
  std::optional<double> reversal_spike_first_um, reversal_spike_second_um;    ///< peak, outward +
  std::optional<double> straightness_first_um, straightness_second_um;        ///< bow over the circle's diameter
  std::optional<double> cyclic_amplitude_um, cyclic_period_mm;
  int cyclic_axis = -1;            ///< 0 first, 1 second (when a cyclic error is found)
  double rms_before_um = 0.0;      ///< radial deviation about each path's LSQ circle
  double rms_after_um = 0.0;       ///< what the fitted signatures leave
  std::vector<std::string> notes;  ///< assumptions and what could not be separated
};

struct BallbarDiagnosisOptions {
  double feed_mm_per_min = 1000.0;  ///< the test's feed (servo mismatch scales with it)
  bool bar_zeroed = true;           ///< the bar was zeroed in its calibrator: the mean radius is a scale
  double min_t_statistic = 6.0;     ///< a signature must stand this far above its standard error
  /// The angles are timed from the bar's feed-in (a capture from the part program): the axes
  /// reach it late by about their lag, so the reversals do not give the loops' lag, and the
  /// radius it costs is not put back.
  bool timed_from_feed_in = false;
};

/// Fits the signature basis (centre per direction, common radius, squareness, servo
/// mismatch, scale per axis, backlash and reversal spikes per axis, straightness per axis),
/// then searches what is left for a cyclic error of either drive (a least-squares
/// periodogram over periods in the axis position). @throws InputError (no points, radius <= 0)
BallbarDiagnosis diagnoseBallbar(double radius_mm, const std::vector<CirclePoint>& points,
                                 const BallbarDiagnosisOptions& options);

}  // namespace mtcal::processing
