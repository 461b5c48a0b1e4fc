#pragma once
// Error separation technique (EST) for guideway straightness (Zhang & Wang, "Error analysis of
// machine tool guideway straightness measured by EST", Machine Tool & Hydraulics 38(3), 2010,
// and the two- and three-point literature it builds on), and straightness evaluation.
//
// A probe carriage steps along the guideway; probe i (0, 1, 2), mounted at i * spacing along
// it, reads V_i(k) = S(k + i m) + R(k) - (i * spacing) * gamma(k) + zero_i, where S is the
// guideway's profile at the sample points (step = spacing / m), R the carriage's translation
// and gamma its yaw (pitch for a vertical profile), in um and rad; the sign of gamma is the
// paper's (its eqs. 12-16). Separation recovers S without a reference straightedge.
//
// Units: positions mm, readings and profiles um, angles rad. Pure numerics, thread-safe.

#include <cstddef>
#include <string>
#include <vector>

namespace mtcal::processing {

/// How the recursion's first values are fixed.
enum class EstStart {
  /// The carriage's translation is zero at the first m samples (R(j) = 0): S(j) = V1(j);
  /// for m = 1 the paper's eq. 5, R(0) = 0, S(0) = V1(0), S(1) = V2(0).
  kCarriageAtRest,
  /// Only S(1) = V2(0) (m = 1): the profile's first point is taken as its zero, S(0) = 0.
  /// Recovers the profile from the second point on, shifted by the true S(0) (paper, fig. 5).
  kSecondPointOnly,
};

struct EstResult {
  std::vector<double> x_mm;                 ///< sample positions
  std::vector<double> profile_um;           ///< S: the guideway's straightness profile
  std::vector<double> carriage_um;          ///< R: the carriage's translation (two-probe only)
  std::vector<double> lost_wavelengths_mm;  ///< frequency method: harmonics it cannot see
};

/// Whether a step of `step_mm` is the run's even step `first_step_mm` (within a millionth of
/// it, or of 1 mm for steps below 1 mm): probe stepping moves by one step throughout.
bool sameStep(double step_mm, double first_step_mm);

/// Whether probes `spacing_steps` apart fit a line of `points` positions: the second probe
/// must read where the first did at two positions at least, so the spacing is at most
/// points - 2 steps.
bool spacingFitsLine(double spacing_steps, std::size_t points);

/// Two-probe time-domain method: S(k + m) = S(k) + V2(k) - V1(k), R(k) = V1(k) - S(k).
/// `v1_um`, `v2_um` at x_mm (even steps); spacing = m * step.
/// @throws InputError when the sizes differ, the steps are uneven or the spacing is not a
///         whole number of steps (or not one step with kSecondPointOnly)
EstResult separateTwoProbe(const std::vector<double>& x_mm, const std::vector<double>& v1_um,
                           const std::vector<double>& v2_um, double spacing_mm, EstStart start);

/// Three-probe method, probes at 0, spacing, 2 spacing (spacing = one step): the second
/// difference V3 - 2 V2 + V1 = S(k+2) - 2 S(k+1) + S(k) cancels translation and yaw; S is its
/// double sum with S(0) = S(1) = 0 (the line through the first two points is the reference).
/// A zero mismatch c = z3 - 2 z2 + z1 adds c k (k - 1) / 2: a parabola.
EstResult separateThreeProbe(const std::vector<double>& x_mm, const std::vector<double>& v1_um,
                             const std::vector<double>& v2_um, const std::vector<double>& v3_um, double spacing_mm);

/// Frequency-domain two-point method on the differences d(k) = V2(k) - V1(k) (spacing = m
/// steps): the profile over one period of the differences, S(f) = D(f) / (exp(2 pi i f m / n) - 1),
/// its mean slope removed (the periodic model cannot hold one). Harmonics with f m / n whole
/// are lost: their wavelengths are reported (spacing / j for j = 1, 2, ...).
EstResult separateFrequency(const std::vector<double>& x_mm, const std::vector<double>& v1_um,
                            const std::vector<double>& v2_um, double spacing_mm);

/// Straightness of a profile: the width of the zone between two parallel lines containing it.
struct Straightness {
  double least_squares_um = 0.0;  ///< max - min of the residuals from the least-squares line
  double min_zone_um = 0.0;       ///< the minimum zone (exact: the narrowest strip, by convex hull)
  double end_point_um = 0.0;      ///< max - min of the deviations from the line through the end points
  double min_zone_slope_um_per_mm = 0.0;
};
/// @throws InputError for fewer than 2 points or unsorted x
Straightness evaluateStraightness(const std::vector<double>& x_mm, const std::vector<double>& y_um);

/// The error the two-probe method makes when the carriage yaws and the yaw is ignored:
/// delta(n) = -spacing * sum_{i<n} gamma(i) (paper, eq. 16), um for gamma in rad.
std::vector<double> ignoredYawError(const std::vector<double>& gamma_rad, double spacing_mm);

/// First-order error of the two-probe profile when probe 2 sits `delta_l_mm` further than
/// the spacing (paper eqs. 9-10: V2 gains S'(x + l) delta_l): at point k,
/// +sum_{i<k} S'(x_i + l) delta_l with the slope S' taken from `profile_um` (um). Spacing of
/// one step.
std::vector<double> spacingErrorUm(const std::vector<double>& x_mm, const std::vector<double>& profile_um,
                                   double delta_l_mm);

/// First-order error of the two-probe profile when each step is `delta_p_mm` longer than
/// planned, accumulating k delta_p at step k (paper eqs. 17-19: the probes read S at
/// x_k + k delta_p): at point k, sum_{i<k} (S'(x_{i+1}) - S'(x_i)) i delta_p. Spacing of one step.
std::vector<double> stepErrorUm(const std::vector<double>& x_mm, const std::vector<double>& profile_um,
                                double delta_p_mm);

/// Standard deviation (um) at point k of a profile separated from readings with independent
/// noise sigma_um each, new readings at every step: two-probe sigma sqrt(2k + 1) (S(0) from one
/// reading, then a random walk of differences); three-probe sigma sqrt(6 sum_{j<k} j^2) (a
/// double sum of second differences).
double twoProbeNoiseUm(int k, double sigma_um);
double threeProbeNoiseUm(int k, double sigma_um);

/// One contribution of an error budget, um: a bound (the half-width of a rectangular
/// distribution) or a standard uncertainty (normal).
struct BudgetItem {
  std::string name;
  double value_um = 0.0;
  bool bound = false;
};
struct Budget {
  double linear_sum_um = 0.0;         ///< the paper's sum of the contributions (worst case)
  double root_sum_square_um = 0.0;    ///< GUM: sqrt of the sum of the items' variances (bounds as a/sqrt 3)
  double monte_carlo_sigma_um = 0.0;  ///< standard deviation of the simulated sum
  double monte_carlo_95_um = 0.0;     ///< half-width holding 95 % of the simulated sums
};
/// Combines the items three ways; the Monte Carlo draws `samples` sums (seeded).
Budget combineBudget(const std::vector<BudgetItem>& items, int samples = 200000, unsigned seed = 1);

}  // namespace mtcal::processing
