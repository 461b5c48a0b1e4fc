#include "mtcal/processing/iso230_4.h"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <numbers>
#include <random>

#include "mtcal/error.h"
#include "mtcal/processing/contour_path.h"

namespace mtcal::processing {
namespace {

constexpr double kPi = std::numbers::pi;

// Gander, Golub & Strebel, "Least-squares fitting of circles and ellipses", BIT 34 (1994),
// the geometric fit of their six points: centre (4.739782, 2.983533), radius 4.714226 (their
// section 3 example); the rms orthogonal residual of that circle, sqrt(sum (|p - c| - r)^2 / 6),
// 0.452327.
TEST(CircleFit, GanderGolubStrebelGeometricFit) {
  const std::vector<Eigen::Vector2d> p{{1, 7}, {2, 6}, {5, 8}, {7, 7}, {9, 5}, {3, 7}};
  const CircleFit fit = fitCircle(p);
  EXPECT_NEAR(fit.centre.x(), 4.739782, 1e-6);
  EXPECT_NEAR(fit.centre.y(), 2.983533, 1e-6);
  EXPECT_NEAR(fit.radius, 4.714226, 1e-6);
  EXPECT_NEAR(fit.rms_residual, 0.452327, 1e-6);
  EXPECT_THROW(fitCircle({{0, 0}, {1, 1}, {2, 2}, {3, 3}}), InputError);
  EXPECT_THROW(fitCircle({{0, 0}, {1, 1}}), InputError);
}

// The angle of sample i of a direction: both directions start at 0 deg, CCW running up
// from 0, CW down from 360.
double angleOf(CircleDirection d, int i, int n) {
  return 2.0 * kPi * (d == CircleDirection::kCcw ? i + 0.5 : n - i - 0.5) / n;
}

// Lost motion b (um) of one axis by the play operator over the samples in time order: the
// table stays put until the motor has crossed the play (one turn run first to set it).
std::vector<double> playErrorsUm(double radius_mm, CircleDirection d, int axis, double b_um, int n) {
  std::vector<double> out;
  double table_mm = 0.0;
  for (int turn = 0; turn < 2; ++turn) {
    for (int i = 0; i < n; ++i) {
      const double t = angleOf(d, i, n);
      const double motor_mm = radius_mm * (axis == 0 ? std::cos(t) : std::sin(t));
      if (turn == 0 && i == 0) table_mm = motor_mm;
      table_mm = std::clamp(table_mm, motor_mm - b_um / 2000.0, motor_mm + b_um / 2000.0);
      if (turn == 1) out.push_back((table_mm - motor_mm) * 1000.0);
    }
  }
  return out;
}

// A path made by a given tool-point error function e(commanded point, direction, angle,
// sample index), reported the way a ballbar does: the radial deviation |p + e| - R, exactly.
std::vector<CirclePoint> measure(
    double radius_mm, int points_per_direction,
    const std::function<Eigen::Vector2d(const Eigen::Vector2d&, CircleDirection, double, int)>& error_um,
    double noise_um = 0.0, std::uint64_t seed = 1) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal(0.0, noise_um > 0.0 ? noise_um : 1.0);
  std::vector<CirclePoint> out;
  for (CircleDirection d : {CircleDirection::kCcw, CircleDirection::kCw}) {
    for (int i = 0; i < points_per_direction; ++i) {
      const double t = angleOf(d, i, points_per_direction);
      const Eigen::Vector2d p = radius_mm * Eigen::Vector2d(std::cos(t), std::sin(t));
      const Eigen::Vector2d actual = p + error_um(p, d, t, i) / 1000.0;
      out.push_back({d, t, (actual.norm() - radius_mm) * 1000.0 + (noise_um > 0.0 ? normal(rng) : 0.0)});
    }
  }
  return out;
}

TEST(CircularTest, AnOffsetCircleGivesItsCentreAndRadiusAndNoCircularDeviation) {
  const Eigen::Vector2d centre_um(3.0, -2.0);
  const auto points =
      measure(100.0, 720, [&](const Eigen::Vector2d& p, CircleDirection, double, int) -> Eigen::Vector2d {
        return centre_um + 1.5 * p.normalized();  // circle of radius R + 1.5 um about (3, -2) um
      });
  // A ballbar sees only lengths: the tangential part of the offset (3.6 um at most) is lost,
  // which bends the reconstructed path by its square over 2R, 6.5e-5 um here.
  constexpr double kSecondOrderUm = 2e-4;
  const CircularTestResult r = evaluateCircularTest(100.0, points);
  ASSERT_TRUE(r.ccw && r.cw && r.g_b_um && r.h_um);
  EXPECT_NEAR(r.ccw->centre_first_um, 3.0, kSecondOrderUm);
  EXPECT_NEAR(r.ccw->centre_second_um, -2.0, kSecondOrderUm);
  EXPECT_NEAR(r.cw->radius_deviation_um, 1.5, kSecondOrderUm);
  EXPECT_NEAR(r.ccw->g_um, 0.0, kSecondOrderUm);
  EXPECT_NEAR(*r.g_b_um, 0.0, kSecondOrderUm);
  EXPECT_NEAR(*r.h_um, 0.0, kSecondOrderUm);
  EXPECT_NEAR(r.ccw->angle_span_deg, 359.5, 1e-9);
}

TEST(CircularTest, GAndHOfClosedFormPaths) {
  // CCW: radial deviation +4 sin 2t, CW: -4 sin 2t (a servo mismatch): each path's G is
  // 8 um, both together 8 um, and at 45 deg they differ by 8 um: H = 8 um.
  std::vector<CirclePoint> points;
  for (int i = 0; i < 3600; ++i) {
    const double t = 2.0 * kPi * i / 3600.0;
    points.push_back({CircleDirection::kCcw, t, 4.0 * std::sin(2.0 * t)});
    points.push_back({CircleDirection::kCw, t, -4.0 * std::sin(2.0 * t)});
  }
  const CircularTestResult r = evaluateCircularTest(150.0, points);
  EXPECT_NEAR(r.ccw->g_um, 8.0, 1e-3);
  EXPECT_NEAR(r.cw->g_um, 8.0, 1e-3);
  EXPECT_NEAR(*r.g_b_um, 8.0, 1e-3);
  EXPECT_NEAR(*r.h_um, 8.0, 1e-3);
  // One direction only: no bidirectional figures.
  points.erase(
      std::remove_if(points.begin(), points.end(), [](const auto& p) { return p.direction == CircleDirection::kCw; }),
      points.end());
  const CircularTestResult one = evaluateCircularTest(150.0, points);
  EXPECT_FALSE(one.cw);
  EXPECT_FALSE(one.g_b_um);
  EXPECT_FALSE(one.h_um);
  EXPECT_THROW(evaluateCircularTest(0.0, points), InputError);
}

// Signatures from the physics, not from the diagnosis' own basis.
constexpr double kR = 100.0;
constexpr double kFeed = 1000.0;  // mm/min

TEST(BallbarDiagnosis, SquarenessOfTwentyMicroradiansIsOneMicrometreAt100mm) {
  // Closed form: an x error alpha y moves the point radially by alpha x y / R = (alpha R / 2)
  // sin 2t; R = 100 mm, alpha = 20 urad -> +-1 um, the same in both directions.
  const auto points = measure(
      kR, 3600,
      [](const Eigen::Vector2d& p, CircleDirection, double, int) {
        return Eigen::Vector2d(20e-6 * p.y() * 1000.0, 0.0);  // x error = alpha y (um)
      },
      0.05);
  double peak = 0.0;
  for (const auto& p : points) peak = std::max(peak, std::abs(p.deviation_um));
  EXPECT_NEAR(peak, 1.0, 0.2);
  const auto d = diagnoseBallbar(kR, points, {kFeed, true, 6.0});
  ASSERT_TRUE(d.squareness_urad);
  EXPECT_NEAR(*d.squareness_urad, -20.0, 0.5);  // +Y leans toward +X: the angle is 90 deg - 20 urad
  EXPECT_FALSE(d.servo_mismatch_ms);
  EXPECT_FALSE(d.backlash_first_um);
  EXPECT_FALSE(d.cyclic_amplitude_um);
  EXPECT_LT(d.rms_after_um, 0.06);
}

TEST(BallbarDiagnosis, ServoMismatchOfOneMillisecondFlipsSignWithDirection) {
  // Reference: +-(F dtau / 2) sin 2t, F = 1000 mm/min, dtau = 1 ms -> +-8.3 um.
  const double omega = kFeed / 60.0 / kR;
  const double tau_x = 0.030, tau_y = 0.029;
  auto lag = [&](const Eigen::Vector2d& p, CircleDirection d, double t, int) -> Eigen::Vector2d {
    const double s = static_cast<int>(d);
    const Eigen::Vector2d lagged(kR * std::cos(t - s * omega * tau_x), kR * std::sin(t - s * omega * tau_y));
    return (lagged - p) * 1000.0;
  };
  // H compares the two paths angle by angle: noise-free here (H is a maximum, noise adds to it).
  const auto r = evaluateCircularTest(kR, measure(kR, 3600, lag));
  EXPECT_NEAR(*r.h_um, 2 * 8.333, 0.01);
  const auto points = measure(kR, 3600, lag, 0.05);
  const auto d = diagnoseBallbar(kR, points, {kFeed, false, 6.0});
  ASSERT_TRUE(d.servo_mismatch_ms);
  EXPECT_NEAR(*d.servo_mismatch_ms, 1.0, 0.02);
  EXPECT_FALSE(d.squareness_urad);
}

TEST(BallbarDiagnosis, ScaleBacklashSpikesAndACyclicErrorEachAloneAndTogether) {
  const double omega = kFeed / 60.0 / kR;
  auto scale = [](const Eigen::Vector2d& p) -> Eigen::Vector2d {
    return Eigen::Vector2d(8e-6 * p.x(), -5e-6 * p.y()) * 1000.0;
  };
  const std::vector<double> play_x_ccw = playErrorsUm(kR, CircleDirection::kCcw, 0, 3.0, 3600);
  const std::vector<double> play_x_cw = playErrorsUm(kR, CircleDirection::kCw, 0, 3.0, 3600);
  const std::vector<double> play_y_ccw = playErrorsUm(kR, CircleDirection::kCcw, 1, 1.6, 3600);
  const std::vector<double> play_y_cw = playErrorsUm(kR, CircleDirection::kCw, 1, 1.6, 3600);
  auto backlash = [&](CircleDirection d, int i) -> Eigen::Vector2d {
    const bool ccw = d == CircleDirection::kCcw;
    return {(ccw ? play_x_ccw : play_x_cw)[static_cast<std::size_t>(i)],
            (ccw ? play_y_ccw : play_y_cw)[static_cast<std::size_t>(i)]};
  };
  auto cyclic = [](const Eigen::Vector2d& p) -> Eigen::Vector2d {
    return Eigen::Vector2d(0.8 * std::sin(2 * kPi * p.x() / 10.0 + 0.3), 0.0);
  };
  auto spikes = [&](double t, CircleDirection d) -> Eigen::Vector2d {
    // X reverses at 0 and 180 deg, Y at 90 and 270: lag in the new direction, 2.5 um decaying in 20 ms.
    const double s = static_cast<int>(d);
    Eigen::Vector2d e = Eigen::Vector2d::Zero();
    for (double r : {0.0, kPi}) {
      double since = std::fmod(s * (t - r) + 4 * kPi, 2 * kPi) / omega;
      e.x() += 2.5 * std::exp(-since / 0.02) * std::cos(r);
    }
    return e;
  };
  {
    const auto d = diagnoseBallbar(kR,
                                   measure(
                                       kR, 3600, [&](auto& p, auto, auto, int) { return scale(p); }, 0.05),
                                   {kFeed, true, 6.0});
    ASSERT_TRUE(d.scale_mismatch_first_ppm && d.scale_mismatch_second_ppm);
    EXPECT_NEAR(*d.scale_mismatch_first_ppm, 8.0, 0.1);
    EXPECT_NEAR(*d.scale_mismatch_second_ppm, -5.0, 0.1);
    EXPECT_FALSE(d.squareness_urad);
  }
  {
    const auto d = diagnoseBallbar(kR,
                                   measure(
                                       kR, 3600, [&](auto&, auto dir, auto, int i) { return backlash(dir, i); }, 0.05),
                                   {kFeed, true, 6.0});
    ASSERT_TRUE(d.backlash_first_um && d.backlash_second_um);
    EXPECT_NEAR(*d.backlash_first_um, 3.0, 0.05);
    EXPECT_NEAR(*d.backlash_second_um, 1.6, 0.05);
    EXPECT_FALSE(d.servo_mismatch_ms);
  }
  {
    const auto d = diagnoseBallbar(kR,
                                   measure(
                                       kR, 3600, [&](auto& p, auto, auto, int) { return cyclic(p); }, 0.05),
                                   {kFeed, true, 6.0});
    ASSERT_TRUE(d.cyclic_amplitude_um && d.cyclic_period_mm);
    EXPECT_EQ(d.cyclic_axis, 0);
    EXPECT_NEAR(*d.cyclic_period_mm, 10.0, 0.1);
    EXPECT_NEAR(*d.cyclic_amplitude_um, 0.8, 0.08);
  }
  {
    const auto d = diagnoseBallbar(kR,
                                   measure(
                                       kR, 3600, [&](auto&, auto dir, double t, int) { return spikes(t, dir); }, 0.05),
                                   {kFeed, true, 6.0});
    ASSERT_TRUE(d.reversal_spike_first_um);
    EXPECT_NEAR(*d.reversal_spike_first_um, 2.5, 0.15);
    EXPECT_FALSE(d.reversal_spike_second_um);
  }
  // All together with squareness 15 urad.
  const auto all = measure(
      kR, 3600,
      [&](const Eigen::Vector2d& p, CircleDirection dir, double t, int i) {
        return Eigen::Vector2d(scale(p) + backlash(dir, i) + cyclic(p) + spikes(t, dir) +
                               Eigen::Vector2d(15e-6 * p.y() * 1000.0, 0.0));
      },
      0.1, 7);
  const auto d = diagnoseBallbar(kR, all, {kFeed, true, 6.0});
  ASSERT_TRUE(d.squareness_urad && d.scale_mismatch_first_ppm && d.backlash_first_um && d.backlash_second_um &&
              d.cyclic_period_mm && d.reversal_spike_first_um);
  EXPECT_NEAR(*d.squareness_urad, -15.0, 0.5);
  EXPECT_NEAR(*d.scale_mismatch_first_ppm, 8.0, 0.2);
  EXPECT_NEAR(*d.scale_mismatch_second_ppm, -5.0, 0.2);
  EXPECT_NEAR(*d.backlash_first_um, 3.0, 0.1);
  EXPECT_NEAR(*d.backlash_second_um, 1.6, 0.1);
  EXPECT_NEAR(*d.cyclic_period_mm, 10.0, 0.1);
  EXPECT_NEAR(*d.reversal_spike_first_um, 2.5, 0.25);
  EXPECT_LT(d.rms_after_um, 0.2);
  EXPECT_GT(d.rms_before_um, 1.0);
}

TEST(BallbarDiagnosis, NoiseAloneNamesNothing) {
  for (std::uint64_t seed = 1; seed <= 5; ++seed) {
    const auto d =
        diagnoseBallbar(kR,
                        measure(
                            kR, 3600, [](auto&, auto, auto, int) { return Eigen::Vector2d(0, 0); }, 0.2, seed),
                        {kFeed, true, 6.0});
    EXPECT_FALSE(d.squareness_urad || d.servo_mismatch_ms || d.scale_mismatch_first_ppm || d.backlash_first_um ||
                 d.backlash_second_um || d.reversal_spike_first_um || d.reversal_spike_second_um ||
                 d.straightness_first_um || d.straightness_second_um || d.cyclic_amplitude_um)
        << "seed " << seed;
  }
}

TEST(ContourPath, ArcsFollowTheGCodeSenseInEachPlane) {
  // G3 in G17 from (10, 0) about the origin: a quarter turn reaches (0, 10).
  ContourPath xy(Eigen::Vector3d(10, 0, 5));
  xy.arc(Eigen::Vector3d(0, 0, 5), Plane::kXY, kPi / 2, 600.0);
  EXPECT_NEAR((xy.end() - Eigen::Vector3d(0, 10, 5)).norm(), 0.0, 1e-12);
  EXPECT_NEAR(xy.durationS(), 10 * kPi / 2 / 10.0, 1e-12);  // 15.7 mm at 10 mm/s
  // G18 (ZX): counter-clockwise seen from +Y runs from +Z toward +X.
  ContourPath zx(Eigen::Vector3d(0, 0, 10));
  zx.arc(Eigen::Vector3d(0, 0, 0), Plane::kZX, kPi / 2, 600.0);
  EXPECT_NEAR((zx.end() - Eigen::Vector3d(10, 0, 0)).norm(), 0.0, 1e-12);
  // G19 (YZ): from +Y toward +Z.
  ContourPath yz(Eigen::Vector3d(0, 10, 0));
  yz.arc(Eigen::Vector3d(0, 0, 0), Plane::kYZ, kPi / 2, 600.0).lineTo(Eigen::Vector3d(0, 0, 0), 600.0);
  EXPECT_NEAR((yz.positionAt(10 * kPi / 2 / 10.0) - Eigen::Vector3d(0, 0, 10)).norm(), 0.0, 1e-12);
  EXPECT_NEAR((yz.positionAt(1e9) - Eigen::Vector3d(0, 0, 0)).norm(), 0.0, 1e-12);
  EXPECT_THROW(ContourPath(Eigen::Vector3d(0, 0, 1)).arc(Eigen::Vector3d(0, 0, 0), Plane::kXY, 1.0, 100.0), InputError);
  EXPECT_THROW(ContourPath(Eigen::Vector3d(1, 0, 0)).lineTo(Eigen::Vector3d(2, 0, 0), 0.0), InputError);
}

}  // namespace
}  // namespace mtcal::processing
