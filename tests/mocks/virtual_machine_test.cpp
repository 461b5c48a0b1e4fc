#include "mtcal/mocks/virtual_machine.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <nlohmann/json.hpp>

#include "mtcal/error.h"
#include "mtcal/mocks/random.h"

namespace mtcal::mocks {
namespace {

TEST(ErrorCurve, PolynomialInMetresPlusHarmonics) {
  ErrorCurve c{{1.0, 10.0, -20.0}, {{2.0, 100.0, 0.0}}};
  // At 250 mm: 1 + 10*0.25 - 20*0.0625 + 2 sin(2 pi 2.5) = 2.25 + 0.
  EXPECT_NEAR(c.value(250.0), 2.25, 1e-12);
  // At 25 mm: quarter period of the harmonic adds its full amplitude.
  EXPECT_NEAR(c.value(25.0), 1.0 + 0.25 - 20 * 0.000625 + 2.0, 1e-12);
}

// The patent's machine: the tool point hangs 120 mm below the Z carriage; X carries Y
// carries Z. A rotation of the X carriage moves a point by eps x r with r measured from the
// X carriage's frame: (0, y, z - 120) + the reflector offset (ISO 230-1 small-angle rigid body).
TEST(VirtualMachine, AbbeTermsFollowTheSmallAngleRigidBodyConvention) {
  VirtualMachineConfig config;
  config.errors["EBX"] = {{100.0}, {}};  // pitch 100 urad, constant
  config.errors["ECX"] = {{-50.0}, {}};  // yaw -50 urad, constant
  WorldClock clock;
  VirtualMachine m(config, clock);
  // Y = Z = 0, reflector (0, 20, 40) from the tool point: r = (0, 20, -80) mm.
  // dx = EBX r_z - ECX r_y = 100e-6 * (-80) + 50e-6 * 20 mm = -7 um.
  // (The full transform product adds second-order terms of ~1e-8 um.)
  EXPECT_NEAR(m.staticErrorUm(Axis::kX, {0.0, 20.0, 40.0}, 300.0, +1), -7.0, 1e-6);
  EXPECT_NEAR(m.staticErrorUm(Axis::kX, {0.0, 0.0, 120.0}, 300.0, +1), 0.0, 1e-6);  // on the X frame's origin
  // The arm grows with the Z travel: at Z = 200 mm, r_z = 200 - 120 + 40 = 120 mm: 12 + 1 um.
  const double done = m.moveTo(Axis::kZ, 200.0);
  EXPECT_NEAR(m.staticErrorUm(Axis::kX, {0.0, 20.0, 40.0}, 300.0, +1), 13.0, 1e-6);
  // Angular optics see the carriage's rotation itself, whatever the arm.
  const Eigen::Vector3d rotation = m.rotationErrorUrad(done + 1.0);
  EXPECT_NEAR(rotation.y(), 100.0, 1e-6);
  EXPECT_NEAR(rotation.z(), -50.0, 1e-6);
}

// EC0Y > 0 turns the Y axis about +Z: +Y leans towards -X, the tool moves by -EC0Y * y in X.
TEST(VirtualMachine, SquarenessTiltsTheAxisThatCarriesIt) {
  VirtualMachineConfig config;
  config.errors["EC0Y"] = {{15.0}, {}};
  WorldClock clock(1000.0);
  VirtualMachine m(config, clock);
  const double done = m.moveTo(Axis::kY, 400.0);
  const Eigen::Vector3d e = m.pointErrorUm({}, done + 1.0);
  EXPECT_NEAR(e.x(), -15e-6 * 400.0 * 1000.0, 1e-6);  // -6 um
  EXPECT_NEAR(e.y(), 0.0, 1e-4);                      // second order: (15e-6)^2 * 400 mm / 2
}

// The simulation and the identification share one model: what the machine shows equals
// -J e of processing's Jacobian to second order (the demo machine's errors are ~10 um, 20 urad).
TEST(VirtualMachine, ObservesTheProcessingModel) {
  auto config = VirtualMachineConfig::demo(3);
  for (auto& a : config.axes) {
    a.backlash_um = 0.0;
    a.positioning_sigma_um = 0.0;
  }
  config.settle_time_constant_s = 0.0;
  WorldClock clock(1000.0);
  VirtualMachine m(config, clock);
  // The three moves run together; the last ends with X.
  const double done = std::max({m.moveTo(Axis::kX, 420.0), m.moveTo(Axis::kY, 130.0), m.moveTo(Axis::kZ, 250.0)});
  const auto& model = m.kinematics();
  const Eigen::Vector3d q(420.0, 130.0, 250.0);
  Eigen::VectorXd e(static_cast<Eigen::Index>(model.terms().size()));
  for (std::size_t t = 0; t < model.terms().size(); ++t) {
    const auto& term = model.terms()[t];
    const int c = model.coordinateOfJoint(term.joint);
    e(static_cast<Eigen::Index>(t)) = config.trueError(term.name, term.motion ? q(c) : 0.0);
  }
  const ToolOffset reflector{10.0, -30.0, 50.0};
  const Eigen::Vector3d p = model.toolPoint() + Eigen::Vector3d(10.0, -30.0, 50.0);
  const Eigen::Vector3d linear_um = -model.jacobian(q, p) * e;
  EXPECT_LT((m.pointErrorUm(reflector, done + 1.0) - linear_um).norm(), 1e-3);
  EXPECT_GT(linear_um.norm(), 3.0);  // 3.1 um here: the check is not trivially met
  EXPECT_LT((m.rotationErrorUrad(done + 1.0) - model.orientationJacobian(q) * e).norm(), 1e-3);
}

TEST(VirtualMachine, BacklashSplitsBetweenApproachDirections) {
  VirtualMachineConfig config;
  config.axes[0].backlash_um = 4.0;
  config.settle_time_constant_s = 0.0;
  WorldClock clock(1000.0);
  VirtualMachine m(config, clock);
  const double up_done = m.moveTo(Axis::kX, 100.0);
  EXPECT_NEAR(m.pointErrorUm({}, up_done + 1.0).x(), -2.0, 1e-9);
  m.moveTo(Axis::kX, 200.0);
  const double down_done = m.moveTo(Axis::kX, 100.0);
  EXPECT_NEAR(m.pointErrorUm({}, down_done + 1.0).x(), +2.0, 1e-9);
  EXPECT_EQ(m.moveCount(), 3u);
  EXPECT_THROW(m.moveTo(Axis::kX, 5000.0), InputError);
}

TEST(VirtualMachine, TheControllersTableCorrectsEachDirectionAsItIsApplied) {
  // Backlash 4 um: -2 um going up, +2 going down. A LinuxCNC-like table cancels it from
  // 50 to 150 mm and adds a slope of 0.01 um/mm going up.
  VirtualMachineConfig config;
  config.axes[0].backlash_um = 4.0;
  config.settle_time_constant_s = 0.0;
  processing::CompensationTable t;
  t.position = {50.0, 150.0};
  t.up_um = {2.0 + 0.5, 2.0 + 1.5};
  t.down_um = {-2.0, -2.0};
  config.compensation[0] = VirtualMachineConfig::AxisCompensation{t, {}};
  WorldClock clock(1000.0);
  VirtualMachine m(config, clock);
  EXPECT_NEAR(m.pointErrorUm({}, 0.0).x(), -2.0, 1e-9);  // before the first move: no correction
  const double up_done = m.moveTo(Axis::kX, 100.0);
  EXPECT_NEAR(m.pointErrorUm({}, up_done + 1.0).x(), 1.0, 1e-9);  // -2 + 2.5 + (1.5 - 0.5) / 2
  EXPECT_NEAR(m.staticErrorUm(Axis::kX, {}, 100.0, +1), 1.0, 1e-9);
  m.moveTo(Axis::kX, 200.0);
  // Beyond the table its last value holds (+1.5 over the backlash).
  EXPECT_NEAR(m.staticErrorUm(Axis::kX, {}, 200.0, +1), 1.5, 1e-9);
  const double down_done = m.moveTo(Axis::kX, 100.0);
  EXPECT_NEAR(m.pointErrorUm({}, down_done + 1.0).x(), 0.0, 1e-9);
  EXPECT_NEAR(m.staticErrorUm(Axis::kX, {}, 100.0, -1), 0.0, 1e-9);
  // Half way through the move down from 200 the table is read at the commanded 150 mm.
  m.moveTo(Axis::kX, 200.0);
  const double done = m.moveTo(Axis::kX, 100.0);
  const double start = done - 100.0 / (config.feed_mm_per_min / 60.0);
  EXPECT_NEAR(m.pointErrorUm({}, (start + done) / 2.0).x(), 2.0 - 2.0, 1e-9);
}

TEST(VirtualMachine, ScatterIsSeededAndReproducible) {
  auto scatter = [](std::uint64_t seed) {
    VirtualMachineConfig config;
    config.seed = seed;
    config.axes[0].positioning_sigma_um = 1.0;
    config.settle_time_constant_s = 0.0;
    WorldClock clock(1000.0);
    VirtualMachine m(config, clock);
    std::vector<double> v;
    for (int i = 0; i < 50; ++i) {
      const double done = m.moveTo(Axis::kX, 100.0 + i);
      v.push_back(m.pointErrorUm({}, done + 0.5).x());
    }
    return v;
  };
  EXPECT_EQ(scatter(5), scatter(5));
  EXPECT_NE(scatter(5), scatter(6));
  const auto v = scatter(5);
  double ss = 0;
  for (double x : v) ss += x * x;
  EXPECT_NEAR(std::sqrt(ss / v.size()), 1.0, 0.35);  // sigma 1 um within sampling error of 50 draws
}

TEST(KeyedRandom, StandardNormalMoments) {
  double sum = 0, ss = 0;
  const int n = 200000;
  for (int i = 0; i < n; ++i) {
    const double x = normalFromKey(42, 7, static_cast<std::uint64_t>(i));
    sum += x;
    ss += x * x;
  }
  EXPECT_NEAR(sum / n, 0.0, 0.01);  // 4.5 standard errors
  EXPECT_NEAR(ss / n, 1.0, 0.015);
}

TEST(VirtualMachineConfig, ReadsAMachineFileAndNamesBadKeys) {
  const auto j = nlohmann::json::parse(R"({
    "name": "vmc-850", "seed": 9,
    "axes": {"X": {"min_mm": 0, "max_mm": 850, "backlash_um": 3,
                   "errors": {"EXX": {"poly": [0, 12]}, "EBX": {"harmonics": [{"amplitude": 2, "period_mm": 200}]}}}},
    "squareness": {"EC0Y": 15}
  })");
  const auto c = VirtualMachineConfig::fromJson(j, "vmc.json");
  EXPECT_EQ(c.name, "vmc-850");
  EXPECT_EQ(c.seed, 9u);
  EXPECT_DOUBLE_EQ(c.axes[0].max_mm, 850.0);
  EXPECT_DOUBLE_EQ(c.trueError("EXX", 500.0), 6.0);
  EXPECT_DOUBLE_EQ(c.trueError("EC0Y", 0.0), 15.0);
  EXPECT_DOUBLE_EQ(c.trueError("EYY", 100.0), 0.0);  // not listed: zero

  auto bad = [](const char* text) {
    try {
      VirtualMachineConfig::fromJson(nlohmann::json::parse(text), "vmc.json");
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(bad(R"({"axes": {"X": {"errors": {"EYY": {"poly": [1]}}}}})").find("axes.X.errors.EYY"), std::string::npos);
  EXPECT_NE(bad(R"({"axes": {"W": {}}})").find("axes.W"), std::string::npos);
  EXPECT_NE(bad(R"({"axes": {"X": {"errors": {"EC0Y": {"poly": [1]}}}}})").find("a static error"), std::string::npos);
  EXPECT_NE(bad(R"({"squareness": {"EXX": 3}})").find("a motion error"), std::string::npos);
  EXPECT_NE(bad(R"({"squareness": {"EQQ": 3}})").find("EQQ"), std::string::npos);
  EXPECT_NE(bad(R"({"axes": {"X": {"min_mm": 10, "max_mm": 5}}})").find("max_mm"), std::string::npos);
  EXPECT_NE(bad(R"({"feed_mm_per_min": "fast"})").find("feed_mm_per_min"), std::string::npos);
  EXPECT_NE(bad(R"({"colour": 1})").find("colour"), std::string::npos);
}

}  // namespace
}  // namespace mtcal::mocks
