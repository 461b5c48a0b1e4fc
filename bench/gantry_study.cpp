// A many-seed study of the gantry point accuracy test (docs/gantry.md), not a timing: the
// patent's 35 holes x 5 gantry positions on the simulated gantry, measured through the
// tracker emulator (its realistic noise, a new seed per repetition), evaluated three ways and
// compared with the machine's truth:
//   patent      three targets, the three-point frame, TCP0 from the A and C axes
//   tool-point  three targets, the three-point frame, TCP0 from the tool-point nest
//   5-lsq       five targets (TB1..TB5, wider apart), Umeyama, TCP0 from the tool-point nest
// Per way: rms and largest |dP - truth| over the holes, and the Monte Carlo U95 of |dP| the
// evaluation reports for itself (mean over holes).
//   ./build/bench/mtcal_study_gantry [repetitions=3] [trials=100]

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <cstdlib>
#include <fstream>
#include <nlohmann/json.hpp>

#include "../tests/support/gantry_session.h"

using namespace mtcal;

namespace {

struct Figures {
  double rms_um = 0.0, max_um = 0.0, mean_u95_um = 0.0, mean_truth_um = 0.0;
};

Figures compare(const mtcal::testing::GantrySession& s, const processing::GantryOptions& options, int trials,
                std::uint64_t seed) {
  const auto ev = processing::evaluateGantry(s.measured, options);
  const auto u = processing::monteCarloGantry(s.measured, options, processing::TrackerMpe{}, trials, seed);
  Figures f;
  for (std::size_t i = 0; i < s.holes.size(); ++i) {
    const Eigen::Vector3d truth = mtcal::testing::truthUm(s, ev, s.holes[i], s.measured.initial_np_mm);
    const double e = (ev.holes[i].dp_um - truth).norm();
    f.rms_um += e * e;
    f.max_um = std::max(f.max_um, e);
    f.mean_u95_um += u.holes[i].norm_u95_um;
    f.mean_truth_um += truth.norm();
  }
  const double n = static_cast<double>(s.holes.size());
  f.rms_um = std::sqrt(f.rms_um / n);
  f.mean_u95_um /= n;
  f.mean_truth_um /= n;
  return f;
}

}  // namespace

int main(int argc, char** argv) {
  spdlog::set_level(spdlog::level::warn);
  const int repetitions = argc > 1 ? std::atoi(argv[1]) : 3;
  const int trials = argc > 2 ? std::atoi(argv[2]) : 100;
  const std::string root = MTCAL_SOURCE_DIR;
  const auto machine_path = root + "/examples/machines/gantry-drilling.json";
  const auto config =
      mocks::VirtualMachineConfig::fromJson(nlohmann::json::parse(std::ifstream(machine_path)), machine_path);
  const auto plan_path = root + "/examples/plans/gantry/point-accuracy-35x5.json";
  auto plan = acquisition::GantryPlan::fromJson(nlohmann::json::parse(std::ifstream(plan_path)), plan_path);
  plan.monte_carlo_trials = 0;
  auto wide = plan;
  wide.targets = {"TB1", "TB2", "TB3", "TB4", "TB5"};
  mocks::TrackerNoise noise;  // the emulator's defaults, outliers included
  fmt::print("{:>4} {:<11} {:>12} {:>12} {:>14} {:>14}\n", "seed", "way", "rms err um", "max err um", "mean U95 um",
             "mean |dP| um");
  for (int r = 1; r <= repetitions; ++r) {
    const auto three = mtcal::testing::runSession(plan, config, noise, {}, static_cast<std::uint64_t>(r), 400.0);
    const auto five = mtcal::testing::runSession(wide, config, noise, {}, static_cast<std::uint64_t>(r), 400.0);
    const std::pair<const char*, Figures> rows[] = {
        {"patent", compare(three, {}, trials, r)},
        {"tool-point", compare(three, {.tcp0 = processing::Tcp0Source::kToolPoint}, trials, r)},
        {"5-lsq", compare(five, {.tcp0 = processing::Tcp0Source::kToolPoint}, trials, r)}};
    for (const auto& [way, f] : rows) {
      fmt::print("{:>4} {:<11} {:>12.1f} {:>12.1f} {:>14.1f} {:>14.1f}\n", r, way, f.rms_um, f.max_um, f.mean_u95_um,
                 f.mean_truth_um);
    }
  }
  return 0;
}
