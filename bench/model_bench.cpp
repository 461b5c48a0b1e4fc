// Volumetric error map of a 3-axis error model on a 100 x 100 x 100 grid: mtcal against a
// straightforward numpy implementation of the same computation (bench/model_map_numpy.py),
// both run by this program on the same stored model. Also the point-by-point full model as
// the reference of what the grid evaluation saves.

#include <benchmark/benchmark.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>

#include "mtcal/acquisition/error_models.h"

namespace {

using namespace mtcal;

constexpr int kGrid = 100;

struct Fixture {
  processing::ErrorModel model;
  nlohmann::json machine;
  std::vector<std::vector<double>> axes;
};

Fixture& fixture() {
  static Fixture* f = [] {
    const std::string root = MTCAL_SOURCE_DIR;
    std::ifstream machine_file(root + "/examples/machines/vmc3-cn104200063.model.json");
    auto machine = nlohmann::json::parse(machine_file);
    std::ifstream csv(root + "/examples/models/vmc3-error-curves.csv");
    std::vector<processing::ErrorFunction> functions;
    for (const auto& c : acquisition::parseErrorCurvesCsv(csv, "vmc3-error-curves.csv")) {
      functions.push_back(processing::ErrorFunction::fit(c, {}));
    }
    std::vector<double> values;
    for (int i = 0; i < kGrid; ++i) values.push_back(50.0 + 550.0 * i / (kGrid - 1));
    return new Fixture{processing::ErrorModel(processing::MultibodyModel::fromJson(machine, "vmc3"), functions), machine,
                       {values, values, values}};
  }();
  return *f;
}

// Runs the numpy script once on the model and returns its best time and sample values.
nlohmann::json runNumpy() {
  static nlohmann::json result = [] {
    const auto path = std::filesystem::temp_directory_path() / "mtcal_bench_model.json";
    nlohmann::json functions;
    for (const auto& f : fixture().model.functions()) functions[f.name()] = f.toJson();
    std::ofstream(path) << nlohmann::json{{"machine", fixture().machine}, {"functions", functions}, {"axes", fixture().axes}}
                                .dump();
    // Debian's interpreter: python3-numpy (scripts/setup) belongs to it, whatever else is on PATH.
    const std::string command = std::string("/usr/bin/python3 ") + MTCAL_SOURCE_DIR + "/bench/model_map_numpy.py " +
                                path.string() + " " + std::to_string(kGrid) + " 3";
    std::unique_ptr<FILE, int (*)(FILE*)> pipe(popen(command.c_str(), "r"), pclose);
    std::string out;
    char buffer[4096];
    while (pipe && std::fgets(buffer, sizeof buffer, pipe.get())) out += buffer;
    return nlohmann::json::parse(out, nullptr, false);
  }();
  return result;
}

void BM_VolumetricMapNumpy(benchmark::State& state) {
  const auto numpy = runNumpy();
  if (numpy.is_discarded()) {
    state.SkipWithError("python3 with numpy did not run (bench/model_map_numpy.py)");
    return;
  }
  for (auto _ : state) state.SetIterationTime(numpy["seconds"].get<double>());
  state.SetItemsProcessed(state.iterations() * numpy["points"].get<std::int64_t>());
}
BENCHMARK(BM_VolumetricMapNumpy)->UseManualTime()->Iterations(1)->Unit(benchmark::kMillisecond);

void BM_VolumetricMapMtcal(benchmark::State& state) {
  const auto& f = fixture();
  std::vector<Eigen::Vector3d> map;
  double best_s = 1e9;
  for (auto _ : state) {
    const auto start = std::chrono::steady_clock::now();
    map = f.model.predictGridUm(f.axes);
    best_s = std::min(best_s, std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
    benchmark::DoNotOptimize(map.data());
  }
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(map.size()));
  const auto numpy = runNumpy();
  if (!numpy.is_discarded()) {
    double max_diff = 0.0;
    for (const auto& [index, e] : numpy["sample"].items()) {
      const auto& mine = map[static_cast<std::size_t>(std::stoul(index))];
      for (int k = 0; k < 3; ++k) max_diff = std::max(max_diff, std::abs(mine(k) - e[k].get<double>()));
    }
    state.counters["max_diff_vs_numpy_um"] = max_diff;
    state.counters["speedup_vs_numpy"] = numpy["seconds"].get<double>() / best_s;
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
          benchmark::DoNotOptimize(f.model.predictUm(Eigen::Vector3d(f.axes[0][i], f.axes[1][j], f.axes[2][k * 10])));
          ++points;
        }
      }
    }
  }
  state.SetItemsProcessed(points);
}
BENCHMARK(BM_VolumetricMapPointByPoint)->Unit(benchmark::kMillisecond)->MinTime(2.0);

}  // namespace

BENCHMARK_MAIN();
