#include "mtcal/mocks/virtual_machine.h"

#include <gtest/gtest.h>

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

TEST(VirtualMachine, AbbeTermsFollowTheSmallAngleRigidBodyConvention) {
  VirtualMachineConfig config;
  config.axes[0].rotation_urad[1] = {{100.0}, {}};  // EBX = 100 urad (pitch), constant
  config.axes[0].rotation_urad[2] = {{-50.0}, {}};  // ECX = -50 urad (yaw), constant
  WorldClock clock;
  VirtualMachine m(config, clock);
  // dx = EBX * z - ECX * y (ISO 230-1, eps x r): 100e-6 * 40 mm + 50e-6 * 20 mm = 5 um.
  EXPECT_NEAR(m.staticErrorUm(Axis::kX, {0.0, 20.0, 40.0}, 300.0, +1), 5.0, 1e-9);
  EXPECT_NEAR(m.staticErrorUm(Axis::kX, {0.0, 0.0, 0.0}, 300.0, +1), 0.0, 1e-12);
}

TEST(VirtualMachine, BacklashSplitsBetweenApproachDirections) {
  VirtualMachineConfig config;
  config.axes[0].backlash_um = 4.0;
  config.settle_time_constant_s = 0.0;
  WorldClock clock(1000.0);
  VirtualMachine m(config, clock);
  const double up_done = m.moveTo(Axis::kX, 100.0);
  EXPECT_NEAR(m.pointErrorUm(Axis::kX, {}, up_done + 1.0), -2.0, 1e-12);
  m.moveTo(Axis::kX, 200.0);
  const double down_done = m.moveTo(Axis::kX, 100.0);
  EXPECT_NEAR(m.pointErrorUm(Axis::kX, {}, down_done + 1.0), +2.0, 1e-12);
  EXPECT_EQ(m.moveCount(), 3u);
  EXPECT_THROW(m.moveTo(Axis::kX, 5000.0), InputError);
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
      v.push_back(m.pointErrorUm(Axis::kX, {}, done + 0.5));
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
  EXPECT_NEAR(sum / n, 0.0, 0.01);       // 4.5 standard errors
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
  EXPECT_DOUBLE_EQ(c.axes[0].translation_um[0].value(500.0), 6.0);
  EXPECT_DOUBLE_EQ(c.squareness_c0y_urad, 15.0);

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
  EXPECT_NE(bad(R"({"axes": {"X": {"min_mm": 10, "max_mm": 5}}})").find("max_mm"), std::string::npos);
  EXPECT_NE(bad(R"({"feed_mm_per_min": "fast"})").find("feed_mm_per_min"), std::string::npos);
  EXPECT_NE(bad(R"({"colour": 1})").find("colour"), std::string::npos);
}

}  // namespace
}  // namespace mtcal::mocks
