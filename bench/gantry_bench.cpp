// The gantry point accuracy evaluation (docs/gantry.md) against an independent numpy
// implementation of the same steps (bench/gantry_numpy.py, run by this program on the same
// measurement file): time, and the largest difference of dP between the two.
// Input: examples/gantry/quick-6x2-export.json (12 holes, 2 x 2001 tracked points).

#include <benchmark/benchmark.h>

#include <chrono>
#include <fstream>
#include <nlohmann/json.hpp>

#include "mtcal/acquisition/gantry_test.h"
#include "mtcal/processing/gantry_accuracy.h"
#include "python_reference.h"

namespace {

using namespace mtcal;

const nlohmann::json& file() {
  static const nlohmann::json j =
      nlohmann::json::parse(std::ifstream(std::string(MTCAL_SOURCE_DIR) + "/examples/gantry/quick-6x2-export.json"));
  return j;
}

const processing::GantryMeasurements& measurements() {
  static const auto m = acquisition::measurementsFromJson(file(), "quick-6x2-export.json");
  return m;
}

const nlohmann::json& numpy() {
  static const nlohmann::json result = runPython("gantry_numpy.py", file(), "5");
  return result;
}

void BM_GantryEvaluateNumpy(benchmark::State& state) {
  if (numpy().is_discarded()) {
    state.SkipWithError("python3 with numpy did not run (bench/gantry_numpy.py)");
    return;
  }
  for (auto _ : state) state.SetIterationTime(numpy()["seconds"].get<double>());
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
  if (!numpy().is_discarded()) {
    double max_diff = 0.0;
    const auto& dp = numpy()["dp_um"];
    for (std::size_t i = 0; i < ev.holes.size(); ++i) {
      for (int k = 0; k < 3; ++k) max_diff = std::max(max_diff, std::abs(ev.holes[i].dp_um(k) - dp[i][static_cast<std::size_t>(k)].get<double>()));
    }
    state.counters["max_diff_vs_numpy_um"] = max_diff;
    state.counters["speedup_vs_numpy"] = numpy()["seconds"].get<double>() / best_s;
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

BENCHMARK_MAIN();
