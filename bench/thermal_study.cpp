// A many-seed study of the thermal error model (docs/thermal.md), not a timing: the spindle
// program on the simulated headstock (Reynolds friction, lumped network) in a new shop each
// seed (bench/thermal_data.h), for one day (the 8-hour program) or several (the program every
// morning, the record through the nights). Fitted on the first 60 %, tested on the rest, open
// loop (what a compensation predicts) unless said:
//   kept       the model kept (fewest inputs within 5 % of the best CV RMS, any family)
//   grey       the paper's way: grey-relational selection, AR(1) errors (its best size by CV)
//   static     forward selection, least squares (its best size by CV)
//   ar1        forward selection, AR(1) errors by Prais-Winsten (its best size by CV)
//   ar1 1-step the same model one step ahead (the previous measured error known)
//   lagged     forward selection over the sensors through first-order lags
//   all        every sensor, least squares
//   fwd 3      the static forward selection's 3-sensor model (a plain forward selection)
//   one        the one sensor most correlated with the drift
//   ./build/bench/mtcal_study_thermal [seeds=20] [days=1] [max_sensors=6]

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <map>
#include <vector>

#include "thermal_data.h"

using namespace mtcal;
using processing::ThermalFamily;

int main(int argc, char** argv) {
  const int seeds = argc > 1 ? std::atoi(argv[1]) : 20;
  const int days = argc > 2 ? std::atoi(argv[2]) : 1;
  const int max_sensors = argc > 3 ? std::atoi(argv[3]) : 6;
  const std::vector<std::string> columns = {"kept",   "grey", "static", "ar1", "ar1 1-step",
                                            "lagged", "all",  "fwd 3",  "one"};
  std::map<std::string, std::vector<double>> rms;
  std::map<std::string, int> kept_family;
  int beats_all = 0, matches_all = 0, beats_forward = 0, compared = 0;
  fmt::print("{} day(s), {} seeds, at most {} inputs; test RMS (um), open loop unless said\n", days, seeds,
             max_sensors);
  fmt::print("{:>4} {:>5} | {:<16}", "seed", "swing", "kept as");
  for (const auto& c : columns) fmt::print(" {:>10}", c);
  fmt::print("\n");
  for (int seed = 1; seed <= seeds; ++seed) {
    const auto shop = bench::simulatedShop(static_cast<std::uint64_t>(seed), days);
    processing::ThermalFitOptions options;
    options.max_sensors = max_sensors;
    const auto r = processing::fitThermalModel(shop.data, options);
    const auto best = processing::bestOfEachPath(r);  // grey, static, ar1, lagged
    std::map<std::string, double> row = {{"kept", r.chosen.rms_test_um},
                                         {"grey", best.at(0)->rms_test_um},
                                         {"static", best.at(1)->rms_test_um},
                                         {"ar1", best.at(2)->rms_test_um},
                                         {"ar1 1-step", best.at(2)->rms_test_one_step_um},
                                         {"lagged", best.at(3)->rms_test_um},
                                         {"all", r.all_sensors ? r.all_sensors->rms_test_um : NAN},
                                         {"fwd 3", NAN},
                                         {"one", r.baseline.rms_test_um}};
    for (const auto& path : r.paths) {
      if (path.method == "stepwise" && path.family == ThermalFamily::kStatic && path.models.size() >= 3)
        row["fwd 3"] = path.models[2].rms_test_um;
    }
    const std::string kept = fmt::format("{} {} ({})", r.chosen.method, processing::thermalFamilyName(r.chosen.family),
                                         r.chosen.sensors.size());
    ++kept_family[processing::thermalFamilyName(r.chosen.family)];
    fmt::print("{:>4} {:>5.2f} | {:<16}", seed, shop.swing_k, kept);
    for (const auto& c : columns) {
      fmt::print(" {:>10.3f}", row[c]);
      rms[c].push_back(row[c]);
    }
    fmt::print("\n");
    if (std::isfinite(row["all"]) && std::isfinite(row["fwd 3"])) {
      ++compared;
      beats_all += row["kept"] < row["all"];
      matches_all += row["kept"] <= row["all"] * 1.05;
      beats_forward += row["kept"] < row["fwd 3"];
    }
  }
  auto median = [](std::vector<double> v) {
    std::erase_if(v, [](double x) { return !std::isfinite(x); });
    if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
    std::sort(v.begin(), v.end());
    return v[v.size() / 2];
  };
  fmt::print("\nmedian test RMS (um):");
  for (const auto& c : columns) fmt::print("  {} {:.3f}", c, median(rms[c]));
  fmt::print("\nkept family:");
  for (const auto& [family, count] : kept_family) fmt::print("  {} {}x", family, count);
  fmt::print(
      "\nthe kept model beats every sensor by least squares in {} of {} shops (within 5 % of it or better in {}), "
      "the 3-sensor forward selection in {} of {}\n",
      beats_all, compared, matches_all, beats_forward, compared);
  return 0;
}
