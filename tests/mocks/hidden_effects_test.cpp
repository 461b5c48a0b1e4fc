#include "mtcal/mocks/hidden_effects.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "mtcal/error.h"
#include "mtcal/processing/diagnosis.h"

namespace mtcal::mocks {
namespace {

TEST(HiddenEffects, TheSameSeedGivesTheSameCampaign) {
  CampaignRequest request;
  request.seed = 17;
  const auto a = makeLinearCampaign(request), b = makeLinearCampaign(request);
  EXPECT_EQ(a.run.deviation_um, b.run.deviation_um);
  EXPECT_EQ(a.run.position_mm, b.run.position_mm);
  ASSERT_EQ(a.truth.size(), b.truth.size());
  request.seed = 18;
  EXPECT_NE(makeLinearCampaign(request).run.deviation_um, a.run.deviation_um);
  request.random = false;
  request.effects = {"warp_drive"};
  EXPECT_THROW(makeLinearCampaign(request), InputError);
}

/// The main parameter of each effect and the tolerance of its relative error.
double relativeTolerance(const std::string& effect) {
  return effect == "environment_compensation" || effect == "abbe_error" ? 0.5 : 0.2;
}
const char* mainParameter(const std::string& effect) {
  if (effect == "backlash") return "reversal";
  if (effect == "cyclic_error") return "amplitude";
  if (effect == "thermal_drift") return "drift_over_run";
  if (effect == "environment_compensation") return "air_temp_coefficient";
  if (effect == "scale_error") return "scale";
  return "offset";
}

// 24 campaigns drawn at random (none, one or two effects, random sizes, with or without a
// model, grid or dense plan); the diagnosis is not told what was hidden. Backlash, cyclic
// error (where the plan can see it), scale error and thermal drift must be named with their
// size within 20 % (35 % when two effects are hidden); the weaker environment-compensation
// and Abbe errors, when named, within 50 % (88 %); effect-free campaigns and wrong names are rare; a cyclic error hidden from a 20 mm grid
// is warned about. The many-seed figures are bench/diagnosis_study's (docs/diagnosis.md).
TEST(HiddenEffects, TheDiagnosisNamesWhatWasHidden) {
  int effect_free = 0, effect_free_alarms = 0, wrong_names = 0, checked = 0;
  for (std::uint64_t seed = 1; seed <= 24; ++seed) {
    CampaignRequest request;
    request.seed = seed;
    const auto c = makeLinearCampaign(request);
    const auto d = processing::diagnose(processing::linearDiagnosisData(c.run));
    SCOPED_TRACE("seed " + std::to_string(seed));
    if (c.truth.empty()) {
      ++effect_free;
      effect_free_alarms += !d.findings.empty();
      continue;
    }
    for (const auto& f : d.findings) {
      const bool hidden = std::any_of(c.truth.begin(), c.truth.end(), [&](const HiddenEffect& h) { return h.effect == f.candidate.effect; });
      wrong_names += !hidden;
      EXPECT_GT(f.gain, 0.0) << f.candidate.effect;
    }
    for (const auto& h : c.truth) {
      if (h.effect == "cyclic_error" && c.grid_plan) {
        EXPECT_TRUE(std::any_of(d.warnings.begin(), d.warnings.end(), [](const std::string& w) { return w.find("cyclic") != std::string::npos; }));
        continue;
      }
      const auto it = std::find_if(d.findings.begin(), d.findings.end(), [&](const processing::Finding& f) { return f.candidate.effect == h.effect; });
      const bool must = h.effect != "environment_compensation" && h.effect != "abbe_error";
      if (it == d.findings.end()) {
        EXPECT_FALSE(must) << h.effect << " not named";
        continue;
      }
      const std::string name = mainParameter(h.effect);
      for (const auto& p : it->parameters) {
        if (p.name != name) continue;
        ++checked;
        const double truth = h.parameters.at(name);
        // Two effects hidden at once share part of their signatures: 1.75 x the tolerance.
        const double tolerance = relativeTolerance(h.effect) * (c.truth.size() > 1 ? 1.75 : 1.0);
        EXPECT_NEAR(p.value, truth, tolerance * std::abs(truth)) << h.effect << " " << name;
      }
    }
  }
  EXPECT_GE(effect_free, 4);
  EXPECT_LE(effect_free_alarms, 1);
  EXPECT_LE(wrong_names, 1);
  EXPECT_GE(checked, 12);
}

}  // namespace
}  // namespace mtcal::mocks
