#include "mtcal/processing/est.h"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <numbers>
#include <random>

#include "mtcal/error.h"

// Two-, three-probe and frequency-domain error separation against simulated probe readings,
// the paper's simulation (Zhang & Wang, Machine Tool & Hydraulics 38(3), 2010, section 3:
// L = 400 mm, step 20 mm) and its error analysis (eqs. 7-8, 16; section 2.4).
namespace mtcal::processing {
namespace {

constexpr double kArcsecRad = std::numbers::pi / (180.0 * 3600.0);

struct Guideway {
  std::vector<double> x_mm;
  std::vector<double> s_um;  ///< profile, one sample further than the carriage positions per step of spacing
  std::vector<double> r_um, gamma_rad;
};

/// n carriage positions every step_mm; the profile known `extra` samples further.
Guideway guideway(std::size_t n, double step_mm, std::size_t extra, bool carriage_at_rest_first = true) {
  Guideway g;
  std::mt19937 rng(11);
  std::normal_distribution<double> wobble(0.0, 0.8);
  for (std::size_t k = 0; k < n + extra; ++k) {
    const double x = step_mm * static_cast<double>(k);
    g.s_um.push_back(1.5 + 4.0 * std::sin(2 * std::numbers::pi * x / 400.0) + 2e-5 * x * x - 0.6 * std::cos(x / 37.0));
  }
  for (std::size_t k = 0; k < n; ++k) {
    g.x_mm.push_back(step_mm * static_cast<double>(k));
    g.r_um.push_back(carriage_at_rest_first && k == 0 ? 0.0 : wobble(rng));
    g.gamma_rad.push_back(2.0 * kArcsecRad * std::sin(0.3 * static_cast<double>(k)) + 0.5 * kArcsecRad);
  }
  return g;
}

/// V_i(k) = S(k + i m) + R(k) - i spacing gamma(k) + zero_i (with_yaw), um.
std::vector<double> probe(const Guideway& g, int i, int m, double spacing_mm, bool with_yaw, double zero_um = 0.0) {
  std::vector<double> v;
  for (std::size_t k = 0; k < g.x_mm.size(); ++k) {
    v.push_back(g.s_um[k + static_cast<std::size_t>(i * m)] + g.r_um[k] -
                (with_yaw ? i * spacing_mm * 1000.0 * g.gamma_rad[k] : 0.0) + zero_um);
  }
  return v;
}

// Paper, section 3 (figs. 5 and 6): with R(0) = 0, S(0) = V1(0), S(1) = V2(0) the separated
// profile and carriage motion coincide with the simulated ones; with only S(1) = V2(0) the
// profile comes out shifted.
TEST(Est, ReproducesThePaperSimulation) {
  const auto g = guideway(21, 20.0, 1);  // L = 400 mm, step = spacing = 20 mm
  const auto v1 = probe(g, 0, 1, 20.0, false), v2 = probe(g, 1, 1, 20.0, false);
  const auto full = separateTwoProbe(g.x_mm, v1, v2, 20.0, EstStart::kCarriageAtRest);
  for (std::size_t k = 0; k < g.x_mm.size(); ++k) {
    EXPECT_NEAR(full.profile_um[k], g.s_um[k], 1e-12) << k;
    EXPECT_NEAR(full.carriage_um[k], g.r_um[k], 1e-12) << k;
  }
  // Second-point start, by hand: S(0) is set to 0 and S(1) = V2(0) = S(1) + R(0) = S(1)
  // (the carriage at rest, R(0) = 0); the recursion S(k + 1) = S(k) + V2(k) - V1(k) adds the
  // true S(k + 1) - S(k), so every point from k = 1 on is the true profile and only the first
  // one is off, by the true S(0) = 1.5 + 4 sin 0 + 0 - 0.6 cos 0 = 0.9 um. The carriage
  // R(k) = V1(k) - S(k) is true from k = 1 on and R(0) = V1(0) - 0 = S(0) = 0.9 um.
  // Referenced to their first points, the curves therefore differ by 0.9 um everywhere.
  const auto second = separateTwoProbe(g.x_mm, v1, v2, 20.0, EstStart::kSecondPointOnly);
  EXPECT_EQ(second.profile_um[0], 0.0);
  EXPECT_NEAR(second.carriage_um[0], 0.9, 1e-12);
  for (std::size_t k = 1; k < g.x_mm.size(); ++k) {
    EXPECT_NEAR(second.profile_um[k], g.s_um[k], 1e-12) << k;
    EXPECT_NEAR(second.carriage_um[k], g.r_um[k], 1e-12) << k;
    EXPECT_NEAR((second.profile_um[k] - second.profile_um[0]) - (g.s_um[k] - g.s_um[0]), 0.9, 1e-12) << k;
  }
}

// The generalised method: spacing = m steps (here 3), the carriage at rest over the first m.
TEST(Est, GeneralisedStepRecoversTheProfile) {
  auto g = guideway(40, 5.0, 3);
  for (std::size_t k = 0; k < 3; ++k) g.r_um[k] = 0.0;
  const auto r = separateTwoProbe(g.x_mm, probe(g, 0, 3, 15.0, false), probe(g, 1, 3, 15.0, false), 15.0,
                                  EstStart::kCarriageAtRest);
  for (std::size_t k = 0; k < g.x_mm.size(); ++k) EXPECT_NEAR(r.profile_um[k], g.s_um[k], 1e-12) << k;
  EXPECT_THROW(separateTwoProbe(g.x_mm, probe(g, 0, 3, 15.0, false), probe(g, 1, 3, 15.0, false), 12.0,
                                EstStart::kCarriageAtRest),
               InputError);  // not a whole number of steps
}

// Paper, eqs. 7-8: a probe alignment (zero) offset adds n * delta, a line: the straightness
// evaluated against the least-squares line, the minimum zone or the end points is unchanged.
TEST(Est, AZeroOffsetIsALineAndLeavesStraightnessUnchanged) {
  const auto g = guideway(21, 20.0, 1);
  const auto v1 = probe(g, 0, 1, 20.0, false);
  const auto clean = separateTwoProbe(g.x_mm, v1, probe(g, 1, 1, 20.0, false), 20.0, EstStart::kCarriageAtRest);
  const auto offset = separateTwoProbe(g.x_mm, v1, probe(g, 1, 1, 20.0, false, 0.7), 20.0, EstStart::kCarriageAtRest);
  for (std::size_t k = 0; k < g.x_mm.size(); ++k) {
    EXPECT_NEAR(offset.profile_um[k] - clean.profile_um[k], 0.7 * static_cast<double>(k), 1e-12);
  }
  const auto a = evaluateStraightness(clean.x_mm, clean.profile_um);
  const auto b = evaluateStraightness(offset.x_mm, offset.profile_um);
  EXPECT_NEAR(a.least_squares_um, b.least_squares_um, 1e-9);
  EXPECT_NEAR(a.min_zone_um, b.min_zone_um, 1e-9);
  EXPECT_NEAR(a.end_point_um, b.end_point_um, 1e-9);
  EXPECT_GT(a.least_squares_um, 1.0);
}

// Paper, eq. 16 and section 2.2.1: ignoring the yaw accumulates -spacing * sum(gamma); 1 arcsec
// at 15 mm is 0.0727 um per step.
TEST(Est, IgnoredYawAccumulates) {
  EXPECT_NEAR(ignoredYawError({kArcsecRad, 0.0}, 15.0)[1], -0.0727, 5e-5);
  auto g = guideway(30, 15.0, 1);
  const auto r =
      separateTwoProbe(g.x_mm, probe(g, 0, 1, 15.0, true), probe(g, 1, 1, 15.0, true), 15.0, EstStart::kCarriageAtRest);
  const auto delta = ignoredYawError(g.gamma_rad, 15.0);
  for (std::size_t k = 0; k < g.x_mm.size(); ++k) EXPECT_NEAR(r.profile_um[k] - g.s_um[k], delta[k], 1e-12) << k;
  EXPECT_GT(std::abs(delta.back()), 0.5);  // 0.5 arcsec of mean yaw over 29 steps
}

// Three probes: the second difference cancels translation and yaw; the profile comes back
// less the line through its first two points. A zero mismatch c adds c k^2 / 2.
TEST(Est, ThreeProbesCancelTranslationAndYaw) {
  const auto g = guideway(25, 10.0, 2);
  const auto v1 = probe(g, 0, 1, 10.0, true), v2 = probe(g, 1, 1, 10.0, true), v3 = probe(g, 2, 1, 10.0, true);
  const auto r = separateThreeProbe(g.x_mm, v1, v2, v3, 10.0);
  for (std::size_t k = 0; k < g.x_mm.size(); ++k) {
    const double line = g.s_um[0] + (g.s_um[1] - g.s_um[0]) * static_cast<double>(k);
    EXPECT_NEAR(r.profile_um[k], g.s_um[k] - line, 1e-9) << k;
  }
  const double c = 0.05;  // z3 - 2 z2 + z1
  const auto mismatched = separateThreeProbe(g.x_mm, v1, v2, probe(g, 2, 1, 10.0, true, c), 10.0);
  for (std::size_t k = 0; k < g.x_mm.size(); ++k) {
    const double kk = static_cast<double>(k);
    EXPECT_NEAR(mismatched.profile_um[k] - r.profile_um[k], c * kk * (kk - 1.0) / 2.0, 1e-9) << k;
  }
}

// Frequency domain on a periodic profile: recovered up to its first value; with a spacing of
// m steps the harmonics at wavelengths spacing / j are lost, and reported.
TEST(Est, FrequencyMethodLosesTheHarmonicsOfTheSpacing) {
  const std::size_t n = 32;
  const double step = 5.0;
  auto make = [&](bool with_lost) {
    Guideway g;
    for (std::size_t k = 0; k < n + 4; ++k) {
      const double t = 2 * std::numbers::pi * static_cast<double>(k % n) / n;
      g.s_um.push_back(2.0 * std::sin(3 * t) + 0.5 * std::cos(5 * t + 0.2) + (with_lost ? 0.7 * std::sin(8 * t) : 0.0));
    }
    for (std::size_t k = 0; k < n; ++k) {
      g.x_mm.push_back(step * static_cast<double>(k));
      g.r_um.push_back(std::sin(0.7 * static_cast<double>(k)));
      g.gamma_rad.push_back(0.0);
    }
    return g;
  };
  const auto g = make(false);
  const auto one = separateFrequency(g.x_mm, probe(g, 0, 1, step, false), probe(g, 1, 1, step, false), step);
  EXPECT_TRUE(one.lost_wavelengths_mm.empty());
  for (std::size_t k = 0; k < n; ++k) EXPECT_NEAR(one.profile_um[k], g.s_um[k] - g.s_um[0], 1e-9) << k;
  // Spacing 4 steps (20 mm) over 32: f = 8 and 16 are lost, wavelengths 20 and 10 mm.
  const auto lossy = make(true);
  const auto four =
      separateFrequency(lossy.x_mm, probe(lossy, 0, 4, 20.0, false), probe(lossy, 1, 4, 20.0, false), 20.0);
  ASSERT_EQ(four.lost_wavelengths_mm.size(), 2u);
  EXPECT_NEAR(four.lost_wavelengths_mm[0], 20.0, 1e-9);
  EXPECT_NEAR(four.lost_wavelengths_mm[1], 10.0, 1e-9);
  for (std::size_t k = 0; k < n; ++k) {
    const double t = 2 * std::numbers::pi * static_cast<double>(k) / n;
    const double lost = 0.7 * std::sin(8 * t);
    EXPECT_NEAR(four.profile_um[k], (lossy.s_um[k] - lost) - (lossy.s_um[0] - 0.0), 1e-9) << k;
  }
}

// The minimum zone is exact: no slope gives a narrower strip (checked on a fine slope grid),
// and it is never wider than the least-squares or end-point evaluation.
TEST(Est, MinimumZoneIsTheNarrowestStrip) {
  // A zigzag: the best strip is horizontal, 1 um wide.
  const auto zig = evaluateStraightness({0, 1, 2, 3, 4}, {0, 1, 0, 1, 0});
  EXPECT_NEAR(zig.min_zone_um, 1.0, 1e-12);
  EXPECT_NEAR(zig.min_zone_slope_um_per_mm, 0.0, 1e-12);
  std::mt19937 rng(4);
  std::normal_distribution<double> noise(0.0, 1.0);
  for (int trial = 0; trial < 20; ++trial) {
    std::vector<double> x, y;
    for (int k = 0; k < 30; ++k) {
      x.push_back(10.0 * k);
      y.push_back(0.01 * k * k + noise(rng));
    }
    const auto s = evaluateStraightness(x, y);
    double brute = std::numeric_limits<double>::infinity();
    for (double slope = -0.2; slope <= 0.6; slope += 1e-6) {
      double lo = 1e9, hi = -1e9;
      for (std::size_t k = 0; k < x.size(); ++k) {
        lo = std::min(lo, y[k] - slope * x[k]);
        hi = std::max(hi, y[k] - slope * x[k]);
      }
      brute = std::min(brute, hi - lo);
    }
    EXPECT_LE(s.min_zone_um, brute + 1e-12);
    EXPECT_NEAR(s.min_zone_um, brute, 3e-4);  // the grid's resolution: 1e-6 um/mm x 290 mm
    EXPECT_LE(s.min_zone_um, s.least_squares_um + 1e-12);
    EXPECT_LE(s.min_zone_um, s.end_point_um + 1e-12);
  }
}

// Paper, section 2.4: sensor accuracy 5, sensor measurement 1.2, repeatability 2.37,
// ignored yaw 0.1, step error 3 um: total 11.67 um as the paper's sum. As independent
// standard uncertainties (GUM) sqrt(41.0669) = 6.408 um, and a normal sum holds 95 % within
// 1.960 x 6.408 = 12.56 um; as bounds of rectangular distributions 6.408 / sqrt(3) = 3.700 um.
TEST(Est, BudgetAsThePapersSumRootSumSquareAndMonteCarlo) {
  std::vector<BudgetItem> items{{"sensor accuracy", 5.0},
                                {"sensor measurement", 1.2},
                                {"repeatability", 2.37},
                                {"ignored yaw", 0.1},
                                {"step error", 3.0}};
  auto b = combineBudget(items);
  EXPECT_NEAR(b.linear_sum_um, 11.67, 1e-12);
  EXPECT_NEAR(b.root_sum_square_um, std::sqrt(41.0669), 1e-12);
  EXPECT_NEAR(b.monte_carlo_sigma_um, b.root_sum_square_um, 0.01 * b.root_sum_square_um);
  EXPECT_NEAR(b.monte_carlo_95_um, 1.959964 * b.root_sum_square_um, 0.02 * b.root_sum_square_um);
  for (auto& item : items) item.bound = true;
  b = combineBudget(items);
  EXPECT_NEAR(b.root_sum_square_um, std::sqrt(41.0669 / 3.0), 1e-12);
  EXPECT_NEAR(b.monte_carlo_sigma_um, b.root_sum_square_um, 0.01 * b.root_sum_square_um);
  EXPECT_LT(b.monte_carlo_95_um, b.linear_sum_um);  // the worst case is never approached
}

/// Two-probe readings of the guideway g with probe 2 at spacing + delta_l and every step
/// delta_p longer than planned (accumulating), from the profile function itself.
std::pair<std::vector<double>, std::vector<double>> misplacedProbes(const std::vector<double>& x, double spacing,
                                                                    double delta_l, double delta_p,
                                                                    const std::function<double(double)>& s) {
  std::vector<double> v1, v2;
  for (std::size_t k = 0; k < x.size(); ++k) {
    const double shift = static_cast<double>(k) * delta_p;
    v1.push_back(s(x[k] + shift));
    v2.push_back(s(x[k] + spacing + delta_l + shift));
  }
  return {v1, v2};
}

// Paper, eqs. 9-10 and 17-19, checked by simulation: the first-order estimates of the spacing
// and step errors against the separation of readings taken with the probes misplaced.
TEST(Est, SpacingAndStepErrorsMatchTheirFirstOrderEstimates) {
  const auto profile = [](double x) { return 3.0 * std::sin(2 * std::numbers::pi * x / 400.0) + 2e-5 * x * x; };
  std::vector<double> x, s;
  for (int k = 0; k <= 20; ++k) {
    x.push_back(20.0 * k);
    s.push_back(profile(x.back()));
  }
  const auto separated = [&](double dl, double dp) {
    const auto [v1, v2] = misplacedProbes(x, 20.0, dl, dp, profile);
    return separateTwoProbe(x, v1, v2, 20.0, EstStart::kCarriageAtRest).profile_um;
  };
  const auto clean = separated(0.0, 0.0);
  const auto spacing = separated(0.5, 0.0);  // the paper's example: a tenth of a 5 mm probe tip
  const auto spacing_estimate = spacingErrorUm(x, s, 0.5);
  const auto step = separated(0.0, 0.003);  // the paper's limit: 3 um per step
  const auto step_estimate = stepErrorUm(x, s, 0.003);
  double spacing_max = 0.0;
  for (std::size_t k = 0; k < x.size(); ++k) {
    EXPECT_NEAR(spacing[k] - clean[k], spacing_estimate[k], 0.01) << k;
    EXPECT_NEAR(step[k] - clean[k], step_estimate[k], 0.002) << k;
    spacing_max = std::max(spacing_max, std::abs(spacing_estimate[k]));
  }
  // The paper calls a 0.5 mm spacing error negligible: here 0.08 um over 400 mm, not zero.
  EXPECT_GT(spacing_max, 0.05);
  EXPECT_LT(spacing_max, 0.1);
}

// Noise propagation, checked by Monte Carlo over 400 seeded repetitions of a 21-point run.
TEST(Est, NoisePropagationMatchesMonteCarlo) {
  std::vector<double> x;
  for (int k = 0; k <= 20; ++k) x.push_back(10.0 * k);
  std::mt19937 rng(21);
  std::normal_distribution<double> noise(0.0, 0.1);
  double ss2 = 0.0, ss3 = 0.0;
  const int runs = 400;
  for (int r = 0; r < runs; ++r) {
    std::vector<double> v1, v2, v3;
    for (std::size_t k = 0; k < x.size(); ++k) {
      v1.push_back(noise(rng));
      v2.push_back(noise(rng));
      v3.push_back(noise(rng));
    }
    ss2 += std::pow(separateTwoProbe(x, v1, v2, 10.0, EstStart::kCarriageAtRest).profile_um[20], 2);
    ss3 += std::pow(separateThreeProbe(x, v1, v2, v3, 10.0).profile_um[20], 2);
  }
  // 400 draws: the sample sigma is within 10 % of the truth with 95 % confidence or better.
  EXPECT_NEAR(std::sqrt(ss2 / runs), twoProbeNoiseUm(20, 0.1), 0.1 * twoProbeNoiseUm(20, 0.1));
  EXPECT_NEAR(std::sqrt(ss3 / runs), threeProbeNoiseUm(20, 0.1), 0.1 * threeProbeNoiseUm(20, 0.1));
  EXPECT_GT(threeProbeNoiseUm(20, 0.1), 10 * twoProbeNoiseUm(20, 0.1));  // 12.2 vs 0.64 um
}

}  // namespace
}  // namespace mtcal::processing
