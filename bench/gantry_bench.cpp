// The gantry point accuracy evaluation (docs/gantry.md) against an independent numpy
// implementation of the same steps (bench/gantry_numpy.py, run by this program on the same
// measurement file): time, and the largest difference of dP between the two.
// Input: examples/gantry/quick-6x2-export.json (12 holes, 2 x 2001 tracked points).

#include <benchmark/benchmark.h>

#include <chrono>

#include "numpy_reference.h"

namespace {

using namespace mtcal;

const processing::GantryMeasurements& measurements() {
  static const auto m = reference::gantryMeasurements();
  return m;
}

const reference::NumpyRun& numpy() {
  static const auto run = reference::tryRunNumpy("gantry_numpy.py", reference::gantryExport(), {"5"});
  return run;
}

void BM_GantryEvaluateNumpy(benchmark::State& state) {
  if (!numpy().error.empty()) {
    state.SkipWithError(numpy().error.c_str());
    return;
  }
  for (auto _ : state) state.SetIterationTime(numpy().result["seconds"].get<double>());
}
BENCHMARK(BM_GantryEvaluateNumpy)->UseManualTime()->Iterations(1)->Unit(benchmark::kMillisecond);

void BM_GantryEvaluateMtcal(benchmark::State& state) {
  processing::GantryEvaluation ev;
  double best_s = 1e9;
  for (auto _ : state) {
    const auto start = std::chrono::steady_clock::now();
    ev = processing::evaluateGantry(measurements());
    best_s = std::min(best_s, std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
    benchmark::DoNotOptimize(ev.holes.data());
  }
  if (numpy().error.empty()) {
    state.counters["max_diff_vs_numpy_um"] = reference::compareGantry(ev, numpy().result).max_abs_difference;
    state.counters["speedup_vs_numpy"] = numpy().result["seconds"].get<double>() / best_s;
  }
}
BENCHMARK(BM_GantryEvaluateMtcal)->Unit(benchmark::kMillisecond)->MinTime(1.0);

// The uncertainty: 100 Monte Carlo trials (each the whole evaluation on moved points).
void BM_GantryMonteCarlo100(benchmark::State& state) {
  for (auto _ : state) {
    const auto u = processing::monteCarloGantry(measurements(), {}, processing::TrackerMpe{}, 100, 1);
    benchmark::DoNotOptimize(u.holes.data());
  }
}
BENCHMARK(BM_GantryMonteCarlo100)->Unit(benchmark::kMillisecond)->MinTime(2.0);

}  // namespace
