// Volumetric error map of a 3-axis error model on a 100 x 100 x 100 grid, and a full
// identification (18 measured lines of the direct method on the patent's grid, 50-600 mm every
// 20 mm: 21 errors), each against a straightforward numpy implementation of the same
// computation (bench/model_map_numpy.py, bench/model_identify_numpy.py), run by this program
// on the same data. Also the point-by-point full model as the reference of what the grid
// evaluation saves.

#include <benchmark/benchmark.h>

#include <chrono>

#include "numpy_reference.h"

namespace {

using namespace mtcal;

constexpr int kGrid = 100;

struct Fixture {
  reference::ModelCase vmc3;
  std::vector<std::vector<double>> axes;
};

Fixture& fixture() {
  static Fixture* f = new Fixture{reference::vmc3Model(), reference::mapGrid({kGrid, kGrid, kGrid})};
  return *f;
}

// Runs the numpy script once on the model (best of 3) and returns its time and 7 sample values.
const reference::NumpyRun& numpyMap() {
  static const reference::NumpyRun run = reference::tryRunNumpy(
      "model_map_numpy.py", reference::mapInput(fixture().vmc3, fixture().axes), reference::mapArgs(3, 7));
  return run;
}

void BM_VolumetricMapNumpy(benchmark::State& state) {
  const auto& numpy = numpyMap();
  if (!numpy.error.empty()) {
    state.SkipWithError(numpy.error.c_str());
    return;
  }
  for (auto _ : state) state.SetIterationTime(numpy.result["seconds"].get<double>());
  state.SetItemsProcessed(state.iterations() * numpy.result["points"].get<std::int64_t>());
}
BENCHMARK(BM_VolumetricMapNumpy)->UseManualTime()->Iterations(1)->Unit(benchmark::kMillisecond);

void BM_VolumetricMapMtcal(benchmark::State& state) {
  const auto& f = fixture();
  std::vector<Eigen::Vector3d> map;
  double best_s = 1e9;
  for (auto _ : state) {
    const auto start = std::chrono::steady_clock::now();
    map = f.vmc3.model.predictGridUm(f.axes);
    best_s = std::min(best_s, std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
    benchmark::DoNotOptimize(map.data());
  }
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(map.size()));
  const auto& numpy = numpyMap();
  if (numpy.error.empty()) {
    const auto agreement = reference::compareMap(map, numpy.result);
    state.counters["max_diff_vs_numpy_um"] = agreement.max_abs_difference;
    state.counters["values_compared"] = static_cast<double>(agreement.compared);
    state.counters["speedup_vs_numpy"] = numpy.result["seconds"].get<double>() / best_s;
  }
}
BENCHMARK(BM_VolumetricMapMtcal)->Unit(benchmark::kMillisecond)->MinTime(2.0);

// The full model point by point (chain products, spline and transform at every point) on a
// tenth of the grid: what the grid evaluation saves.
void BM_VolumetricMapPointByPoint(benchmark::State& state) {
  const auto& f = fixture();
  std::int64_t points = 0;
  for (auto _ : state) {
    for (int i = 0; i < kGrid; ++i) {
      for (int j = 0; j < kGrid; ++j) {
        for (int k = 0; k < kGrid / 10; ++k) {
          benchmark::DoNotOptimize(
              f.vmc3.model.predictUm(Eigen::Vector3d(f.axes[0][i], f.axes[1][j], f.axes[2][k * 10])));
          ++points;
        }
      }
    }
  }
  state.SetItemsProcessed(points);
}
BENCHMARK(BM_VolumetricMapPointByPoint)->Unit(benchmark::kMillisecond)->MinTime(2.0);

// The direct method's 18 lines (docs/multibody-model.md) on the fixture's error model as the
// truth, read through the full model with 0.05 um / 0.05 urad of seeded noise per node.
const std::vector<processing::MeasuredLine>& identificationLines() {
  static const auto lines = reference::directMethodLines(fixture().vmc3.model);
  return lines;
}

const reference::NumpyRun& numpyIdentification() {
  static const reference::NumpyRun run = reference::tryRunNumpy(
      "model_identify_numpy.py", reference::identificationInput(fixture().vmc3.machine, identificationLines()), {"3"});
  return run;
}

void BM_IdentificationNumpy(benchmark::State& state) {
  const auto& numpy = numpyIdentification();
  if (!numpy.error.empty()) {
    state.SkipWithError(numpy.error.c_str());
    return;
  }
  for (auto _ : state) state.SetIterationTime(numpy.result["seconds"].get<double>());
}
BENCHMARK(BM_IdentificationNumpy)->UseManualTime()->Iterations(1)->Unit(benchmark::kMillisecond);

void BM_IdentificationMtcal(benchmark::State& state) {
  const auto& lines = identificationLines();
  processing::LineIdentification id;
  double best_s = 1e9;
  for (auto _ : state) {
    const auto start = std::chrono::steady_clock::now();
    id = processing::identifyFromLines(fixture().vmc3.model.kinematics(), lines, {});
    best_s = std::min(best_s, std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
    benchmark::DoNotOptimize(id.curves.data());
  }
  state.counters["errors"] = static_cast<double>(id.curves.size());
  const auto& numpy = numpyIdentification();
  if (numpy.error.empty()) {
    const auto agreement = reference::compareIdentification(id, numpy.result);
    state.counters["values_compared"] = static_cast<double>(agreement.compared);
    state.counters["max_diff_vs_numpy"] = agreement.max_abs_difference;
    state.counters["speedup_vs_numpy"] = numpy.result["seconds"].get<double>() / best_s;
  }
}
BENCHMARK(BM_IdentificationMtcal)->Unit(benchmark::kMillisecond)->MinTime(2.0);

}  // namespace
