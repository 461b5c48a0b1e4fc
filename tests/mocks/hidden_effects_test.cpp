#include "mtcal/mocks/hidden_effects.h"

#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <functional>
#include <map>
#include <numbers>
#include <numeric>
#include <stdexcept>
#include <string>
#include <type_traits>

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

TEST(HiddenEffects, AGivenSizeChangesOnlyThatEffect) {
  CampaignRequest request;
  request.seed = 5;
  request.random = false;
  request.effects = {"environment_compensation"};
  request.grid_plan = 0;
  const auto drawn = makeLinearCampaign(request);
  request.sizes["environment_compensation"] = 2.5;
  const auto given = makeLinearCampaign(request);
  ASSERT_EQ(given.truth.size(), 1u);
  EXPECT_EQ(given.truth[0].parameters.at("air_temp_coefficient"), 2.5);
  EXPECT_NE(drawn.truth[0].parameters.at("air_temp_coefficient"), 2.5);
  // The plan, the times and the air are those of the seed: only the effect's size differs.
  EXPECT_EQ(given.run.position_mm, drawn.run.position_mm);
  EXPECT_EQ(given.run.time_s, drawn.run.time_s);
  EXPECT_TRUE(given.run.channels.at(0).values == drawn.run.channels.at(0).values);
  EXPECT_NE(given.run.deviation_um, drawn.run.deviation_um);
  // A size for an effect that is not hidden, or for a random campaign, is refused.
  request.sizes = {{"abbe_error", 50.0}};
  EXPECT_THROW(makeLinearCampaign(request), InputError);
  request.random = true;
  request.sizes = {{"environment_compensation", 2.5}};
  EXPECT_THROW(makeLinearCampaign(request), InputError);
}

// What a campaign says each effect adds is what its readings carry. The same seed with one
// effect's size doubled differs, reading by reading, by the change of what it says that effect
// adds (the growth: its part along the travel doubles, its datum's drift, the simpler part, is
// drawn the same); and the readings less every effect's addition scatter, between the cycles
// at a position and direction, by the noise the campaign gives.
TEST(HiddenEffects, WhatEachEffectAddsIsWhatTheReadingsCarry) {
  CampaignRequest request;
  request.seed = 8;
  request.random = false;
  request.effects = {"thermal_growth", "backlash"};
  request.with_model = 0;
  request.grid_plan = 1;
  const auto campaignWith = [&](double growth_ppm, double lost_motion_um) {
    request.sizes = {{"thermal_growth", growth_ppm}, {"backlash", lost_motion_um}};
    return makeLinearCampaign(request);
  };
  const auto base = campaignWith(6.0, 3.0), growth_twice = campaignWith(12.0, 3.0),
             backlash_twice = campaignWith(6.0, 6.0);
  const auto& growth = base.added_um.at("thermal_growth");
  const auto& datum = base.simpler_part_um.at("thermal_growth");
  const auto& backlash = base.added_um.at("backlash");
  ASSERT_EQ(growth.size(), base.run.deviation_um.size());
  ASSERT_EQ(backlash.size(), base.run.deviation_um.size());
  EXPECT_EQ(datum, growth_twice.simpler_part_um.at("thermal_growth"));
  EXPECT_EQ(base.simpler_part_um.count("backlash"), 0u);
  double largest_growth_um = 0.0, largest_backlash_um = 0.0;
  for (std::size_t i = 0; i < growth.size(); ++i) {
    const double along_travel_um = growth[i] - datum[i];
    EXPECT_NEAR(growth_twice.added_um.at("thermal_growth")[i] - datum[i], 2.0 * along_travel_um, 1e-12) << i;
    EXPECT_NEAR(growth_twice.run.deviation_um[i] - base.run.deviation_um[i],
                growth_twice.added_um.at("thermal_growth")[i] - growth[i], 1e-9)
        << i;
    EXPECT_NEAR(backlash_twice.run.deviation_um[i] - base.run.deviation_um[i],
                backlash_twice.added_um.at("backlash")[i] - backlash[i], 1e-9)
        << i;
    largest_growth_um = std::max(largest_growth_um, std::abs(along_travel_um));  // 6 ppm over 400 mm: 2.4 um at most
    largest_backlash_um = std::max(largest_backlash_um, std::abs(backlash[i]));
  }
  EXPECT_GT(largest_growth_um, 0.5);
  EXPECT_LE(largest_growth_um, 2.4);
  EXPECT_GT(largest_backlash_um, 0.5);  // half the reversal of a 3 um lost motion
  // The rest is the machine's own error at the position and direction, and the noise: over 10
  // seeds (1680 degrees of freedom) the scatter's variance is the noise's to 1 +- 0.035.
  double ss = 0.0, dof = 0.0;
  for (std::uint64_t seed = 8; seed < 18; ++seed) {
    request.seed = seed;
    const auto c = campaignWith(6.0, 3.0);
    std::map<std::pair<double, int>, std::vector<double>> rest;
    for (std::size_t i = 0; i < c.run.deviation_um.size(); ++i)
      rest[{c.run.position_mm[i], c.run.direction[i]}].push_back(
          c.run.deviation_um[i] - c.added_um.at("thermal_growth")[i] - c.added_um.at("backlash")[i]);
    for (const auto& [where, values] : rest) {
      const double mean = std::accumulate(values.begin(), values.end(), 0.0) / static_cast<double>(values.size());
      for (const double v : values) ss += (v - mean) * (v - mean);
      dof += static_cast<double>(values.size()) - 1.0;
    }
  }
  ASSERT_EQ(dof, 10 * 21.0 * 2.0 * 4.0);  // 21 positions, 2 directions, 5 cycles
  const double ratio = ss / dof / (base.reading_noise_um * base.reading_noise_um);
  EXPECT_GT(ratio, 0.9);
  EXPECT_LT(ratio, 1.1);
}

// The covariance a campaign gives of its model's own error is that error's. Over 100 effect-free
// campaigns with a model on the dense plan (100 positions between the model's nodes, 20 mm
// apart), the positions' mean readings less the model, whitened by the covariance the campaign
// gives (the model's error there and the noise of a mean of 6 readings), have a variance of 1
// and no correlation between neighbours. Whitened by the noise alone, neighbours (about 4 mm apart)
// share the model's smooth error: their correlation is far from 0.
TEST(HiddenEffects, TheModelsOwnErrorHasTheCovarianceTheCampaignGives) {
  double square_sum = 0.0, neighbour_sum = 0.0, noise_alone_square_sum = 0.0, noise_alone_neighbour_sum = 0.0;
  int squares = 0, neighbours = 0;
  for (std::uint64_t seed = 1; seed <= 100; ++seed) {
    CampaignRequest request;
    request.seed = seed;
    request.random = false;
    request.with_model = 1;
    request.grid_plan = 0;
    const auto c = makeLinearCampaign(request);
    std::map<double, std::vector<std::size_t>> readings_at;
    for (std::size_t i = 0; i < c.run.position_mm.size(); ++i) readings_at[c.run.position_mm[i]].push_back(i);
    const auto positions = static_cast<Eigen::Index>(readings_at.size());
    Eigen::VectorXd mean_um(positions);
    Eigen::MatrixXd covariance_um2(positions, positions);
    std::vector<std::size_t> first;
    for (const auto& [x, rows] : readings_at) {
      double sum = 0.0;
      for (const auto i : rows) sum += c.run.deviation_um[i] - c.run.simulated_um[i];
      mean_um(static_cast<Eigen::Index>(first.size())) = sum / static_cast<double>(rows.size());
      first.push_back(rows.front());
    }
    const double mean_noise_um2 = c.reading_noise_um * c.reading_noise_um / 6.0;
    for (Eigen::Index a = 0; a < positions; ++a) {
      ASSERT_EQ(readings_at.at(c.run.position_mm[first[static_cast<std::size_t>(a)]]).size(), 6u);
      for (Eigen::Index b = 0; b < positions; ++b)
        covariance_um2(a, b) =
            c.model_error_covariance_um2(static_cast<Eigen::Index>(first[static_cast<std::size_t>(a)]),
                                         static_cast<Eigen::Index>(first[static_cast<std::size_t>(b)]));
      covariance_um2(a, a) += mean_noise_um2;
    }
    const Eigen::VectorXd whitened = covariance_um2.llt().matrixL().solve(mean_um);
    const Eigen::VectorXd noise_alone = mean_um / std::sqrt(mean_noise_um2);
    for (Eigen::Index a = 0; a < positions; ++a) {
      square_sum += whitened(a) * whitened(a);
      noise_alone_square_sum += noise_alone(a) * noise_alone(a);
      ++squares;
      if (a + 1 < positions) {
        neighbour_sum += whitened(a) * whitened(a + 1);
        noise_alone_neighbour_sum += noise_alone(a) * noise_alone(a + 1);
        ++neighbours;
      }
    }
  }
  const double variance = square_sum / squares, neighbour_correlation = neighbour_sum / square_sum,
               noise_alone_correlation = noise_alone_neighbour_sum / noise_alone_square_sum;
  EXPECT_GT(variance, 0.9);
  EXPECT_LT(variance, 1.1);
  EXPECT_LT(std::abs(neighbour_correlation), 0.05);
  EXPECT_GT(noise_alone_correlation, 0.2);
}

/// A campaign of the study's generator with these effects, not drawn at random (their sizes are
/// the seed's), with a model or not (1 / 0) and on the 20 mm grid or the dense plan (1 / 0).
HiddenEffectCampaign campaignOf(std::uint64_t seed, std::vector<std::string> effects, int with_model, int grid_plan) {
  CampaignRequest request;
  request.random = false;
  request.seed = seed;
  request.effects = std::move(effects);
  request.with_model = with_model;
  request.grid_plan = grid_plan;
  return makeLinearCampaign(request);
}

/// The main parameter of each effect and the tolerance of its relative error.
double relativeTolerance(const HiddenEffect& h) {
  if (h.effect == "environment_compensation" || h.effect == "abbe_error" || h.effect == "thermal_growth") return 0.5;
  if (h.effect == "channel_dependence" && h.parameters.at("smooth") > 0.0) return 0.5;
  return 0.2;
}
const char* mainParameter(const HiddenEffect& h) {
  if (h.effect == "backlash") return "reversal";
  if (h.effect == "cyclic_error") return "amplitude";
  if (h.effect == "thermal_drift") return "drift_over_run";
  if (h.effect == "environment_compensation") return "air_temp_coefficient";
  if (h.effect == "scale_error") return "scale";
  if (h.effect == "thermal_growth") return "growth_over_run";
  if (h.effect == "channel_dependence") return h.parameters.at("smooth") > 0.0 ? "peak_to_valley" : "sensitivity";
  return "offset";
}

// 24 campaigns drawn at random (none, one or two effects, random sizes, with or without a
// model, grid or dense plan); the diagnosis is not told what was hidden. Backlash, cyclic
// error (where the plan can see it), scale error and thermal drift must be named with their
// size within 20 % (35 % when two effects are hidden); the weaker environment-compensation
// and Abbe errors, when named, within 50 % (88 %); effect-free campaigns and wrong names are rare; a cyclic error
// hidden from a 20 mm grid is warned about. The many-seed figures are bench/diagnosis_study's (docs/diagnosis.md). The
// 50 % is not tightened: over seeds 1-300 these two effects were named 20 times (of 61 hidden), off by up to 25 % with
// one effect hidden and by up to 100 % with two (seeds 270 and 281: small effects named because the noise enlarged
// them); seeds 1-24 name only two of them (seeds 14 and 16, off by 1 % and 14 %). Each is tested at a known size below.
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
      const bool hidden = std::any_of(c.truth.begin(), c.truth.end(),
                                      [&](const HiddenEffect& h) { return h.effect == f.candidate.effect; });
      wrong_names += !hidden;
      EXPECT_GT(f.gain, 0.0) << f.candidate.effect;
    }
    for (const auto& h : c.truth) {
      if (h.effect == "cyclic_error" && c.grid_plan) {
        EXPECT_TRUE(std::any_of(d.warnings.begin(), d.warnings.end(),
                                [](const std::string& w) { return w.find("cyclic") != std::string::npos; }));
        continue;
      }
      const auto it = std::find_if(d.findings.begin(), d.findings.end(),
                                   [&](const processing::Finding& f) { return f.candidate.effect == h.effect; });
      const bool must = h.effect != "environment_compensation" && h.effect != "abbe_error";
      if (it == d.findings.end()) {
        EXPECT_FALSE(must) << h.effect << " not named";
        continue;
      }
      const std::string name = mainParameter(h);
      for (const auto& p : it->parameters) {
        if (p.name != name) continue;
        ++checked;
        const double truth = h.parameters.at(name);
        // Two effects hidden at once share part of their signatures: 1.75 x the tolerance.
        const double tolerance = relativeTolerance(h) * (c.truth.size() > 1 ? 1.75 : 1.0);
        EXPECT_NEAR(p.value, truth, tolerance * std::abs(truth)) << h.effect << " " << name;
      }
    }
  }
  EXPECT_GE(effect_free, 4);
  EXPECT_LE(effect_free_alarms, 1);
  EXPECT_LE(wrong_names, 1);
  EXPECT_GE(checked, 12);
}

/// A seed of a campaign with one effect hidden at a known size: the seed fixes everything else
/// (the positions, the air's swing, the pitch, the noise).
struct KnownSizeCase {
  std::uint64_t seed;
  double size_rms_um;  ///< what the effect adds, RMS about its mean over the run (the generator's truth)
};

/// The campaign of `k.seed` with only `effect` hidden, at `size` (its main parameter's unit),
/// on the plan and with the model given; its truth is checked to be the case measured.
HiddenEffectCampaign knownSizeCampaign(const std::string& effect, double size, const KnownSizeCase& k, bool with_model,
                                       bool grid_plan) {
  CampaignRequest request;
  request.seed = k.seed;
  request.random = false;
  request.effects = {effect};
  request.with_model = with_model ? 1 : 0;
  request.grid_plan = grid_plan ? 1 : 0;
  request.sizes[effect] = size;
  auto c = makeLinearCampaign(request);
  EXPECT_EQ(c.truth.size(), 1u);
  if (!c.truth.empty()) {
    EXPECT_NEAR(c.truth[0].parameters.at("size_rms"), k.size_rms_um, 0.001);  // the case is the one measured
  }
  return c;
}

/// Diagnoses the campaign as `mtcal diagnose` does and requires: exactly one finding, named
/// as the hidden effect; its main parameter within `standard_errors` of the truth, in the
/// standard error the diagnosis itself reports; a positive held-out gain.
void expectNamedAlone(const HiddenEffectCampaign& c, double standard_errors) {
  ASSERT_EQ(c.truth.size(), 1u);
  const auto& hidden = c.truth.front();
  const auto d = processing::diagnose(processing::linearDiagnosisData(c.run));
  ASSERT_EQ(d.findings.size(), 1u) << (d.findings.empty() ? std::string("nothing named")
                                                          : "also " + d.findings.back().candidate.effect);
  const auto& f = d.findings.front();
  EXPECT_EQ(f.candidate.effect, hidden.effect);
  const std::string name = mainParameter(hidden);
  const auto p = std::find_if(f.parameters.begin(), f.parameters.end(),
                              [&](const processing::ParameterValue& v) { return v.name == name; });
  ASSERT_NE(p, f.parameters.end()) << hidden.effect << " named through another parameter (" << f.candidate.variable
                                   << ")";
  ASSERT_TRUE(std::isfinite(p->standard_error) && p->standard_error > 0.0);
  const double truth = hidden.parameters.at(name);
  EXPECT_NEAR(p->value, truth, standard_errors * p->standard_error)
      << name << " +- " << p->standard_error << " " << p->unit;
  EXPECT_GT(f.gain, 0.0);
  EXPECT_GT(d.gain, 0.0);
}

// A growth along the travel against a model (the model with an identification error of its
// own), on both plans: its growth over the run is within max(10 %, 2 of its standard errors)
// of the truth as often as a standard error means. Two things made its errors too small: the
// model's own error at a position, shared by every repeat there and smooth along the travel,
// and the choice between a first-order and a steady time course, within 1 or 2 of BIC of each
// other on a growth that settles within the run, whose growths over the run differ. Measured
// on seeds 900001..900060: 58 of the 60 growths named are within (95 % expected); with the
// standard errors from the repeats' scatter and the chosen form alone, 52 were. The bound, all
// but 5 (55 of 60: 95 % less 1.2 binomial standard deviations), fails the errors as they were. 18 of the
// growths name the other time course as a form that fits nearly as well (Akaike weight 1 % or
// more), with its weight.
/// The hidden value of `parameter` of the campaign's `effect` (std::out_of_range: not hidden).
double hiddenValue(const HiddenEffectCampaign& c, const std::string& effect, const std::string& parameter) {
  const auto h = std::find_if(c.truth.begin(), c.truth.end(), [&](const auto& t) { return t.effect == effect; });
  if (h == c.truth.end()) throw std::out_of_range(effect + " is not hidden");
  return h->parameters.at(parameter);
}

TEST(HiddenEffects, AGrowthsSizeAgainstAModelIsWithinItsStandardErrors) {
  int named = 0, within = 0, with_another_form = 0;
  for (std::uint64_t seed = 900001; seed <= 900060; ++seed) {
    CampaignRequest request;
    request.seed = seed;
    request.random = false;
    request.effects = {"thermal_growth"};
    request.with_model = 1;
    request.grid_plan = static_cast<int>(seed % 2);
    const auto c = makeLinearCampaign(request);
    const auto d = processing::diagnose(processing::linearDiagnosisData(c.run));
    const double truth = hiddenValue(c, "thermal_growth", "growth_over_run");
    for (const auto& f : d.findings) {
      if (f.candidate.effect != "thermal_growth") continue;
      ++named;
      if (f.other_forms.size() == 1) {  // its weight beside the finding's: exp(-dAIC / 2) / (1 + exp(-dAIC / 2))
        const auto& o = f.other_forms.front();
        EXPECT_NEAR(o.weight, std::exp(-0.5 * o.delta_aic) / (1.0 + std::exp(-0.5 * o.delta_aic)), 1e-12);
        ++with_another_form;
      }
      for (const auto& p : f.parameters) {
        if (p.name == "growth_over_run") {
          within += std::abs(p.value - truth) <= std::max(0.1 * std::abs(truth), 2.0 * p.standard_error);
        }
      }
    }
  }
  EXPECT_GE(named, 58);
  EXPECT_GE(within, named - 5);
  EXPECT_GE(with_another_form, 10);
}

// A wrong air-temperature compensation of 4 ppm/K, on the dense plan (100 random positions
// x 3 bidirectional cycles, 3600 s), without a model. The coefficient is the reading's error
// per kelvin of the air's change: Edlen's index falls by 0.929 ppm/K near 20 degC
// (processing/src/diagnosis.cpp, kDeadPathUmPerMmK; Edlen, Metrologia 2 (1966) 71), so an air
// sensor not read at all gives 0.93 ppm/K and a compensation of the wrong sign 1.86 ppm/K;
// 4 ppm/K is above what the air alone can do, and is the size where the diagnosis names it
// every time. Measured on this generator and diagnosis (seeds 1-100 at each size, the air
// swinging with the 0.4-1.5 K amplitude each seed draws): named with air_temp_coefficient in
// 100 of 100 seeds at +4 and at -4 ppm/K (seed 1, in both signs, also names a position x time
// growth of 0.03 gain, so seeds 2-4 are used here), 99 of 100 at 3 ppm/K, 94 of 100 at 1.86,
// 75 of 100 at 0.93. The coefficient's
// error in its reported standard errors had a standard deviation of 1.00 and never exceeded
// 2.6 (of 100): the standard error is honest, so 4 of them is the tolerance. On the 20 mm grid
// plan (1260 s, shorter than most of the air's periods, 1200-3600 s) the air's change is
// nearly a ramp in time and the same 4 ppm/K is named in only 87 of 100 seeds: the others
// name a position x time growth (7), a position x material-temperature expansion (4) or the
// pressure (2): those signatures are nearly the same on such a run.
TEST(HiddenEffects, AWrongAirCompensationOf4PpmPerKIsNamedWithItsCoefficient) {
  constexpr double kCoefficientPpmPerK = 4.0;
  // Seeds 2-4: the air swings 0.63, 0.60, 0.40 K (standard deviation over the run).
  for (const KnownSizeCase k : {KnownSizeCase{2, 0.567}, KnownSizeCase{3, 0.443}, KnownSizeCase{4, 0.362}}) {
    SCOPED_TRACE("seed " + std::to_string(k.seed));
    const auto c = knownSizeCampaign("environment_compensation", kCoefficientPpmPerK, k, /*with_model=*/false,
                                     /*grid_plan=*/false);
    ASSERT_EQ(c.truth.size(), 1u);
    ASSERT_EQ(c.truth[0].parameters.at("air_temp_coefficient"), kCoefficientPpmPerK);
    expectNamedAlone(c, 4.0);
  }
}

// Optics 150 mm off the line the model assumes, on the ISO 230-2 grid (every 20 mm over
// 0..400 mm, 5 bidirectional cycles) against the model identified from an earlier run; the
// pitch is the generator's bow (a 40-80 urad/m slope and a 150-250 urad/m^2 curvature drawn
// per seed). 150 mm is an ordinary distance between a laser's beam and the tool on a machine
// tool; the random campaigns draw 20-80 mm. Measured on this generator and diagnosis (seeds
// 1-100 at each size): named in 99 of 100 seeds at 150 mm (not in seed 68; seed 39 also names
// a 0.2 um reversal), 91 at 80 mm, 53 at 50 mm; on the dense plan 100, 96 and 78 of 100. The
// offset's error in its reported standard errors had a standard deviation of 1.36 on the grid
// and at most 3.74 in the 99 seeds at 150 mm; on the dense plan 1.9, with 2 of 100 beyond 4
// (likely the model's own identification error, smooth along the travel, which the standard
// error takes as independent). So the grid is used here, with 4 reported standard errors.
TEST(HiddenEffects, AnAbbeOffsetOf150MmIsNamedWithItsOffset) {
  constexpr double kOffsetMm = 150.0;
  for (const KnownSizeCase k : {KnownSizeCase{1, 0.325}, KnownSizeCase{2, 0.474}, KnownSizeCase{3, 0.566}}) {
    SCOPED_TRACE("seed " + std::to_string(k.seed));
    const auto c = knownSizeCampaign("abbe_error", kOffsetMm, k, /*with_model=*/true, /*grid_plan=*/true);
    ASSERT_EQ(c.truth.size(), 1u);
    // The truth is the offset the readings show per urad of pitch: the optics' offset to first order.
    ASSERT_NEAR(c.truth[0].parameters.at("offset"), kOffsetMm, 0.01);
    expectNamedAlone(c, 4.0);
  }
}

/// The named causes of a campaign, sorted.
std::vector<std::string> namedCauses(const processing::Diagnosis& d) {
  std::vector<std::string> out;
  for (const auto& f : d.findings) out.push_back(f.candidate.effect);
  std::sort(out.begin(), out.end());
  return out;
}

/// A study campaign of `effects` (`seed`, the case's seeds) on the dense plan against a model,
/// and its diagnosis.
std::pair<HiddenEffectCampaign, processing::Diagnosis> denseAgainstAModel(std::uint64_t seed,
                                                                          std::vector<std::string> effects) {
  CampaignRequest request;
  request.random = false;
  request.seed = seed;
  request.effects = std::move(effects);
  request.with_model = 1;
  request.grid_plan = 0;
  auto c = makeLinearCampaign(request);
  auto d = processing::diagnose(processing::linearDiagnosisData(c.run));
  return {std::move(c), std::move(d)};
}

// Two campaigns of the study (bench/diagnosis_study, the seeds of its cases) that a cause
// found early used to spoil; both now name exactly what was hidden.
// - A 6.2 ppm scale error and a drift (-5.4 um, tau 877 s) on the dense plan against a model:
//   the first round names a growth (its term along the travel settles within the first cycle
//   and takes the scale's part); the backward check replaces it by a drift, and the search
//   going on from there finds the scale (before, the search had ended: the drift alone).
// - A coolant dependence of 5.7 um/K and a drift (-7.7 um, tau 3 330 s) on the dense plan: the
//   drift is found first with a time constant of about 700 s that takes the coolant's slow
//   wander, beside which the coolant predicts held-out repeats worse (2.51 against 1.63 um);
//   refitted beside it, the drift's time constant moves and the two predict to 0.50 um (before:
//   a drift and a spurious 0.6 um backlash).
TEST(HiddenEffects, ACauseFoundEarlyNoLongerHidesTheOther) {
  CampaignRequest request;
  request.random = false;
  request.grid_plan = 0;
  request.seed = 12000001;
  request.effects = {"scale_error", "thermal_drift"};
  request.with_model = 1;
  const auto scaled = makeLinearCampaign(request);
  ASSERT_EQ(scaled.truth.size(), 2u);
  EXPECT_NEAR(scaled.truth[0].parameters.at("scale"), 6.2, 0.05);  // the campaign measured
  const auto d1 = processing::diagnose(processing::linearDiagnosisData(scaled.run));
  EXPECT_EQ(namedCauses(d1), (std::vector<std::string>{"scale_error", "thermal_drift"}));

  request.seed = 10000001;
  request.effects = {"channel_dependence", "thermal_drift"};
  request.with_model = 0;
  const auto cooled = makeLinearCampaign(request);
  ASSERT_EQ(cooled.truth.size(), 2u);
  EXPECT_NEAR(cooled.truth[1].parameters.at("sensitivity"), 5.72, 0.01);
  const auto d2 = processing::diagnose(processing::linearDiagnosisData(cooled.run));
  EXPECT_EQ(namedCauses(d2), (std::vector<std::string>{"channel_dependence", "thermal_drift"}));
}

// A growth along the travel (4.06 ppm over the run, tau 1 250 s, its datum drifting by 1.7 um)
// on the 20 mm grid against a model: its term along the travel settles within the first
// cycles and reads as a scale. The growth is found first; the backward check, testing its
// term along the travel against the repeats' scatter alone, makes it a drift, and the scale
// is named next. The growth fits every reading as well as the two with as many parameters,
// and better than its drift alone: it is named for both (before: a drift of 1.8 um and a
// scale of 2.6 ppm). The same beside a backlash of 4.5 um (before: a backlash, a drift and
// a scale). A scale beside a drift stays two findings (ACauseFoundEarlyNoLongerHidesTheOther).
TEST(HiddenEffects, AGrowthReadAsADriftAndAScaleIsOneCause) {
  for (const auto& [seed, effects] : std::vector<std::pair<std::uint64_t, std::vector<std::string>>>{
           {8500084, {"thermal_growth"}}, {11500112, {"thermal_growth", "backlash"}}}) {
    SCOPED_TRACE(seed);
    const auto c = campaignOf(seed, effects, 1, 1);
    const auto d = processing::diagnose(processing::linearDiagnosisData(c.run));
    auto expected = effects;
    std::sort(expected.begin(), expected.end());
    EXPECT_EQ(namedCauses(d), expected);
    EXPECT_TRUE(std::any_of(d.considered.begin(), d.considered.end(), [](const auto& t) {
      return t.effect == "thermal_growth" &&
             t.verdict.rfind("named for the thermal_drift and scale_error findings: one cause", 0) == 0;
    }));
    const double truth = hiddenValue(c, "thermal_growth", "growth_over_run");
    for (const auto& f : d.findings) {
      if (f.candidate.effect != "thermal_growth") continue;
      EXPECT_GT(f.gain, 0.0);
      for (const auto& p : f.parameters) {
        if (p.name == "growth_over_run") {
          EXPECT_LE(std::abs(p.value - truth), std::max(0.1 * std::abs(truth), 2.0 * p.standard_error));
        }
      }
    }
  }
}

// A growth along the travel (-5.2 ppm, tau 460 s) on the 20 mm grid without a model: the
// baseline takes every position's mean, and what is left of the growth, its change between the
// cycles, is hardly more than its datum's drift explains (a study campaign the diagnosis misses,
// naming the drift). The finding says what was tested and not needed, and does not name the
// drift as an alternative to itself (it did: "cannot be told apart from: thermal_drift"); its
// evidence and held-out figures are the drift's (they were the growth's: held out 0.555 um for
// the finding, 0.564 with every finding, the finding alone).
TEST(HiddenEffects, ADriftThatWasAGrowthSaysTheGrowthWasTestedAndNotNeeded) {
  const auto c = campaignOf(8500095, {"thermal_growth"}, 0, 1);
  const processing::DiagnosisOptions options;
  const auto d = processing::diagnose(processing::linearDiagnosisData(c.run), options);
  ASSERT_EQ(namedCauses(d), std::vector<std::string>{"thermal_drift"});
  const auto& drift = d.findings.front();
  ASSERT_TRUE(drift.replaced_form.has_value());
  EXPECT_EQ(drift.replaced_form->cause, "thermal_growth (time_s)");
  EXPECT_GE(drift.replaced_form->p_value, options.alpha);
  EXPECT_LT(drift.replaced_form->p_value, 0.2);  // the run nearly tells: p 0.0576
  EXPECT_EQ(std::count(drift.alternatives.begin(), drift.alternatives.end(), "thermal_drift (time_s)"), 0);
  // Its evidence is the drift's test (227.5, its time constant held at the growth's; the search
  // tested it at 227.7), not the growth's (228.9); its held-out figures those with it, the only
  // finding: the figures with every finding.
  const auto roundOne = [&](const std::string& effect) {
    double most = -1e300;
    for (const auto& t : d.considered)
      if (t.round == 1 && t.effect == effect) most = std::max(most, t.delta_bic);
    return most;
  };
  EXPECT_LT(drift.delta_bic, roundOne("thermal_growth"));
  EXPECT_NEAR(drift.delta_bic, roundOne("thermal_drift"), 0.5);
  EXPECT_DOUBLE_EQ(drift.rms_after_um, d.final_heldout_rms_um);
  EXPECT_DOUBLE_EQ(drift.rms_before_um, d.heldout_rms_um);
}

// A coolant's curve and a drift on the 20 mm grid (a study campaign): a growth found beside the
// drift became, in the backward check, a second first-order drift that cancelled the first
// (amplitudes -10 +- 220 and +10 +- 230 um). Made simpler, a finding may no more cancel another
// than a candidate of the search may: it is dropped, and the drift and the curve are named with
// their sizes.
TEST(HiddenEffects, AFindingMadeSimplerThatWouldCancelAnotherIsDropped) {
  const auto c = campaignOf(10500006, {"channel_dependence", "thermal_drift"}, 0, 1);
  const auto d = processing::diagnose(processing::linearDiagnosisData(c.run));
  EXPECT_EQ(namedCauses(d), (std::vector<std::string>{"channel_dependence", "thermal_drift"}));
  EXPECT_TRUE(std::any_of(d.considered.begin(), d.considered.end(), [](const auto& t) {
    return t.round == 0 && t.effect == "thermal_growth" &&
           t.verdict.rfind(
               "dropped: its further terms are not needed, and as thermal_drift it is entangled with the "
               "thermal_drift finding",
               0) == 0;
  }));
  for (const auto& f : d.findings) {
    const auto& h =
        *std::find_if(c.truth.begin(), c.truth.end(), [&](const auto& t) { return t.effect == f.candidate.effect; });
    const auto name = std::string(mainParameter(h));
    const double truth = h.parameters.at(name);
    for (const auto& p : f.parameters) {
      if (p.name == name) {
        SCOPED_TRACE(name);
        EXPECT_LE(std::abs(p.value - truth), std::max(0.1 * std::abs(truth), 2.0 * p.standard_error));
      }
    }
  }
}

// A drift first-order in time (tau about 1000 s) beside a backlash, read in its steady form
// when it entered (the two forms' BIC within 2 before the backlash was in the model); an air
// compensation term then took the steady form's misfit. The first-order drift fits every
// reading better than the two with as many parameters, and better than the steady drift
// alone: it is named for both (study campaigns; before: a steady drift, the backlash and an
// air compensation of 2.5 and -3.7 ppm/K, neither hidden).
TEST(HiddenEffects, ASteadyDriftAndATermThatTookItsMisfitAreOneFirstOrderDrift) {
  for (const auto& [seed, with_model] : std::vector<std::pair<std::uint64_t, int>>{{9500115, 0}, {9500160, 1}}) {
    SCOPED_TRACE(seed);
    const auto c = campaignOf(seed, {"backlash", "thermal_drift"}, with_model, 1);
    const auto d = processing::diagnose(processing::linearDiagnosisData(c.run));
    EXPECT_EQ(namedCauses(d), (std::vector<std::string>{"backlash", "thermal_drift"}));
    EXPECT_TRUE(std::any_of(d.considered.begin(), d.considered.end(), [](const auto& t) {
      return t.effect == "thermal_drift" &&
             t.verdict.rfind(
                 "named for the thermal_drift and environment_compensation findings: one cause in "
                 "another form",
                 0) == 0;
    }));
    const auto drift = std::find_if(d.findings.begin(), d.findings.end(),
                                    [](const auto& f) { return f.candidate.effect == "thermal_drift"; });
    ASSERT_NE(drift, d.findings.end());
    EXPECT_TRUE(std::any_of(drift->parameters.begin(), drift->parameters.end(),
                            [](const auto& p) { return p.name == "time_constant"; }));
    const double truth = hiddenValue(c, "thermal_drift", "drift_over_run");
    for (const auto& p : drift->parameters) {
      if (p.name == "drift_over_run") {
        EXPECT_LE(std::abs(p.value - truth), std::max(0.1 * std::abs(truth), 2.0 * p.standard_error));
      }
    }
  }
}

// A reading that follows a coolant's wandering temperature along a curve (8 um peak to valley)
// beside a drift, on the 20 mm grid against a model: a cycle held out leaves the coolant at the
// edge of its range, where a cubic in it fitted on the other cycles extrapolated so far that
// the channel and the drift together predicted held-out cycles worse than nothing (1.92
// against 1.76 um), and nothing was named. The curve is a quadratic in the channel: both are
// named, the curve's peak to valley within max(10 %, 2 SE) (a study campaign).
TEST(HiddenEffects, AChannelsCurveBesideADriftIsNamedWhereACubicExtrapolatedWildly) {
  const auto c = campaignOf(10500156, {"channel_dependence", "thermal_drift"}, 1, 1);
  const auto d = processing::diagnose(processing::linearDiagnosisData(c.run));
  EXPECT_EQ(namedCauses(d), (std::vector<std::string>{"channel_dependence", "thermal_drift"}));
  const double truth = hiddenValue(c, "channel_dependence", "peak_to_valley");
  const auto channel = std::find_if(d.findings.begin(), d.findings.end(),
                                    [](const auto& f) { return f.candidate.effect == "channel_dependence"; });
  ASSERT_NE(channel, d.findings.end());
  const auto p = std::find_if(channel->parameters.begin(), channel->parameters.end(),
                              [](const auto& q) { return q.name == "peak_to_valley"; });
  ASSERT_NE(p, channel->parameters.end());
  EXPECT_LE(std::abs(p->value - truth), std::max(0.1 * truth, 2.0 * p->standard_error));
}

// A drift first-order in time (5.14 um over the run, tau 3450 s) beside a coolant's slow
// wander, dense plan against a model: the growth found first becomes a first-order drift
// (its growth not needed) next to a steady drift already named, and the backward check keeps
// each given the other. Two forms of one cause are one finding, its time course both:
// amplitude (1 - e^(-T/tau)) + rate T over the run's T, tau within the range searched (up to
// twice the run), neither form listed as another form of it. Before, the two were named as two
// drifts of 1.73 and 3.67 um, neither the drift the run saw.
TEST(HiddenEffects, ADriftNamedInTwoFormsIsOneFindingWithBoth) {
  const auto [c, d] = denseAgainstAModel(10000210, {"channel_dependence", "thermal_drift"});
  EXPECT_EQ(namedCauses(d), (std::vector<std::string>{"channel_dependence", "thermal_drift"}));
  ASSERT_EQ(std::count_if(d.findings.begin(), d.findings.end(),
                          [](const auto& f) { return f.candidate.effect == "thermal_drift"; }),
            1);
  const auto& drift = *std::find_if(d.findings.begin(), d.findings.end(),
                                    [](const auto& f) { return f.candidate.effect == "thermal_drift"; });
  std::map<std::string, processing::ParameterValue> p;
  for (const auto& v : drift.parameters) p[v.name] = v;
  ASSERT_EQ(p.count("amplitude") + p.count("time_constant") + p.count("drift_rate") + p.count("drift_over_run"), 4u);
  const auto [first, last] = std::minmax_element(c.run.time_s.begin(), c.run.time_s.end());
  const double run_s = *last - *first;
  EXPECT_LE(p["time_constant"].value, 2.0 * run_s * (1.0 + 1e-12));
  EXPECT_TRUE(drift.other_forms.empty());
  EXPECT_NEAR(p["drift_over_run"].value,
              p["amplitude"].value * (1.0 - std::exp(-run_s / p["time_constant"].value)) +
                  p["drift_rate"].value * run_s / 3600.0,
              1e-9 * std::abs(p["drift_over_run"].value));
  double truth = 0.0;
  for (const auto& h : c.truth) {
    if (h.effect == "thermal_drift") truth = h.parameters.at("drift_over_run");
  }
  EXPECT_NEAR(truth, 5.14, 0.005);
  EXPECT_LE(std::abs(p["drift_over_run"].value - truth),
            std::max(0.1 * truth, 2.0 * p["drift_over_run"].standard_error));
  EXPECT_TRUE(std::any_of(d.considered.begin(), d.considered.end(), [](const auto& t) {
    return t.verdict.find("one finding with both time courses") != std::string::npos;
  }));
}

// A channel's dependence beside a drift that settles slowly (tau 3 280 s): the drift is named steady in time, and its
// first-order form fits nearly as well. The channel's sensitivity fitted beside the one form is not the one fitted
// beside the other, and its standard error counts that (Burnham and Anderson's unconditional error over the models with
// each finding in another form). Before, it was -2.95 +- 0.053 um/degC for a truth of -2.50: 8.4 of its errors off.
TEST(HiddenEffects, AParameterCountsTheSpreadOfAnotherFindingsForms) {
  const auto [c, d] = denseAgainstAModel(10000106, {"channel_dependence", "thermal_drift"});
  ASSERT_EQ(namedCauses(d), (std::vector<std::string>{"channel_dependence", "thermal_drift"}));
  const auto find = [&](const std::string& effect) {
    return *std::find_if(d.findings.begin(), d.findings.end(),
                         [&](const auto& f) { return f.candidate.effect == effect; });
  };
  const auto drift = find("thermal_drift");
  ASSERT_FALSE(drift.other_forms.empty());  // the first-order form, weighed
  EXPECT_GT(drift.other_forms.front().weight, 0.01);
  double truth = 0.0;
  for (const auto& h : c.truth) {
    if (h.effect == "channel_dependence") truth = h.parameters.at("sensitivity");
  }
  EXPECT_NEAR(truth, -2.50, 0.005);
  const auto channel = find("channel_dependence");
  const auto found = std::find_if(channel.parameters.begin(), channel.parameters.end(),
                                  [](const auto& p) { return p.name == "sensitivity"; });
  ASSERT_NE(found, channel.parameters.end());
  const auto sensitivity = *found;
  EXPECT_LE(std::abs(sensitivity.value - truth), 2.0 * sensitivity.standard_error);
  EXPECT_LT(sensitivity.standard_error, 0.15 * std::abs(sensitivity.value));  // not an error made to fit
}

// Three-probe stepping runs (error separation): 12 seeds each of effect-free runs, probes'
// zeros (c1 - 2 c2 + c3 of 0.1..1 um) and a carriage yaw that changes within a few steps
// (20..60 urad, wavelength 2.5..6 steps). Over 300 seeds each (bench/diagnosis_study est) at
// alpha 0.01: 0.3 % of effect-free runs named anything, the zeros were named alone in 98.7 %
// and the short yaw in 99.0 %. Here: nothing named on the effect-free runs, the hidden cause
// alone in at least 11 of 12 of the others, the zeros within max(10 %, 2 standard errors) and
// the yaw's peak to valley within 15 % where named.
TEST(HiddenEffects, EstRunsNameTheProbesZerosAndAShortWaveYaw) {
  for (std::uint64_t seed = 1; seed <= 12; ++seed) {
    const auto clean = makeEstCampaign(seed, {});
    EXPECT_TRUE(processing::diagnose(processing::estDiagnosisData(clean.run)).findings.empty()) << "seed " << seed;
  }
  for (const char* effect : {"probe_offset", "carriage_yaw_short"}) {
    int alone = 0;
    for (std::uint64_t seed = 1; seed <= 12; ++seed) {
      const auto c = makeEstCampaign(seed, {effect});
      const auto d = processing::diagnose(processing::estDiagnosisData(c.run));
      ASSERT_EQ(c.truth.size(), 1u);
      const auto& truth = c.truth.front();
      if (d.findings.size() != 1 || d.findings.front().candidate.effect != truth.effect) continue;
      ++alone;
      for (const auto& p : d.findings.front().parameters) {
        if (p.name == "zero_combination") {
          const double expected = truth.parameters.at("zero_combination");
          EXPECT_LE(std::abs(p.value - expected), std::max(0.1 * std::abs(expected), 2.0 * p.standard_error))
              << "seed " << seed;
        }
        if (p.name == "yaw_peak_to_valley") {
          const double expected = truth.parameters.at("yaw_peak_to_valley");
          EXPECT_NEAR(p.value, expected, 0.15 * expected) << "seed " << seed;
        }
      }
    }
    EXPECT_GE(alone, 11) << effect;
  }
  EXPECT_THROW(makeEstCampaign(1, {"warp_drive"}), InputError);
}

// A constant on probe 3 is the probes' zeros' (or a yaw's constant rate, which three probes
// cannot tell from them): a generic dependence is tested beyond it. The study's campaign 3000102
// (a yaw of 12.9 urad, wavelength 692 mm, 23 steps) named a generic dependence on the profile's slope
// beside the yaw when the generic term could take that constant too (delta BIC 16.1); the yaw
// alone is named now, its peak to valley within max(10 %, 2 standard errors).
TEST(HiddenEffects, EstGenericDependenceIsTestedBeyondTheZerosConstant) {
  const auto c = makeEstCampaign(3000102, {"carriage_yaw"});
  const auto d = processing::diagnose(processing::estDiagnosisData(c.run));
  ASSERT_EQ(d.findings.size(), 1u);
  ASSERT_EQ(d.findings.front().candidate.effect, "carriage_yaw");
  const double expected = c.truth.front().parameters.at("yaw_peak_to_valley");
  int compared = 0;
  for (const auto& p : d.findings.front().parameters) {
    if (p.name != "yaw_peak_to_valley") continue;
    EXPECT_LE(std::abs(p.value - expected), std::max(0.1 * expected, 2.0 * p.standard_error));
    ++compared;
  }
  EXPECT_EQ(compared, 1);
}

// A scale error beside a growth, against a model on a dense plan: the growth's term along the
// travel, held at its fit without the scale, had taken the scale's part through the positions'
// means, and the scale was tested for nothing (study campaigns 12500090 and 12500177: a growth
// alone, of -4.31 ppm for a truth of +5.84, and of -1.80 for +5.06). A term the same at every
// repeat of a position is now tested with the terms that vary within the positions refitted
// beside it (both strata at once): both are named, the scale and the growth over the run each
// within max(10 %, 2 standard errors) of its truth.
TEST(HiddenEffects, AScaleBesideAGrowthIsNamedWithIt) {
  for (const std::uint64_t seed : {12500090, 12500177}) {
    SCOPED_TRACE(seed);
    const auto [c, d] = denseAgainstAModel(seed, {"scale_error", "thermal_growth"});
    EXPECT_NEAR(hiddenValue(c, "scale_error", "scale"), seed == 12500090 ? -9.54 : -4.88, 0.005);  // the study's
    EXPECT_EQ(namedCauses(d), (std::vector<std::string>{"scale_error", "thermal_growth"}));
    for (const auto& [effect, parameter] : std::vector<std::pair<std::string, std::string>>{
             {"scale_error", "scale"}, {"thermal_growth", "growth_over_run"}}) {
      const double truth = hiddenValue(c, effect, parameter);
      int compared = 0;
      for (const auto& f : d.findings) {
        for (const auto& p : f.parameters) {
          if (f.candidate.effect != effect || p.name != parameter) continue;
          EXPECT_LE(std::abs(p.value - truth), std::max(0.1 * std::abs(truth), 2.0 * p.standard_error)) << parameter;
          ++compared;
        }
      }
      EXPECT_EQ(compared, 1) << parameter;
    }
  }
}

// A scale and an Abbe offset that hide each other where the model's own error is estimated from
// the positions' means: alone, neither passes (each leaves the other in those means, and a smooth
// error that large takes either); together they do. The study's campaigns 12500078 (dense plan)
// and 12500140 (20 mm grid), two effects at random on the test seeds, named nothing then: so
// estimated, they still name nothing (named, such pairs were as often the model's own error),
// and a warning says what the run cannot tell, with the pair's figures. Tested against the error
// the model states (its identification's scatter through its fit), the positions' means agree
// with it and both are named, each within max(10 %, 2 standard errors) of its truth.
TEST(HiddenEffects, AScaleAndAnAbbeOffsetThatHideEachOtherAreWarnedAbout) {
  for (const auto& [seed, grid, scale, warning] : std::vector<std::tuple<std::uint64_t, int, double, std::string>>{
           {12500078, 0, 4.78, "from 0.607 to 0.524 um (delta BIC 49.2, p 1.2e-11)"},
           {12500140, 1, 9.52, "from 1.029 to 0.508 um (delta BIC 55.7, p 7e-11)"}}) {
    SCOPED_TRACE(seed);
    const auto c = campaignOf(seed, {"scale_error", "abbe_error"}, 1, grid);
    EXPECT_NEAR(hiddenValue(c, "scale_error", "scale"), scale, 0.005);  // the study's
    auto estimated = c.run;
    estimated.simulated_error_factor_um.resize(0, 0);
    const auto d = processing::diagnose(processing::linearDiagnosisData(estimated));
    EXPECT_TRUE(d.findings.empty());
    const std::string expected = "abbe_error + scale_error (EBX_urad, position_mm) together lower the held-out RMS " +
                                 warning +
                                 ", but neither passes alone: the run cannot tell whether both, one of them "
                                 "or the model's own error along the travel (which they can take together) is the "
                                 "cause, and neither is named";
    EXPECT_TRUE(std::any_of(d.warnings.begin(), d.warnings.end(), [&](const std::string& w) {
      return w.find(expected) != std::string::npos;
    })) << (d.warnings.empty() ? std::string("no warning") : d.warnings.back());
    // The pair is in the search's record, as a check after the search.
    EXPECT_TRUE(std::any_of(d.considered.begin(), d.considered.end(), [](const processing::Considered& t) {
      return t.round == 0 && t.effect == "abbe_error + scale_error" &&
             t.verdict == "passes together, neither alone: warned, not named";
    }));

    const auto stated = processing::diagnose(processing::linearDiagnosisData(c.run));
    ASSERT_EQ(stated.findings.size(), 2u);
    for (const auto& [effect, parameter] :
         std::vector<std::pair<std::string, std::string>>{{"scale_error", "scale"}, {"abbe_error", "offset"}}) {
      const auto f = std::find_if(stated.findings.begin(), stated.findings.end(),
                                  [&](const auto& f) { return f.candidate.effect == effect; });
      ASSERT_NE(f, stated.findings.end()) << effect;
      EXPECT_EQ(f->candidate.variable, effect == "abbe_error" ? "EBX_urad" : "position_mm");
      const double truth = hiddenValue(c, effect, parameter), value = f->parameters.front().value;
      EXPECT_LE(std::abs(value - truth), std::max(0.1 * std::abs(truth), 2.0 * f->parameters.front().standard_error))
          << effect << " " << value << " for " << truth;
    }
    EXPECT_TRUE(std::any_of(stated.notes.begin(), stated.notes.end(), [](const std::string& n) {
      return n.find("taken as the model states it") != std::string::npos &&
             n.find("agree with it") != std::string::npos;
    }));
  }
}

/// The readings of a campaign's run that `keep` (by their index) keeps, as a run of their own.
processing::LinearRunInput readingsOf(const processing::LinearRunInput& run,
                                      const std::function<bool(std::size_t)>& keep, const std::string& source) {
  std::vector<Eigen::Index> rows;
  for (std::size_t i = 0; i < run.cycle.size(); ++i) {
    if (keep(i)) rows.push_back(static_cast<Eigen::Index>(i));
  }
  processing::LinearRunInput out = run;
  out.source = source;
  const auto pick = [&](const auto& v) {
    std::remove_cvref_t<decltype(v)> kept;
    for (const auto i : rows) kept.push_back(v[static_cast<std::size_t>(i)]);
    return kept;
  };
  out.position_mm = pick(run.position_mm);
  out.deviation_um = pick(run.deviation_um);
  out.direction = pick(run.direction);
  out.cycle = pick(run.cycle);
  out.time_s = pick(run.time_s);
  out.simulated_um = pick(run.simulated_um);
  out.simulated_error_factor_um = run.simulated_error_factor_um(rows, Eigen::all);
  for (auto& c : out.channels) c.values = c.values(rows).eval();
  for (auto& a : out.model_angles_urad) a.values = a.values(rows).eval();
  return out;
}

// Runs against one model that states its own error share it (the same nodes' errors): pooled in
// one fit, the positions' means of both are tested against it. The grid campaign of scale and
// Abbe offset above, its cycles 1..2 and 3..5 as two runs: pooled, both causes are named, each
// within max(10 %, 2 standard errors) of its truth, and the means agree with the statement.
TEST(HiddenEffects, RunsAgainstOneModelShareTheErrorItStates) {
  const auto c = campaignOf(12500140, {"scale_error", "abbe_error"}, 1, 1);
  const auto cycles = [&](int first, int last) {
    return [&c, first, last](std::size_t i) { return c.run.cycle[i] >= first && c.run.cycle[i] <= last; };
  };
  const auto a = processing::linearDiagnosisData(readingsOf(c.run, cycles(1, 2), "run A"));
  const auto b = processing::linearDiagnosisData(readingsOf(c.run, cycles(3, 5), "run B"));
  const auto pooled = processing::poolDiagnosisData({a, b});
  ASSERT_EQ(pooled.model_error_factor.rows(), a.model_error_factor.rows() + b.model_error_factor.rows());
  EXPECT_TRUE(pooled.model_error_factor.topRows(a.model_error_factor.rows()).isApprox(a.model_error_factor));
  const auto d = processing::diagnose(pooled);
  EXPECT_EQ(namedCauses(d), (std::vector<std::string>{"abbe_error", "scale_error"}));
  for (const auto& f : d.findings) {
    const std::string parameter = f.candidate.effect == "abbe_error" ? "offset" : "scale";
    const double truth = hiddenValue(c, f.candidate.effect, parameter), value = f.parameters.front().value;
    EXPECT_LE(std::abs(value - truth), std::max(0.1 * std::abs(truth), 2.0 * f.parameters.front().standard_error))
        << f.candidate.effect << " " << value << " for " << truth;
  }
  EXPECT_TRUE(std::any_of(d.notes.begin(), d.notes.end(), [](const std::string& n) {
    return n.find("taken as the model states it") != std::string::npos && n.find("agree with it") != std::string::npos;
  }));
  // Against models of different descriptions, nothing is shared: the error is estimated.
  auto other = b;
  other.model_description = "another model";
  EXPECT_EQ(processing::poolDiagnosisData({a, other}).model_error_factor.size(), 0);
}

// A model whose error exceeds what it states (the machine changed since it was identified: a wave
// of 0.8 um and 200 mm along the travel, which no cause of the library makes) is not trusted: the positions'
// means disagree with its statement, the report says so, and the diagnosis is the one that
// estimates the model's error from the run, finding for finding. Where the model is as it says,
// the report says that the means agree. Effect-free campaigns with a model, on the 20 mm grid and
// the dense plan.
TEST(HiddenEffects, AModelWhoseErrorExceedsItsStatementIsNotTrusted) {
  int agreed = 0;
  for (std::uint64_t seed = 1; seed <= 10; ++seed) {
    SCOPED_TRACE(seed);
    auto c = campaignOf(seed, {}, 1, static_cast<int>(seed % 2));
    ASSERT_GT(c.run.simulated_error_factor_um.cols(), 0);
    const auto as_stated = processing::diagnose(processing::linearDiagnosisData(c.run));
    agreed += std::any_of(as_stated.notes.begin(), as_stated.notes.end(), [](const std::string& n) {
      return n.find("taken as the model states it") != std::string::npos;
    });
    for (std::size_t i = 0; i < c.run.simulated_um.size(); ++i)
      c.run.simulated_um[i] += 0.8 * std::sin(2.0 * std::numbers::pi * c.run.position_mm[i] / 200.0);
    // Refused, the diagnosis is made again: one progress count over both, never going back.
    std::vector<std::pair<std::size_t, std::size_t>> progress;
    processing::DiagnosisOptions counted;
    counted.on_progress = [&](std::size_t done, std::size_t total) { progress.emplace_back(done, total); };
    const auto changed = processing::diagnose(processing::linearDiagnosisData(c.run), counted);
    ASSERT_FALSE(progress.empty());
    EXPECT_EQ(progress.back().first, progress.back().second);
    for (std::size_t k = 1; k < progress.size(); ++k) EXPECT_GE(progress[k].first, progress[k - 1].first);
    auto estimated_run = c.run;
    estimated_run.simulated_error_factor_um.resize(0, 0);
    const auto estimated = processing::diagnose(processing::linearDiagnosisData(estimated_run));
    ASSERT_EQ(changed.notes.size(), estimated.notes.size() + 1);
    EXPECT_NE(changed.notes.back().find("disagree with the model's own error as the model states it"),
              std::string::npos)
        << changed.notes.back();
    EXPECT_EQ(changed.stated_error.what, "model_error");
    EXPECT_EQ(changed.stated_error.outcome, "refused");
    EXPECT_LT(changed.stated_error.p_value, 0.01);
    EXPECT_TRUE(std::isnan(changed.stated_error.p_value_point_to_point));  // a stated noise's only
    EXPECT_TRUE(estimated.stated_error.what.empty());
    EXPECT_EQ(namedCauses(changed), namedCauses(estimated));
    EXPECT_EQ(changed.final_heldout_rms_um, estimated.final_heldout_rms_um);
  }
  EXPECT_GE(agreed, 9);  // at p >= 0.01 each

  // Each position read once: no scatter within the positions to weigh the statement against.
  const auto c = campaignOf(1, {}, 1, 1);
  const auto once = readingsOf(
      c.run, [&](std::size_t i) { return c.run.cycle[i] == 1 && c.run.direction[i] > 0; }, "one pass");
  const auto d = processing::diagnose(processing::linearDiagnosisData(once));
  EXPECT_NE(d.notes.back().find("hold no scatter to weigh it against"), std::string::npos) << d.notes.back();
  EXPECT_EQ(d.stated_error.outcome, "not used");

  // A statement that does not fit the data's positions is refused, naming it.
  auto wrong = processing::linearDiagnosisData(c.run);
  wrong.model_error_factor.conservativeResize(wrong.model_error_factor.rows() - 1, Eigen::NoChange);
  try {
    processing::diagnose(wrong);
    ADD_FAILURE() << "a statement of 20 rows for 21 positions was taken";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("the model's stated error has 20 rows for 21 positions"), std::string::npos)
        << e.what();
  }
}

// What trusting the statement costs: a machine changed since in a shape a cause can take is that
// cause as far as the check can tell. A half sine of 1 um over the travel (a bow, as the pitch's),
// 40 effect-free campaigns with a model, the grid and the dense plan alternately: the figures of
// docs/diagnosis.md (step 4).
TEST(HiddenEffects, AChangeACauseCanTakeIsThatCauseAgainstTheStatedError) {
  int named_stated = 0, named_estimated = 0, refused = 0, abbe = 0, with_scale = 0;
  for (std::uint64_t seed = 1; seed <= 40; ++seed) {
    auto c = campaignOf(seed, {}, 1, static_cast<int>(seed % 2));
    for (std::size_t i = 0; i < c.run.simulated_um.size(); ++i)
      c.run.simulated_um[i] += std::sin(std::numbers::pi * c.run.position_mm[i] / 400.0);
    const auto stated = processing::diagnose(processing::linearDiagnosisData(c.run));
    auto estimated_run = c.run;
    estimated_run.simulated_error_factor_um.resize(0, 0);
    const auto estimated = processing::diagnose(processing::linearDiagnosisData(estimated_run));
    const auto named = namedCauses(stated);
    named_stated += !named.empty();
    abbe += std::find(named.begin(), named.end(), "abbe_error") != named.end();
    named_estimated += !estimated.findings.empty();
    refused += stated.notes.back().find("disagree with the model's own error") != std::string::npos;
    with_scale += std::find(named.begin(), named.end(), "scale_error") != named.end() &&
                  std::find(named.begin(), named.end(), "abbe_error") != named.end();
  }
  EXPECT_EQ(named_stated, 35);
  EXPECT_EQ(abbe, 35);
  EXPECT_EQ(with_scale, 18);
  EXPECT_EQ(named_estimated, 11);
  EXPECT_EQ(refused, 5);
}

// An EST run states its noise: every probe's reading at a step is the mean of several, whose
// scatter the run keeps. The tests pool it with the residuals' scatter, which over 20 to 40
// steps is a poor estimate of its own. Over the study's first 60 campaigns of a long yaw (test
// seeds 3500001..), the statement names the yaw in 35 and with the noise estimated from the
// residuals (the correlation 1/4) 29; over its first 60 effect-free ones (500001..), neither
// names anything. Stated a third of what it is, the statement is refused in every campaign (the
// diagnosis made without it scatters more), and that diagnosis stands, finding for finding.
TEST(HiddenEffects, EstNoiseTheProbesScatterStatesIsPooledAndChecked) {
  const auto yawNamed = [](const processing::Diagnosis& d) {
    return std::any_of(d.findings.begin(), d.findings.end(),
                       [](const auto& f) { return f.candidate.effect == "carriage_yaw"; });
  };
  int yaw_stated = 0, yaw_estimated = 0, alarms_stated = 0, alarms_estimated = 0, agreed = 0, refused = 0;
  for (std::uint64_t k = 1; k <= 60; ++k) {
    for (const bool yaw : {true, false}) {
      const std::uint64_t seed = (yaw ? 3500000 : 500000) + k;
      auto c = makeEstCampaign(seed, yaw ? std::vector<std::string>{"carriage_yaw"} : std::vector<std::string>{});
      const auto stated = processing::diagnose(processing::estDiagnosisData(c.run));
      agreed += stated.notes.back().find("the residuals agree with it") != std::string::npos;
      auto unknown = c.run;
      unknown.scatter_um = {};
      unknown.readings.clear();
      const auto estimated = processing::diagnose(processing::estDiagnosisData(unknown));
      if (yaw) {
        yaw_stated += yawNamed(stated);
        yaw_estimated += yawNamed(estimated);
      } else {
        alarms_stated += !stated.findings.empty();
        alarms_estimated += !estimated.findings.empty();
      }
      if (k > 10 || !yaw) continue;
      for (auto& probe : c.run.scatter_um)
        for (auto& s : probe) s /= 3.0;
      // The noise estimated, the correlation the probes' scatter gives kept (it does not scale).
      auto dropped = processing::estDiagnosisData(c.run);
      dropped.stated_noise_variance = dropped.stated_noise_dof = 0.0;
      const auto without = processing::diagnose(dropped);
      const auto understated = processing::diagnose(processing::estDiagnosisData(c.run));
      refused +=
          understated.notes.back().find("the residuals scatter more than the probes' scatter") != std::string::npos &&
          understated.stated_error.what == "noise" && understated.stated_error.outcome == "refused";
      ASSERT_EQ(understated.findings.size(), without.findings.size()) << seed;
      for (std::size_t f = 0; f < without.findings.size(); ++f) {
        EXPECT_EQ(understated.findings[f].candidate.effect, without.findings[f].candidate.effect);
        EXPECT_DOUBLE_EQ(understated.findings[f].delta_bic, without.findings[f].delta_bic);
      }
    }
  }
  EXPECT_EQ(yaw_stated, 35);
  EXPECT_EQ(yaw_estimated, 29);
  EXPECT_EQ(alarms_stated, 0);
  EXPECT_EQ(alarms_estimated, 0);
  EXPECT_GE(agreed, 115);  // alpha 0.01: a refusal or two of 120 where the statement is right
  EXPECT_EQ(refused, 10);
}

// A long yaw the diagnosis with the noise estimated misses leaves its residuals scattering more
// than the probes state: the statement was refused there, and the yaw left unnamed (the study's
// campaign 3500204: a yaw of 24.9 urad peak to valley over 20 steps, residuals 0.107 um RMS
// against a stated 0.055). From one point to the next they agree with it (what is left is slow):
// it is taken, and the yaw named, its peak to valley within 2 standard errors of the truth.
TEST(HiddenEffects, EstNoiseIsTakenWhereWhatTheResidualsHoldBeyondItIsSlow) {
  const auto c = makeEstCampaign(3500204, {"carriage_yaw"});
  const auto d = processing::diagnose(processing::estDiagnosisData(c.run));
  EXPECT_EQ(d.stated_error.outcome, "taken");
  EXPECT_LT(d.stated_error.p_value, 0.01);
  EXPECT_GE(d.stated_error.p_value_point_to_point, 0.1);
  EXPECT_NE(d.notes.back().find("from one point to the next they agree with it"), std::string::npos);
  ASSERT_EQ(d.findings.size(), 1u);
  EXPECT_EQ(d.findings[0].candidate.effect, "carriage_yaw");
  const double truth = c.truth.at(0).parameters.at("yaw_peak_to_valley");
  EXPECT_NEAR(truth, 24.9, 0.05);
  int compared = 0;
  for (const auto& p : d.findings[0].parameters) {
    if (p.name != "yaw_peak_to_valley") continue;
    EXPECT_NEAR(p.value, truth, 2.0 * p.standard_error);
    ++compared;
  }
  EXPECT_EQ(compared, 1);
}

// A smooth curve of the position on probe 3 is what a carriage yaw makes (any such curve is
// some yaw's change per step): the yaw's spline stands for it, and no generic curve of the
// position is tried. The study's campaigns of a long yaw beside a spacing error (test seeds)
// named a generic curve of the position in 7 of 300, where the yaw is the cause (peak to
// valley 26 to 61 urad). None does now; five of them name the yaw (two before the probes' stated
// noise was taken where the residuals agree with it from one point to the next).
TEST(HiddenEffects, EstSmoothCurveOfThePositionIsTheYawsNotAGenericOne) {
  int yaw = 0;
  for (const std::uint64_t seed : {6500003, 6500093, 6500147, 6500207, 6500209, 6500283, 6500296}) {
    const auto c = makeEstCampaign(seed, {"scale_error", "carriage_yaw"});
    const auto d = processing::diagnose(processing::estDiagnosisData(c.run));
    for (const auto& f : d.findings) {
      EXPECT_NE(f.candidate.effect, "generic") << seed << ": " << f.candidate.variable;
      yaw += f.candidate.effect == "carriage_yaw";
    }
    for (const auto& considered : d.considered)
      EXPECT_FALSE(considered.effect == "generic" && considered.variable != "profile_slope") << considered.variable;
  }
  EXPECT_EQ(yaw, 5);
}

}  // namespace
}  // namespace mtcal::mocks
