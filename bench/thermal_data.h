#pragma once
// Thermal monitoring data of a simulated shop (bench/thermal_study.cpp, thermal_bench.cpp):
// the 8-hour spindle program on the simulated headstock, 16 sensors read as the logger reads
// them (offset within 0.05 K, 0.005 K noise, 0.01 K rounding), the Z drift as a probe reads it
// (0.05 um noise), every 60 s. The shop changes with the seed: the air's daily swing
// 0.3..1.5 K at a random phase, the middle phase's speed 800..1500 rpm. Over several days the
// program runs every morning (its middle speed drawn anew each day) and the machine stands
// for the rest of the day; the record goes on through the nights.

#include <cmath>
#include <numbers>
#include <random>
#include <vector>

#include "mtcal/mocks/machine_thermal.h"
#include "mtcal/processing/thermal_model.h"

namespace mtcal::bench {

struct ThermalShop {
  processing::ThermalData data;
  double swing_k = 0.0, middle_rpm = 0.0;
};

inline ThermalShop simulatedShop(std::uint64_t seed, int days = 1) {
  constexpr double kIntervalS = 60.0;
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  std::normal_distribution<double> normal;
  ThermalShop shop;
  mocks::MachineThermalConfig config;
  config.ambient_swing_k = shop.swing_k = 0.3 + 1.2 * uniform(rng);
  config.ambient_phase_rad = 2.0 * std::numbers::pi * uniform(rng);
  shop.middle_rpm = 800.0 + 700.0 * uniform(rng);
  mocks::MachineThermal thermal(config);
  std::vector<mocks::SpindlePhase> program;
  for (int day = 0; day < days; ++day) {
    const double middle_rpm = day == 0 ? shop.middle_rpm : 800.0 + 700.0 * uniform(rng);
    program.insert(program.end(),
                   {{150 * 60.0, 2000.0}, {90 * 60.0, middle_rpm}, {60 * 60.0, 2000.0}, {180 * 60.0, 0.0}});
    if (day + 1 < days) program.push_back({16 * 3600.0 - 180 * 60.0, 0.0});
  }
  thermal.startProgram(program, 0.0);
  const int n = days == 1 ? 481 : days * 1440 + 1, sites = static_cast<int>(config.model.sensors.size());
  std::vector<double> offset(static_cast<std::size_t>(sites));
  for (auto& o : offset) o = 0.05 * (2.0 * uniform(rng) - 1.0);
  auto& d = shop.data;
  for (const auto& s : config.model.sensors) d.sensors.push_back(s.name);
  d.temperature_c.resize(n, sites);
  d.target_um.resize(n);
  d.time_s.resize(n);
  for (int k = 0; k < n; ++k) {
    const auto state = thermal.at(k * kIntervalS);
    d.time_s(k) = k * kIntervalS;
    for (int c = 0; c < sites; ++c) {
      d.temperature_c(k, c) =
          std::round((state.sensors_c(c) + offset[static_cast<std::size_t>(c)] + 0.005 * normal(rng)) * 100.0) / 100.0;
    }
    d.target_um(k) = state.drift_um(2) + 0.05 * normal(rng);
  }
  return shop;
}

}  // namespace mtcal::bench
