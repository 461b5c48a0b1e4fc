// The diagnosis (docs/diagnosis.md) of two campaigns of bench/diagnosis_study's generator: the
// 20 mm grid (210 readings, own baseline) and the dense plan against a model (600 readings),
// each with a hidden effect, against the reference of one least-squares solve of the first
// campaign's baseline in the same process: what the evidence, the candidates' searches, their
// tests and the cross-validation cost in such solves. A campaign's runs of several errors in one
// fit against the same runs diagnosed apart.

#include <benchmark/benchmark.h>
#include <fmt/format.h>

#include <Eigen/Dense>
#include <cmath>
#include <map>
#include <random>

#include "mtcal/mocks/hidden_effects.h"
#include "mtcal/processing/diagnosis.h"

namespace {

using namespace mtcal;

const processing::DiagnosisData& campaign(int which) {
  static const auto make = [](bool grid, const char* effect) {
    mocks::CampaignRequest request;
    request.seed = 7;
    request.random = false;
    request.effects = {effect};
    request.grid_plan = grid ? 1 : 0;
    request.with_model = grid ? 0 : 1;
    return processing::linearDiagnosisData(mocks::makeLinearCampaign(request).run);
  };
  static const processing::DiagnosisData grid = make(true, "backlash"), dense = make(false, "cyclic_error");
  return which == 0 ? grid : dense;
}

void BM_DiagnosisReferenceOneSolve(benchmark::State& state) {
  const auto& d = campaign(0);
  for (auto _ : state) benchmark::DoNotOptimize(d.baseline.colPivHouseholderQr().solve(d.measured).eval());
}
BENCHMARK(BM_DiagnosisReferenceOneSolve)->Unit(benchmark::kMicrosecond);

void BM_Diagnose(benchmark::State& state) {
  const auto& d = campaign(static_cast<int>(state.range(0)));
  for (auto _ : state) benchmark::DoNotOptimize(processing::diagnose(d).gain);
  state.SetLabel(state.range(0) == 0 ? "grid 210 readings, own baseline, backlash"
                                     : "dense 600 readings, model, cyclic error");
}
BENCHMARK(BM_Diagnose)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

/// A dense imported run of `readings` readings: a laser read on the fly along 0..400 mm, five
/// bidirectional passes, every reading at its own position (1 kHz), with an error curve, a
/// reversal of 2 um, a drift and the air's temperature; 0.5 um of scatter.
const processing::LinearRunInput& denseRun(std::int64_t readings) {
  static std::map<std::int64_t, processing::LinearRunInput> runs;
  auto& run = runs[readings];
  if (!run.position_mm.empty()) return run;
  std::mt19937_64 rng(static_cast<std::uint64_t>(readings));
  std::normal_distribution<double> scatter(0.0, 0.5);
  const std::int64_t per_pass = readings / 10;
  std::vector<double> air;
  for (std::int64_t i = 0; i < readings; ++i) {
    const std::int64_t pass = i / per_pass, k = i % per_pass;
    const int direction = pass % 2 ? -1 : 1;
    const double x = 400.0 * (direction > 0 ? k : per_pass - 1 - k) / static_cast<double>(per_pass - 1);
    const double t = 1e-3 * static_cast<double>(i);
    run.position_mm.push_back(x);
    run.direction.push_back(direction);
    run.cycle.push_back(static_cast<int>(pass / 2) + 1);
    run.time_s.push_back(t);
    run.deviation_um.push_back(3.0 * std::sin(x / 70.0) + 1e-3 * x + direction + 2.0 * (1.0 - std::exp(-t / 30.0)) +
                               scatter(rng));
    air.push_back(20.0 + 0.3 * std::sin(t / 20.0));
  }
  run.source = fmt::format("{} readings", readings);
  run.channels = {{"air_temp_c", "degC", Eigen::Map<const Eigen::VectorXd>(air.data(), readings)}};
  return run;
}

// The whole diagnosis (the data's preparation included) of a dense run of 1e3 .. 1e6 readings.
void BM_DiagnoseReadings(benchmark::State& state) {
  const auto& run = denseRun(state.range(0));
  std::size_t findings = 0;
  for (auto _ : state) {
    const auto result = processing::diagnose(processing::linearDiagnosisData(run));
    findings = result.findings.size();
    benchmark::DoNotOptimize(result.gain);
  }
  state.SetComplexityN(state.range(0));
  state.counters["readings"] = static_cast<double>(state.range(0));
  state.counters["findings"] = static_cast<double>(findings);
}
BENCHMARK(BM_DiagnoseReadings)
    ->Arg(1000)
    ->Arg(10000)
    ->Arg(100000)
    ->Arg(1000000)
    ->Unit(benchmark::kSecond)
    ->Iterations(1)
    ->Complexity(benchmark::oN);

/// `count` runs of a campaign, each of its own error of the axes (EXX, EYX, EZX, EYY, ...; the
/// generator's 20 mm grid with a backlash, seed 11 on), as `diagnose cN` pools them: one fit,
/// each run its own causes.
const std::vector<processing::DiagnosisData>& campaignRuns(std::int64_t count) {
  static std::map<std::int64_t, std::vector<processing::DiagnosisData>> made;
  auto& runs = made[count];
  if (!runs.empty()) return runs;
  static const char* const errors[] = {"EXX", "EYX", "EZX", "EYY", "EXY", "EZY", "EZZ", "EXZ", "EYZ"};
  for (std::int64_t k = 0; k < count; ++k) {
    mocks::CampaignRequest request;
    request.seed = 11 + static_cast<std::uint64_t>(k);
    request.random = false;
    request.effects = {"backlash"};
    request.grid_plan = 1;
    request.with_model = 0;
    auto run = mocks::makeLinearCampaign(request).run;
    run.source = fmt::format("run {}", k + 1);
    run.measures = errors[k % 9];
    runs.push_back(processing::linearDiagnosisData(run));
  }
  return runs;
}

// The reference: each of the campaign's runs diagnosed on its own, one after the other.
void BM_DiagnoseCampaignRunsApart(benchmark::State& state) {
  const auto& runs = campaignRuns(state.range(0));
  for (auto _ : state) {
    for (const auto& run : runs) benchmark::DoNotOptimize(processing::diagnose(run).gain);
  }
  state.counters["runs"] = static_cast<double>(state.range(0));
}
BENCHMARK(BM_DiagnoseCampaignRunsApart)->Arg(3)->Arg(6)->Arg(12)->Unit(benchmark::kMillisecond);

// The same runs in one fit (the pooling included).
void BM_DiagnoseCampaignRunsInOneFit(benchmark::State& state) {
  const auto& runs = campaignRuns(state.range(0));
  for (auto _ : state) benchmark::DoNotOptimize(processing::diagnose(processing::poolDiagnosisData(runs)).gain);
  state.counters["runs"] = static_cast<double>(state.range(0));
}
BENCHMARK(BM_DiagnoseCampaignRunsInOneFit)->Arg(3)->Arg(6)->Arg(12)->Unit(benchmark::kMillisecond);

}  // namespace
