// The diagnosis (docs/diagnosis.md) of two campaigns of bench/diagnosis_study's generator: the
// 20 mm grid (210 readings, own baseline) and the dense plan against a model (600 readings),
// each with a hidden effect, against the reference of one least-squares solve of the first
// campaign's baseline in the same process: what the evidence, the candidates' searches, their
// tests and the cross-validation cost in such solves.

#include <benchmark/benchmark.h>

#include <Eigen/Dense>

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

}  // namespace
