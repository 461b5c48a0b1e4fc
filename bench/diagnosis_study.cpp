// A study, not a timing: the diagnosis (processing/diagnosis.h) over many campaigns with hidden effects
// (mocks/hidden_effects.h). For every seed a campaign hides none, one or two effects with
// random magnitudes; the pipeline is not told which. Reported: the false-alarm rate (any
// finding on effect-free data), the detection rate of each effect, how often another cause is
// named, the error of each effect's parameter, and the held-out gain. Figures go to
// docs/diagnosis.md.
//
//   mtcal_study_diagnosis [CAMPAIGNS=300] [FIRST_SEED=1] [EFFECT_FREE_CAMPAIGNS=500]
//   mtcal_study_diagnosis csv SEED EFFECT[,EFFECT] [grid|dense]   (one campaign as CSV)

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <map>
#include <string>
#include <vector>

#include "mtcal/mocks/hidden_effects.h"
#include "mtcal/processing/diagnosis.h"

namespace {

using mtcal::mocks::HiddenEffect;

/// The parameter compared with the truth, per effect.
const std::map<std::string, std::string> kMainParameter = {{"backlash", "reversal"},
                                                           {"cyclic_error", "amplitude"},
                                                           {"thermal_drift", "drift_over_run"},
                                                           {"environment_compensation", "air_temp_coefficient"},
                                                           {"scale_error", "scale"},
                                                           {"abbe_error", "offset"}};

double median(std::vector<double> v) {
  if (v.empty()) return NAN;
  std::sort(v.begin(), v.end());
  return v.size() % 2 ? v[v.size() / 2] : 0.5 * (v[v.size() / 2 - 1] + v[v.size() / 2]);
}
double quantile(std::vector<double> v, double q) {
  if (v.empty()) return NAN;
  std::sort(v.begin(), v.end());
  return v[static_cast<std::size_t>(std::min<double>(v.size() - 1, std::floor(q * static_cast<double>(v.size()))))];
}

/// Effects smaller than this (RMS of what they add, um) are counted apart, in two bins split
/// at kTinyUm: the readings' scatter is 0.5 um per approach.
constexpr double kSmallUm = 0.25, kTinyUm = 0.1;

struct Tally {
  int hidden = 0, found = 0, warned = 0, aliased = 0;
  int small = 0, small_found = 0, tiny = 0, tiny_found = 0;
  std::vector<double> relative_error;
};

}  // namespace

int main(int argc, char** argv) {
  // mtcal_study_diagnosis csv SEED EFFECT[,EFFECT...] [grid|dense]: one campaign as the CSV
  // `mtcal import linear` reads (examples/diagnosis).
  if (argc > 1 && std::string(argv[1]) == "csv") {
    mtcal::mocks::CampaignRequest request;
    request.seed = argc > 2 ? std::strtoull(argv[2], nullptr, 10) : 1;
    request.random = false;
    if (argc > 3) {
      std::string list = argv[3];
      for (std::size_t start = 0; start <= list.size();) {
        const auto end = std::min(list.find(',', start), list.size());
        if (end > start) request.effects.push_back(list.substr(start, end - start));
        start = end + 1;
      }
    }
    request.with_model = 0;
    request.grid_plan = argc > 4 && std::string(argv[4]) == "dense" ? 0 : 1;
    const auto campaign = mtcal::mocks::makeLinearCampaign(request);
    for (const auto& h : campaign.truth) {
      fmt::print("# hidden: {}", h.effect);
      for (const auto& [name, value] : h.parameters) fmt::print(" {}={:.4g}", name, value);
      fmt::print("\n");
    }
    if (campaign.truth.empty()) fmt::print("# hidden: nothing\n");
    fmt::print("{}", mtcal::mocks::linearCampaignCsv(campaign));
    return 0;
  }
  const int campaigns = argc > 1 ? std::atoi(argv[1]) : 300;
  const std::uint64_t first = argc > 2 ? std::strtoull(argv[2], nullptr, 10) : 1;
  int clean = 0, clean_alarms = 0, with_effects = 0, wrong_named = 0;
  std::map<std::string, Tally> tally;
  std::map<std::string, int> false_alarm_effects, wrong_effects;
  std::vector<double> gains, seconds;
  for (int k = 0; k < campaigns; ++k) {
    mtcal::mocks::CampaignRequest request;
    request.seed = first + static_cast<std::uint64_t>(k);
    const auto campaign = mtcal::mocks::makeLinearCampaign(request);
    const auto start = std::chrono::steady_clock::now();
    const auto data = mtcal::processing::linearDiagnosisData(campaign.run);
    const auto result = mtcal::processing::diagnose(data);
    seconds.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
    if (std::getenv("MTCAL_STUDY_VERBOSE")) {
      fmt::print("seed {} model {} grid {}:", campaign.seed, campaign.with_model, campaign.grid_plan);
      for (const auto& h : campaign.truth) {
        fmt::print(" [{}", h.effect);
        for (const auto& [n, v] : h.parameters) fmt::print(" {}={:.3g}", n, v);
        fmt::print("]");
      }
      fmt::print(" ->");
      for (const auto& f : result.findings) {
        fmt::print(" <{} {} dBIC {:.1f} p {:.2g}", f.candidate.effect, f.candidate.variable, f.delta_bic, f.p_value);
        for (const auto& p : f.parameters) fmt::print(" {}={:.3g}", p.name, p.value);
        fmt::print(">");
      }
      fmt::print("\n");
      if (const char* trace = std::getenv("MTCAL_STUDY_TRACE");
          trace && std::strtoull(trace, nullptr, 10) == campaign.seed) {
        for (const auto& c : result.considered) {
          fmt::print("  round {} {} ({}): delta BIC {:.1f}, p {:.2g}, held out {:.3f}: {}\n", c.round, c.effect,
                     c.variable, c.delta_bic, c.p_value, c.heldout_rms_um, c.verdict);
        }
      }
    }
    if (campaign.truth.empty()) {
      ++clean;
      if (!result.findings.empty()) {
        ++clean_alarms;
        for (const auto& f : result.findings) ++false_alarm_effects[f.candidate.effect];
      }
      continue;
    }
    ++with_effects;
    gains.push_back(result.gain);
    bool wrong = false;
    for (const auto& f : result.findings) {
      const bool hidden = std::any_of(campaign.truth.begin(), campaign.truth.end(),
                                      [&](const HiddenEffect& h) { return h.effect == f.candidate.effect; });
      if (!hidden) {
        wrong = true;
        ++wrong_effects[f.candidate.effect];
      }
    }
    wrong_named += wrong;
    for (const auto& h : campaign.truth) {
      auto& t = tally[h.effect];
      const bool aliased = h.effect == "cyclic_error" && campaign.grid_plan;
      if (aliased) {
        ++t.aliased;
        const bool warned = std::any_of(result.warnings.begin(), result.warnings.end(),
                                        [](const std::string& w) { return w.find("cyclic") != std::string::npos; });
        t.warned += warned;
        continue;
      }
      const double size = h.parameters.at("size_rms");
      if (size < kSmallUm) {
        const bool found = std::any_of(result.findings.begin(), result.findings.end(),
                                       [&](const auto& f) { return f.candidate.effect == h.effect; });
        (size < kTinyUm ? t.tiny : t.small) += 1;
        (size < kTinyUm ? t.tiny_found : t.small_found) += found;
        continue;
      }
      ++t.hidden;
      for (const auto& f : result.findings) {
        if (f.candidate.effect != h.effect) continue;
        ++t.found;
        const auto& name = kMainParameter.at(h.effect);
        for (const auto& p : f.parameters) {
          if (p.name == name)
            t.relative_error.push_back(std::abs(p.value - h.parameters.at(name)) / std::abs(h.parameters.at(name)));
        }
        break;
      }
    }
  }
  // Effect-free campaigns only, for the false-alarm rate: half with a model, half on the grid.
  const int clean_only = argc > 3 ? std::atoi(argv[3]) : 500;
  int clean_only_alarms = 0;
  std::map<std::string, int> clean_only_effects;
  for (int k = 0; k < clean_only; ++k) {
    mtcal::mocks::CampaignRequest request;
    request.seed = 1000000 + first + static_cast<std::uint64_t>(k);
    request.random = false;
    request.with_model = k % 2;
    request.grid_plan = (k / 2) % 2;
    const auto result = mtcal::processing::diagnose(
        mtcal::processing::linearDiagnosisData(mtcal::mocks::makeLinearCampaign(request).run));
    clean_only_alarms += !result.findings.empty();
    for (const auto& f : result.findings) ++clean_only_effects[f.candidate.effect];
  }
  fmt::print("campaigns {} (seeds {}..{}), {:.1f} ms median per diagnosis\n\n", campaigns, first,
             first + static_cast<std::uint64_t>(campaigns) - 1, 1e3 * median(seconds));
  fmt::print("effect-free campaigns: {}, with any finding: {} ({:.1f} %)", clean, clean_alarms,
             clean ? 100.0 * clean_alarms / clean : 0.0);
  for (const auto& [e, count] : false_alarm_effects) fmt::print(" {}:{}", e, count);
  if (clean_only > 0) {
    // Wilson's 95 % interval of the rate.
    const double n = clean_only, p = clean_only_alarms / n, z = 1.96;
    const double centre = (p + z * z / (2 * n)) / (1 + z * z / n),
                 half = z / (1 + z * z / n) * std::sqrt(p * (1 - p) / n + z * z / (4 * n * n));
    fmt::print(
        "\neffect-free campaigns only (seeds {}..): {}, with any finding: {} ({:.1f} %, 95 % interval {:.1f}..{:.1f} "
        "%)",
        1000000 + first, clean_only, clean_only_alarms, 100.0 * p, 100.0 * std::max(0.0, centre - half),
        100.0 * (centre + half));
    for (const auto& [e, count] : clean_only_effects) fmt::print(" {}:{}", e, count);
  }
  fmt::print("\ncampaigns with effects: {}, naming a cause that was not hidden: {} ({:.1f} %)", with_effects,
             wrong_named, with_effects ? 100.0 * wrong_named / with_effects : 0.0);
  for (const auto& [e, count] : wrong_effects) fmt::print(" {}:{}", e, count);
  fmt::print("\nmedian held-out gain where effects were hidden: {:.1f} %\n\n", 100.0 * median(gains));
  fmt::print(
      "| effect | hidden, size >= {} um | found | rate | parameter | median rel. error | 90 % rel. error | {}..{} um: "
      "found | < {} um: found | aliased by the grid: warned |\n",
      kSmallUm, kTinyUm, kSmallUm, kTinyUm);
  fmt::print("|---|---|---|---|---|---|---|---|---|---|\n");
  for (const auto& [effect, t] : tally) {
    fmt::print("| {} | {} | {} | {:.1f} % | {} | {:.1f} % | {:.1f} % | {} | {} | {} |\n", effect, t.hidden, t.found,
               t.hidden ? 100.0 * t.found / t.hidden : 0.0, kMainParameter.at(effect), 100.0 * median(t.relative_error),
               100.0 * quantile(t.relative_error, 0.9),
               t.small ? fmt::format("{} of {}", t.small_found, t.small) : std::string("-"),
               t.tiny ? fmt::format("{} of {}", t.tiny_found, t.tiny) : std::string("-"),
               t.aliased ? fmt::format("{} of {}", t.warned, t.aliased) : std::string("-"));
  }
  return 0;
}
