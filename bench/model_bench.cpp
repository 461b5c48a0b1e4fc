// Volumetric error map of a 3-axis error model on a 100 x 100 x 100 grid, and a full
// identification (18 measured lines of the direct method on the patent's grid, 50-600 mm every
// 20 mm: 21 errors), each against a straightforward numpy implementation of the same
// computation (bench/model_map_numpy.py, bench/model_identify_numpy.py), run by this program
// on the same data. Also the point-by-point full model as the reference of what the grid
// evaluation saves.

#include <benchmark/benchmark.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <random>

#include "mtcal/acquisition/error_models.h"
#include "python_reference.h"
#include "mtcal/processing/line_identification.h"

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
    nlohmann::json functions;
    for (const auto& f : fixture().model.functions()) functions[f.name()] = f.toJson();
    return runPython("model_map_numpy.py",
                     {{"machine", fixture().machine}, {"functions", functions}, {"axes", fixture().axes}},
                     std::to_string(kGrid) + " 3");
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

// The direct method's 18 lines (docs/multibody-model.md) on the fixture's error model as the
// truth, read through the full model with 0.05 um / 0.05 urad of seeded noise per node.
const std::vector<processing::MeasuredLine>& identificationLines() {
  static const auto lines = [] {
    const auto& model = fixture().model;
    const auto& m = model.kinematics();
    const Eigen::Vector3d home(300, 200, 150), off(0, 25, 45);
    struct Spec {
      const char* measures;
      int axis, component;
      Eigen::Vector3d offset;
    };
    const std::vector<Spec> specs = {
        {"EXX", 0, 0, off}, {"EYX", 0, 1, off}, {"EZX", 0, 2, off}, {"EBX", 0, 4, off}, {"ECX", 0, 5, off},
        {"EYY", 1, 1, off}, {"EXY", 1, 0, off}, {"EZY", 1, 2, off}, {"EAY", 1, 3, off}, {"ECY", 1, 5, off},
        {"EZZ", 2, 2, off}, {"EXZ", 2, 0, off}, {"EYZ", 2, 1, off}, {"EAZ", 2, 3, off}, {"EBZ", 2, 4, off},
        {"EZX", 0, 2, Eigen::Vector3d(0, 225, 45)}, {"EZY", 1, 2, Eigen::Vector3d(150, 25, 45)},
        {"EXZ", 2, 0, Eigen::Vector3d(0, 125, 45)}};
    std::mt19937_64 rng(3);
    std::normal_distribution<double> noise(0.0, 0.05);
    std::vector<processing::MeasuredLine> out;
    for (const auto& spec : specs) {
      processing::MeasuredLine line;
      line.id = spec.measures;
      line.measures = spec.measures;
      line.coordinate = spec.axis;
      line.q = home;
      line.point_mm = m.toolPoint() + spec.offset;
      line.component = spec.component;
      for (double x = 50.0; x <= 600.0 + 1e-9; x += 20.0) {
        Eigen::VectorXd q = home;
        q(spec.axis) = x;
        const Eigen::VectorXd e = model.errorsAt(q);
        const Eigen::VectorXd zero = Eigen::VectorXd::Zero(e.size());
        const double reading = spec.component < 3
                                   ? (m.actualPoint(q, e, line.point_mm) - m.actualPoint(q, zero, line.point_mm))(spec.component) * 1000.0
                                   : m.orientationErrorUrad(q, e)(spec.component - 3);
        line.position_mm.push_back(x);
        line.mean.push_back(reading + noise(rng));
        line.s.push_back(0.3);
        line.repeats.push_back(18);
      }
      out.push_back(std::move(line));
    }
    return out;
  }();
  return lines;
}

nlohmann::json runNumpyIdentification() {
  static nlohmann::json result = [] {
    nlohmann::json lines = nlohmann::json::array();
    for (const auto& l : identificationLines()) {
      std::vector<double> s;
      for (const auto& v : l.s) s.push_back(*v);
      lines.push_back({{"measures", l.measures},
                       {"coordinate", l.coordinate},
                       {"q", std::vector<double>(l.q.data(), l.q.data() + l.q.size())},
                       {"point_mm", std::vector<double>(l.point_mm.data(), l.point_mm.data() + 3)},
                       {"component", l.component},
                       {"position_mm", l.position_mm},
                       {"mean", l.mean},
                       {"s", s}});
    }
    return runPython("model_identify_numpy.py", {{"machine", fixture().machine}, {"lines", lines}}, "3");
  }();
  return result;
}

void BM_IdentificationNumpy(benchmark::State& state) {
  const auto numpy = runNumpyIdentification();
  if (numpy.is_discarded()) {
    state.SkipWithError("python3 with numpy did not run (bench/model_identify_numpy.py)");
    return;
  }
  for (auto _ : state) state.SetIterationTime(numpy["seconds"].get<double>());
}
BENCHMARK(BM_IdentificationNumpy)->UseManualTime()->Iterations(1)->Unit(benchmark::kMillisecond);

void BM_IdentificationMtcal(benchmark::State& state) {
  const auto& lines = identificationLines();
  processing::LineIdentification id;
  double best_s = 1e9;
  for (auto _ : state) {
    const auto start = std::chrono::steady_clock::now();
    id = processing::identifyFromLines(fixture().model.kinematics(), lines, {});
    best_s = std::min(best_s, std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
    benchmark::DoNotOptimize(id.curves.data());
  }
  state.counters["errors"] = static_cast<double>(id.curves.size());
  const auto numpy = runNumpyIdentification();
  if (!numpy.is_discarded()) {
    double max_diff = 0.0;
    std::size_t compared = 0;
    for (const auto& c : id.curves) {
      if (!numpy["curves"].contains(c.name)) continue;
      const auto& theirs = numpy["curves"][c.name];
      for (std::size_t n = 0; n < c.mean.size() && n < theirs.size(); ++n) {
        max_diff = std::max(max_diff, std::abs(c.mean[n] - theirs[n].get<double>()));
      }
      ++compared;
    }
    state.counters["errors_compared"] = static_cast<double>(compared);
    state.counters["max_diff_vs_numpy"] = max_diff;
    state.counters["speedup_vs_numpy"] = numpy["seconds"].get<double>() / best_s;
  }
}
BENCHMARK(BM_IdentificationMtcal)->Unit(benchmark::kMillisecond)->MinTime(2.0);

}  // namespace

BENCHMARK_MAIN();
