// A many-seed study of the thermal error model (docs/thermal.md), not a timing: the 8-hour
// spindle program on the simulated headstock (Reynolds friction, lumped network) in a new shop
// each seed (bench/thermal_data.h). Fitted on the first 60 %, tested on the rest:
//   chosen     the model kept (fewest sensors within 5 % of the best CV RMS)
//   baseline   the one sensor most correlated with the drift, linear
//   grey best  the paper's grey-relational selection at its best size (chosen by the test RMS,
//              1..6 sensors: an oracle, for comparison only)
//   needed     fewest sensors whose test RMS reaches 1 um, stepwise and grey (- : none)
//   ./build/bench/mtcal_study_thermal [seeds=20]

#include <fmt/format.h>

#include <algorithm>
#include <cstdlib>
#include <vector>

#include "thermal_data.h"

using namespace mtcal;

int main(int argc, char** argv) {
  const int seeds = argc > 1 ? std::atoi(argv[1]) : 20;
  std::vector<double> chosen_rms, baseline_rms, grey_rms, gains;
  std::vector<int> chosen_k, needed_stepwise, needed_grey;
  fmt::print("{:>4} {:>6} {:>5} {:>6} | {:>2} {:>9} {:>11} {:>9} {:>6} | {:>6} {:>6}\n", "seed", "swing", "rpm", "phi",
             "k", "chosen", "baseline", "grey best", "gain", "need s", "need g");
  for (int seed = 1; seed <= seeds; ++seed) {
    const auto shop = bench::simulatedShop(static_cast<std::uint64_t>(seed));
    const auto& d = shop.data;
    processing::ThermalFitOptions options;
    options.max_sensors = 6;
    const auto r = processing::fitThermalModel(d, options);
    double grey_best = 1e300;
    for (const auto& c : r.grey) grey_best = std::min(grey_best, c.rms_test_um);
    auto needed = [](const std::vector<processing::ThermalCandidate>& path) {
      for (const auto& c : path) {
        if (c.rms_test_um <= 1.0) return static_cast<int>(c.sensors.size());
      }
      return 0;
    };
    chosen_rms.push_back(r.chosen.rms_test_um);
    baseline_rms.push_back(r.baseline.rms_test_um);
    grey_rms.push_back(grey_best);
    gains.push_back(r.gain);
    chosen_k.push_back(static_cast<int>(r.chosen.sensors.size()));
    needed_stepwise.push_back(needed(r.stepwise));
    needed_grey.push_back(needed(r.grey));
    auto cell = [](int k) { return k ? fmt::format("{}", k) : std::string("-"); };
    fmt::print("{:>4} {:>6.2f} {:>5.0f} {:>6.3f} | {:>2} {:>9.3f} {:>11.3f} {:>9.3f} {:>5.1f}% | {:>6} {:>6}\n", seed,
               shop.swing_k, shop.middle_rpm, r.chosen.phi, r.chosen.sensors.size(), r.chosen.rms_test_um,
               r.baseline.rms_test_um, grey_best, 100.0 * r.gain, cell(needed_stepwise.back()),
               cell(needed_grey.back()));
  }
  auto median = [](std::vector<double> v) {
    std::sort(v.begin(), v.end());
    return v[v.size() / 2];
  };
  auto count = [](const std::vector<int>& v, int k) { return std::count(v.begin(), v.end(), k); };
  fmt::print("\nmedian test rms: chosen {:.3f} um, baseline {:.3f} um, grey best {:.3f} um; median gain {:.1f} %\n",
             median(chosen_rms), median(baseline_rms), median(grey_rms), 100.0 * median(gains));
  fmt::print("1 um reached: stepwise in {} of {} seeds, grey in {} of {}\n", seeds - count(needed_stepwise, 0), seeds,
             seeds - count(needed_grey, 0), seeds);
  for (int k = 1; k <= 6; ++k) {
    fmt::print("  {} sensors: chosen {}x, needed for 1 um stepwise {}x, grey {}x\n", k, count(chosen_k, k),
               count(needed_stepwise, k), count(needed_grey, k));
  }
  return 0;
}
