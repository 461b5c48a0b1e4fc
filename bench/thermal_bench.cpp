// The thermal model's fit (docs/thermal.md) on 8 hours of 16 sensors every minute (481 rows,
// bench/thermal_data.h, seed 1), against the reference of one least-squares solve of the drift
// on all 16 sensors in the same process: what the selection (grey grades, clusters, forward
// stepwise with cross-validation, AR(1) fits and their diagnostics) costs in such solves.

#include <benchmark/benchmark.h>

#include "mtcal/processing/regression.h"
#include "thermal_data.h"

namespace {

using namespace mtcal;

const processing::ThermalData& data() {
  static const auto shop = bench::simulatedShop(1);
  return shop.data;
}

void BM_ThermalReferenceOneSolve(benchmark::State& state) {
  for (auto _ : state) benchmark::DoNotOptimize(processing::fitLinear(data().temperature_c, data().target_um).rss);
}
BENCHMARK(BM_ThermalReferenceOneSolve)->Unit(benchmark::kMicrosecond);

void BM_ThermalFit(benchmark::State& state) {
  processing::ThermalFitOptions options;
  options.max_sensors = static_cast<int>(state.range(0));
  for (auto _ : state) benchmark::DoNotOptimize(processing::fitThermalModel(data(), options).gain);
}
BENCHMARK(BM_ThermalFit)->Arg(4)->Arg(6)->Unit(benchmark::kMillisecond);

}  // namespace
