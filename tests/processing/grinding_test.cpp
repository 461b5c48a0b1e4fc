#include "mtcal/processing/grinding.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <numbers>

#include "mtcal/error.h"

namespace mtcal::processing {
namespace {

constexpr double kPi = std::numbers::pi;

MultibodyModel grinder() {
  std::ifstream in(std::string(MTCAL_EXAMPLES_DIR) + "/machines/grinder-xc-mks8332a.model.json");
  return MultibodyModel::fromJson(nlohmann::json::parse(in), "grinder");
}

std::vector<Eigen::Vector2d> circle(double r, int n) {
  std::vector<Eigen::Vector2d> p;
  for (int i = 0; i < n; ++i) p.emplace_back(r * std::cos(2 * kPi * i / n), r * std::sin(2 * kPi * i / n));
  return p;
}

// A cam: base circle 20 mm, a lift of 6 mm over 140 deg (1 - cos) centred at 90 deg.
std::vector<Eigen::Vector2d> cam(int n) {
  std::vector<double> angle, radius;
  for (int i = 0; i < n; ++i) {
    const double a = 360.0 * i / n;
    const double u = (a - 20.0) / 140.0;
    angle.push_back(a);
    radius.push_back(20.0 + (u > 0.0 && u < 1.0 ? 3.0 * (1.0 - std::cos(2 * kPi * u)) : 0.0));
  }
  return polarProfile(angle, radius);
}

TEST(PeriodicSpline, ACircleStaysACircle) {
  // Cubic interpolation of a circle by 72 chords: the radius error is about R (dtheta)^4 / 384
  // = 20 * 0.0873^4 / 384 = 3.0e-6 mm (3.03e-6 seen: the chord-length parameter adds a
  // little), the curvature within 1e-3 of 1/R.
  const PeriodicSpline2d s(circle(20.0, 72));
  for (int k = 0; k < 500; ++k) {
    const double at = s.period() * k / 500.0;
    EXPECT_NEAR(s.at(at).norm(), 20.0, 3.2e-6);
    EXPECT_NEAR(s.curvature(at), 1.0 / 20.0, 1e-3);
  }
  EXPECT_THROW(PeriodicSpline2d({{0, 0}, {1, 0}, {1, 0}, {0, 1}}), InputError);
}

TEST(WheelPath, OffsetsAlongTheOutwardNormalByTheWheelRadius) {
  const auto path = wheelCentrePath(circle(20.0, 90), 150.0, 360);
  ASSERT_EQ(path.size(), 360u);
  for (const auto& w : path) {
    EXPECT_NEAR(w.centre_mm.norm(), 170.0, 1e-5);
    EXPECT_NEAR((w.centre_mm - w.profile_mm).norm(), 150.0, 1e-9);
    EXPECT_GT(w.normal.dot(w.profile_mm), 0.0);  // outward
  }
  // A clockwise point list is oriented first: the same path.
  auto cw = circle(20.0, 90);
  std::reverse(cw.begin(), cw.end());
  EXPECT_NEAR(wheelCentrePath(cw, 150.0, 360)[10].centre_mm.norm(), 170.0, 1e-5);
  // The cam: every wheel centre is a wheel radius from the profile and no closer to any of it.
  const auto cam_path = wheelCentrePath(cam(360), 150.0, 720);
  const PeriodicSpline2d profile(cam(360));
  for (std::size_t k = 0; k < cam_path.size(); k += 37) {
    double nearest = 1e9;
    for (int j = 0; j < 20000; ++j)
      nearest = std::min(nearest, (profile.at(profile.period() * j / 20000.0) - cam_path[k].centre_mm).norm());
    EXPECT_NEAR(nearest, 150.0, 1e-4) << k;
  }
}

TEST(WheelPath, AWheelTooLargeForAConcaveFlankIsRefused) {
  // A dent: the radius drops by 0.5 mm over about 20 deg around 180 deg.
  std::vector<double> angle, radius;
  for (int i = 0; i < 360; ++i) {
    angle.push_back(i);
    radius.push_back(20.0 - 0.5 * std::exp(-std::pow((i - 180.0) / 10.0, 2)));
  }
  try {
    wheelCentrePath(polarProfile(angle, radius), 150.0, 720);
    FAIL() << "a 150 mm wheel cannot enter the dent";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("concave"), std::string::npos) << e.what();
  }
  EXPECT_NO_THROW(wheelCentrePath(polarProfile(angle, radius), 10.0, 720));  // a small wheel can
  EXPECT_THROW(polarProfile({0, 10, 5, 20}, {1, 1, 1, 1}), InputError);
  // A table cut short (0 to 89 deg of a 1 deg table) is not closed across the rest of the turn.
  const std::vector<double> quarter_angle(angle.begin(), angle.begin() + 90),
      quarter_radius(radius.begin(), radius.begin() + 90);
  try {
    polarProfile(quarter_angle, quarter_radius);
    FAIL() << "a quarter of a lift table was taken for a cam";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("the angles run from 0 to 89 deg, leaving 271 deg of the turn without a row "
                                         "(its rows step by up to 1 deg)"),
              std::string::npos)
        << e.what();
  }
  EXPECT_NO_THROW(polarProfile({0, 90, 180, 270}, {1, 1, 1, 1}));  // a closing step as large as the others
}

TEST(GrindCompensation, IdealCommandsPutTheWheelOnThePathOfAnExactMachine) {
  const auto m = grinder();
  const auto path = wheelCentrePath(cam(360), 150.0, 360);
  std::vector<Eigen::Vector2d> centres;
  for (const auto& w : path) centres.push_back(w.centre_mm);
  const auto none = [&](const Eigen::VectorXd&) {
    return Eigen::VectorXd::Zero(static_cast<Eigen::Index>(m.terms().size()));
  };
  const auto commands = compensateGrinding(m, none, centres, {});
  ASSERT_EQ(commands.size(), centres.size());
  for (std::size_t i = 0; i < commands.size(); ++i) {
    EXPECT_EQ(commands[i].iterations, 0);
    EXPECT_NEAR(commands[i].x_mm, centres[i].norm(), 1e-9);  // the slide sets the wheel's distance from the C axis
    EXPECT_NEAR(commands[i].error_um, 0.0, 1e-6);
    if (i > 0) {
      EXPECT_LT(std::abs(commands[i].c_deg - commands[i - 1].c_deg), 5.0);  // unwrapped
    }
  }
  // One turn of the cam is one turn of the head.
  EXPECT_NEAR(std::abs(commands.back().c_deg - commands.front().c_deg), 359.0, 1.0);
}

TEST(GrindCompensation, CorrectedCommandsBringTheActualWheelCentreWithinTheResolution) {
  const auto m = grinder();
  const auto path = wheelCentrePath(cam(360), 150.0, 720);
  std::vector<Eigen::Vector2d> centres;
  for (const auto& w : path) centres.push_back(w.centre_mm);
  // The machine's errors: the C axis 8 um off in X and 5 um in Y, its angular positioning
  // 30 urad + 20 sin(c) urad, its radial run-out 2 um at once per turn, the X slide's
  // positioning 10 um/m and its yaw 15 urad.
  const auto errors = [&](const Eigen::VectorXd& q) {
    Eigen::VectorXd e = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(m.terms().size()));
    const double x = q(0), c = q(1) * kPi / 180.0;
    e(m.termIndex("EX0C")) = 8.0;
    e(m.termIndex("EY0C")) = -5.0;
    e(m.termIndex("ECC")) = 30.0 + 20.0 * std::sin(c);
    e(m.termIndex("EXC")) = 2.0 * std::cos(c);
    e(m.termIndex("EXX")) = 10.0 * x / 1000.0;
    e(m.termIndex("ECX")) = 15.0;
    return e;
  };
  ASSERT_EQ(m.coordinates()[0], "x");
  CompensationOptions options;
  const auto commands = compensateGrinding(m, errors, centres, options);
  double worst_before = 0.0, worst_after = 0.0;
  int most_iterations = 0;
  for (std::size_t i = 0; i < commands.size(); ++i) {
    const auto& g = commands[i];
    worst_before = std::max(worst_before, g.error_ideal_um);
    worst_after = std::max(worst_after, g.error_um);
    most_iterations = std::max(most_iterations, g.iterations);
    // The constraint P_W = P_T checked here from the model directly.
    Eigen::VectorXd q(2);
    q << g.x_mm, g.c_deg;
    const Eigen::Vector2d actual = m.actualPoint(q, errors(q)).head<2>();
    const double resolution_um =
        std::hypot(options.resolution_x_um, g.x_mm * options.resolution_c_deg * kPi / 180.0 * 1000.0);
    EXPECT_LT((actual - centres[i]).norm() * 1000.0, resolution_um) << i;
  }
  EXPECT_GT(worst_before, 8.0);  // uncorrected, the cam would be off by the C axis' offset and more
  EXPECT_LT(worst_after, 0.35);  // the resolution: 0.1 um on X, 170 mm x 1e-4 deg = 0.30 um on C
  EXPECT_LE(most_iterations, 4);

  const std::string program = grindingGcode(commands, 10.0, "test cam");
  EXPECT_NE(program.find("G93"), std::string::npos);
  EXPECT_EQ(std::count(program.begin(), program.end(), '\n'),
            static_cast<long>(commands.size() + 9));  // the G1 blocks, the closing one and 9 lines around them
  // The turn is closed: the last block goes back to the first point's X, one turn of C on.
  const auto last = program.rfind("G1 ");
  const std::string closing = program.substr(last, program.find('\n', last) - last);
  const double sense = commands.back().c_deg >= commands.front().c_deg ? 1.0 : -1.0;
  EXPECT_EQ(closing.substr(0, closing.find(" F")),
            fmt::format("G1 X{:.5f} C{:.5f}", commands.front().x_mm, commands.front().c_deg + sense * 360.0));
}

}  // namespace
}  // namespace mtcal::processing
