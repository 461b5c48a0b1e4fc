#include "mtcal/mocks/hidden_effects.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <numeric>

#include "mtcal/error.h"
#include "mtcal/mocks/random.h"
#include "mtcal/mocks/virtual_machine.h"
#include "mtcal/processing/error_model.h"

namespace mtcal::mocks {
namespace {

constexpr double kTwoPi = 2.0 * std::numbers::pi;
constexpr double kTargetTimeS = 6.0;
constexpr double kScatterUm = 0.5;       // a reading's positioning scatter per approach
constexpr double kOpticsNoiseUm = 0.05;  // the optics' noise
constexpr int kEarlierRepeats = 10;      // the model's earlier run: readings per position

/// Draws of one campaign: uniform in [lo, hi) keyed to (seed, what).
struct Draw {
  std::uint64_t seed;
  std::uint64_t next = 0;
  double uniform(double lo, double hi) {
    return lo + (hi - lo) * uniformFromKey(mix64(seed * 0x9E3779B97F4A7C15ULL + ++next));
  }
  double sign() { return uniform(0.0, 1.0) < 0.5 ? -1.0 : 1.0; }
  double normal(std::uint64_t stream, std::uint64_t index) const { return normalFromKey(seed, stream, index); }
};

/// The readings a probe averages at a step of an EST campaign.
constexpr int kEstReadingsPerStep = 10;

bool needsModel(const std::string& effect) { return effect == "scale_error" || effect == "abbe_error"; }
bool drifts(const std::string& effect) { return effect == "thermal_drift" || effect == "thermal_growth"; }

}  // namespace

const std::vector<std::string>& hiddenEffectNames() {
  static const std::vector<std::string> names = {
      "backlash",    "cyclic_error", "thermal_drift",      "environment_compensation",
      "scale_error", "abbe_error",   "channel_dependence", "thermal_growth"};
  return names;
}

HiddenEffectCampaign makeLinearCampaign(const CampaignRequest& request) {
  HiddenEffectCampaign c;
  c.seed = request.seed;
  Draw draw{request.seed};
  std::vector<std::string> effects = request.effects;
  if (request.random) {
    c.with_model = draw.uniform(0.0, 1.0) < 0.5;
    c.grid_plan = draw.uniform(0.0, 1.0) < 0.5;
    const double u = draw.uniform(0.0, 1.0);
    const int count = u < 0.3 ? 0 : (u < 0.8 ? 1 : 2);
    std::vector<std::string> pool;
    for (const auto& e : hiddenEffectNames()) {
      if (c.with_model || !needsModel(e)) pool.push_back(e);
    }
    effects.clear();
    while (static_cast<int>(effects.size()) < count) {
      const auto& e = pool[static_cast<std::size_t>(draw.uniform(0.0, static_cast<double>(pool.size())))];
      if (std::find(effects.begin(), effects.end(), e) != effects.end()) continue;
      // A growth carries its own offset drift with the same time constant: a second drift
      // beside it is one cause told twice.
      if (!effects.empty() && drifts(e) && drifts(effects.front())) continue;
      effects.push_back(e);
    }
  } else {
    for (const auto& e : effects) {
      if (std::find(hiddenEffectNames().begin(), hiddenEffectNames().end(), e) == hiddenEffectNames().end()) {
        throw InputError(fmt::format("hidden effect '{}': not one the generator knows", e));
      }
    }
    if (std::count_if(effects.begin(), effects.end(), drifts) > 1) {
      throw InputError("hidden effects thermal_drift and thermal_growth: a growth carries its own drift; hide one");
    }
    c.with_model = request.with_model >= 0
                       ? request.with_model == 1
                       : std::any_of(effects.begin(), effects.end(), [](const auto& e) { return needsModel(e); });
    c.grid_plan = request.grid_plan >= 0 ? request.grid_plan == 1 : draw.uniform(0.0, 1.0) < 0.5;
  }
  for (const auto& [e, size] : request.sizes) {
    if (request.random || std::find(effects.begin(), effects.end(), e) == effects.end()) {
      throw InputError(fmt::format("hidden effect '{}': a size is given for an effect that is not requested", e));
    }
  }
  // The size requested for an effect, else the one drawn (drawn either way: the draws after it stay the same).
  auto sized = [&](const std::string& e, double drawn) {
    const auto it = request.sizes.find(e);
    return it == request.sizes.end() ? drawn : it->second;
  };
  auto hidden = [&](const std::string& e) { return std::find(effects.begin(), effects.end(), e) != effects.end(); };

  // The machine before the hidden effects, and as measured.
  VirtualMachineConfig before = VirtualMachineConfig::demo(request.seed);
  for (auto& a : before.axes) a.backlash_um = 0.0;
  // Pitch (urad): a bow, so that an Abbe error is not a scale error.
  before.errors["EBX"] = {{0.0, draw.uniform(40.0, 80.0), -draw.uniform(150.0, 250.0)}, {}};
  VirtualMachineConfig after = before;
  if (hidden("backlash")) after.axes[0].backlash_um = sized("backlash", draw.uniform(1.5, 6.0));
  ErrorCurve cyclic;
  double scale_ppm = 0.0;
  if (hidden("cyclic_error")) {
    const double leads[] = {4.0, 5.0, 6.35, 8.0, 10.0, 12.7, 16.0};
    const double period = leads[static_cast<int>(draw.uniform(0.0, 7.0))];
    const double amplitude = sized("cyclic_error", draw.uniform(0.5, 2.0));
    cyclic.harmonics.push_back({amplitude, period, draw.uniform(0.0, kTwoPi)});
    after.errors["EXX"].harmonics.push_back(cyclic.harmonics.back());
    c.truth.push_back({"cyclic_error", {{"amplitude", amplitude}, {"period", period}}});
  }
  if (hidden("scale_error")) {
    const double ppm = scale_ppm = sized("scale_error", draw.sign() * draw.uniform(3.0, 15.0));
    after.errors["EXX"].poly.resize(std::max<std::size_t>(after.errors["EXX"].poly.size(), 2), 0.0);
    after.errors["EXX"].poly[1] += ppm;  // um/m
    c.truth.push_back({"scale_error", {{"scale", ppm}}});
  }
  const ToolOffset no_offset{0.0, 0.0, 0.0};
  ToolOffset optics = no_offset;
  if (hidden("abbe_error")) optics[2] = sized("abbe_error", draw.sign() * draw.uniform(20.0, 80.0));
  WorldClock clock;
  VirtualMachine machine_before(before, clock), machine_after(after, clock);

  // The plan.
  std::vector<double> targets;
  int cycles = 5;
  if (c.grid_plan) {
    for (int k = 0; k <= 20; ++k) targets.push_back(20.0 * k);
  } else {
    cycles = 3;
    for (int k = 0; k < 100; ++k) targets.push_back(draw.uniform(0.0, 400.0));
    std::sort(targets.begin(), targets.end());
  }
  const double duration_s = kTargetTimeS * static_cast<double>(targets.size() * 2 * static_cast<std::size_t>(cycles));

  // Environment over the run.
  const double air_swing = draw.uniform(0.4, 1.5), air_period = draw.uniform(1200.0, 3600.0),
               air_phase = draw.uniform(0.0, kTwoPi);
  const double pressure_swing = draw.uniform(20.0, 150.0), pressure_period = draw.uniform(3000.0, 9000.0);
  const double material_rise = draw.uniform(-0.3, 0.5);
  // An auxiliary channel that wanders like an AR(1) process (a coolant's temperature):
  // correlation time 5..30 min, standard deviation 0.2..1 K.
  const double coolant_sd = draw.uniform(0.2, 1.0), coolant_tau = draw.uniform(300.0, 1800.0);
  double drift_amplitude = 0.0, drift_tau = 1.0, env_coefficient = 0.0;
  double growth_ppm = 0.0;
  double channel_sensitivity = 0.0, channel_curvature = 0.0;
  const double last_s = duration_s - kTargetTimeS;  // the run's last reading
  if (hidden("thermal_drift")) {
    drift_amplitude = sized("thermal_drift", draw.sign() * draw.uniform(2.0, 8.0));
    drift_tau = draw.uniform(0.2, 1.0) * duration_s;
    c.truth.push_back({"thermal_drift",
                       {{"amplitude", drift_amplitude},
                        {"time_constant", drift_tau},
                        {"drift_over_run", drift_amplitude * (1.0 - std::exp(-last_s / drift_tau))}}});
  }
  if (hidden("environment_compensation")) {
    env_coefficient = sized("environment_compensation", draw.sign() * draw.uniform(0.4, 1.2));
    c.truth.push_back({"environment_compensation", {{"air_temp_coefficient", env_coefficient}}});
  }
  if (hidden("thermal_growth")) {
    // The axis grows along its travel with a first-order response (growth_ppm at x mm reached
    // after the time constant), its datum drifting with it by drift_amplitude.
    growth_ppm = sized("thermal_growth", draw.sign() * draw.uniform(4.0, 15.0));
    drift_amplitude = draw.sign() * draw.uniform(1.0, 4.0);
    drift_tau = draw.uniform(0.2, 1.0) * duration_s;
    c.truth.push_back({"thermal_growth",
                       {{"growth", growth_ppm},
                        {"amplitude", drift_amplitude},
                        {"time_constant", drift_tau},
                        {"growth_over_run", growth_ppm * (1.0 - std::exp(-last_s / drift_tau))}}});
  }
  if (hidden("channel_dependence")) {
    // Linear in the channel (um/K), or a smooth curve of it: half of each.
    const bool smooth = draw.uniform(0.0, 1.0) < 0.5;
    channel_sensitivity = sized("channel_dependence", draw.sign() * draw.uniform(1.0, 3.0) / coolant_sd);
    if (smooth) channel_curvature = draw.sign() * draw.uniform(1.0, 2.0) * std::abs(channel_sensitivity) / coolant_sd;
  }

  // The model: the error curve identified from an earlier effect-free run of the machine
  // (20 mm grid, 5 bidirectional cycles, the same scatter), knots 20 mm apart.
  processing::ErrorCurveData earlier{"EXX", {}, {}, {}, {}};
  for (int k = 0; k <= 20; ++k) {
    const double x = 20.0 * k;
    double sum = 0.0, sum2 = 0.0;
    for (int r = 0; r < kEarlierRepeats; ++r) {
      const double v = machine_before.staticErrorUm(Axis::kX, no_offset, x, r % 2 ? -1 : 1) +
                       kScatterUm * draw.normal(6, static_cast<std::uint64_t>(k * 10 + r)) +
                       kOpticsNoiseUm * draw.normal(7, static_cast<std::uint64_t>(k * 10 + r));
      sum += v;
      sum2 += v * v;
    }
    earlier.position_mm.push_back(x);
    earlier.mean.push_back(sum / kEarlierRepeats);
    earlier.s.push_back(std::sqrt(std::max(0.0, (sum2 - sum * sum / kEarlierRepeats) / (kEarlierRepeats - 1))));
    earlier.repeats.push_back(kEarlierRepeats);
  }
  const processing::ErrorFitOptions model_fit{3, 20.0};
  const auto model = processing::ErrorFunction::fit(earlier, model_fit);

  auto& run = c.run;
  run.source = fmt::format("hidden-effect campaign {}", request.seed);
  const std::size_t points = targets.size() * 2 * static_cast<std::size_t>(cycles);
  std::vector<double> air(points), pressure, material, coolant(points);
  const double coolant_phi = std::exp(-kTargetTimeS / coolant_tau);
  double wander = coolant_sd * draw.normal(8, 0);
  for (std::size_t i = 0; i < points; ++i) {
    air[i] = 20.3 + air_swing * std::sin(kTwoPi * kTargetTimeS * static_cast<double>(i) / air_period + air_phase) +
             0.01 * draw.normal(3, i);
    if (i > 0)
      wander = coolant_phi * wander + coolant_sd * std::sqrt(1.0 - coolant_phi * coolant_phi) * draw.normal(8, i);
    coolant[i] = 22.0 + wander + 0.005 * draw.normal(9, i);
  }
  const double coolant_mean = std::accumulate(coolant.begin(), coolant.end(), 0.0) / static_cast<double>(points);
  // The compensation's error follows the air's change over the run (its mean is a scale error).
  const double air_mean = std::accumulate(air.begin(), air.end(), 0.0) / static_cast<double>(points);
  std::vector<std::vector<double>> angles(2);
  std::uint64_t point = 0;
  for (int cycle = 1; cycle <= cycles; ++cycle) {
    for (int direction : {1, -1}) {
      for (std::size_t k = 0; k < targets.size(); ++k) {
        const double x = direction > 0 ? targets[k] : targets[targets.size() - 1 - k];
        const double t = kTargetTimeS * static_cast<double>(point);
        const double t_air = air[point];
        const double at_optics = machine_after.staticErrorUm(Axis::kX, optics, x, direction);
        const double response = 1.0 - std::exp(-t / drift_tau);
        const double drift = drift_amplitude * response;
        const double growth = growth_ppm * 1e-3 * x * response;
        const double compensation = env_coefficient * 1e-3 * x * (t_air - air_mean);
        const double dc = coolant[point] - coolant_mean;
        const double follows_channel = channel_sensitivity * dc + channel_curvature * dc * dc;
        double value = at_optics;
        value += kScatterUm * draw.normal(1, point) + kOpticsNoiseUm * draw.normal(2, point);
        value += drift + growth;
        value += compensation;
        value += follows_channel;
        // What each hidden effect adds here (for its size).
        for (const auto& effect : effects) {
          double added = 0.0;
          if (effect == "backlash") {
            added = machine_after.staticErrorUm(Axis::kX, no_offset, x, direction) -
                    0.5 * (machine_after.staticErrorUm(Axis::kX, no_offset, x, 1) +
                           machine_after.staticErrorUm(Axis::kX, no_offset, x, -1));
          } else if (effect == "cyclic_error") {
            added = cyclic.value(x);
          } else if (effect == "scale_error") {
            added = scale_ppm * 1e-3 * x;
          } else if (effect == "abbe_error") {
            added = at_optics - machine_after.staticErrorUm(Axis::kX, no_offset, x, direction);
          } else if (effect == "thermal_drift") {
            added = drift;
          } else if (effect == "thermal_growth") {
            added = drift + growth;
            c.simpler_part_um[effect].push_back(drift);
          } else if (effect == "channel_dependence") {
            added = follows_channel;
          } else if (effect == "environment_compensation") {
            added = compensation;
          }
          c.added_um[effect].push_back(added);
        }
        run.position_mm.push_back(x);
        run.direction.push_back(direction);
        run.cycle.push_back(cycle);
        run.time_s.push_back(t);
        run.deviation_um.push_back(value);
        pressure.push_back(101000.0 + pressure_swing * std::sin(kTwoPi * t / pressure_period) +
                           2.0 * draw.normal(4, point));
        material.push_back(20.5 + material_rise * t / duration_s + 0.01 * draw.normal(5, point));
        if (c.with_model) {
          run.simulated_um.push_back(model.value(x));
          angles[0].push_back(before.trueError("EBX", x));
          angles[1].push_back(before.trueError("ECX", x));
        }
        ++point;
      }
    }
  }
  auto column = [](const std::string& name, const std::string& unit, const std::vector<double>& v) {
    return processing::DiagnosisVariable{
        name, unit, Eigen::Map<const Eigen::VectorXd>(v.data(), static_cast<Eigen::Index>(v.size()))};
  };
  run.channels = {column("air_temp_c", "degC", air), column("air_pressure_pa", "Pa", pressure),
                  column("material_temp_c", "degC", material), column("coolant_temp_c", "degC", coolant)};
  c.reading_noise_um = std::hypot(kScatterUm, kOpticsNoiseUm);
  if (c.with_model) {
    // The model's own error as it states it (its nodes' pooled scatter through its fit); the
    // oracle's is the same with the readings' true scatter.
    run.model_description = "the error curve identified from an earlier effect-free run";
    run.simulated_error_factor_um = model.fitErrorFactor(
        Eigen::Map<const Eigen::VectorXd>(run.position_mm.data(), static_cast<Eigen::Index>(points)));
    double stated_variance = 0.0;
    for (const auto& s : earlier.s) stated_variance += *s * *s / static_cast<double>(earlier.s.size());
    c.model_error_covariance_um2 = c.reading_noise_um * c.reading_noise_um / stated_variance *
                                   run.simulated_error_factor_um * run.simulated_error_factor_um.transpose();
    run.model_angles_urad = {column("EBX_urad", "urad", angles[0]), column("ECX_urad", "urad", angles[1])};
  }
  if (hidden("backlash")) {
    const double reversal = machine_after.staticErrorUm(Axis::kX, optics, 200.0, 1) -
                            machine_after.staticErrorUm(Axis::kX, optics, 200.0, -1);
    c.truth.push_back({"backlash", {{"reversal", reversal}}});
  }
  if (hidden("abbe_error")) {
    // The offset the reading's change per urad of pitch shows (first order, exact for this machine).
    const double d_um = (machine_after.staticErrorUm(Axis::kX, optics, 400.0, 1) -
                         machine_after.staticErrorUm(Axis::kX, no_offset, 400.0, 1)) -
                        (machine_after.staticErrorUm(Axis::kX, optics, 0.0, 1) -
                         machine_after.staticErrorUm(Axis::kX, no_offset, 0.0, 1));
    const double d_angle = before.trueError("EBX", 400.0) - before.trueError("EBX", 0.0);
    c.truth.push_back({"abbe_error", {{"offset", d_um / (d_angle * 1e-3)}}});
  }
  if (hidden("channel_dependence")) {
    HiddenEffect h{"channel_dependence", {{"smooth", channel_curvature != 0.0 ? 1.0 : 0.0}}};
    if (channel_curvature == 0.0) {
      h.parameters["sensitivity"] = channel_sensitivity;
    } else {
      const auto& v = c.added_um["channel_dependence"];
      h.parameters["peak_to_valley"] = *std::max_element(v.begin(), v.end()) - *std::min_element(v.begin(), v.end());
    }
    c.truth.push_back(h);
  }
  // Sizes: the RMS of what each effect adds about its mean (the part a zero cannot absorb).
  for (auto& h : c.truth) {
    const auto& v = c.added_um[h.effect];
    const double mean = std::accumulate(v.begin(), v.end(), 0.0) / static_cast<double>(v.size());
    double ss = 0.0;
    for (double x : v) ss += (x - mean) * (x - mean);
    h.parameters["size_rms"] = std::sqrt(ss / static_cast<double>(v.size()));
  }
  return c;
}

EstCampaign makeEstCampaign(std::uint64_t seed, const std::vector<std::string>& effects) {
  static const std::vector<std::string> known = {"probe_offset", "scale_error", "carriage_yaw", "carriage_yaw_short"};
  for (const auto& e : effects) {
    if (std::find(known.begin(), known.end(), e) == known.end())
      throw InputError(fmt::format("hidden EST effect '{}': not one the generator knows", e));
  }
  auto hidden = [&](const char* e) { return std::find(effects.begin(), effects.end(), e) != effects.end(); };
  EstCampaign c;
  c.seed = seed;
  Draw draw{seed};
  const int steps = static_cast<int>(draw.uniform(20.0, 41.0));
  const double d = draw.uniform(20.0, 30.0), length = d * (steps + 1);
  const double noise_um = draw.uniform(0.02, 0.05);
  // The guideway: a tilted line, a bow and two waves.
  const double tilt = draw.sign() * draw.uniform(0.05, 0.2), bow = draw.uniform(-4.0, 4.0);
  const double wave1 = draw.uniform(0.5, 2.0), period1 = draw.uniform(0.3, 0.8) * length,
               phase1 = draw.uniform(0.0, kTwoPi);
  const double wave2 = draw.uniform(0.1, 0.5), period2 = draw.uniform(60.0, 150.0), phase2 = draw.uniform(0.0, kTwoPi);
  auto profile = [&](double x) {
    const double u = x / length - 0.5;
    return tilt * x + bow * 4.0 * u * u + wave1 * std::sin(kTwoPi * x / period1 + phase1) +
           wave2 * std::sin(kTwoPi * x / period2 + phase2);
  };
  std::array<double, 3> zero{0.0, 0.0, 0.0};
  if (hidden("probe_offset")) {
    // A combination c1 - 2 c2 + c3 of 0.1..1 um, spread over the three zeros.
    const double combination = draw.sign() * draw.uniform(0.1, 1.0);
    zero[0] = draw.uniform(-0.5, 0.5);
    zero[2] = draw.uniform(-0.5, 0.5);
    zero[1] = (zero[0] + zero[2] - combination) / 2.0;
    c.truth.push_back({"probe_offset", {{"zero_combination", combination}}});
  }
  double spacing_error_mm = 0.0;
  if (hidden("scale_error")) {
    spacing_error_mm = draw.sign() * draw.uniform(0.2, 1.0);
    c.truth.push_back({"scale_error", {{"spacing_error", spacing_error_mm}}});
  }
  double yaw_amplitude = 0.0, yaw_wavelength = 1.0, yaw_phase = 0.0;
  if (hidden("carriage_yaw") || hidden("carriage_yaw_short")) {
    const bool short_wave = hidden("carriage_yaw_short");
    yaw_amplitude = short_wave ? draw.uniform(20.0, 60.0) : draw.uniform(5.0, 30.0);
    yaw_wavelength = short_wave ? draw.uniform(2.5, 6.0) * d : draw.uniform(0.5, 1.5) * length;
    yaw_phase = draw.uniform(0.0, kTwoPi);
    // What the diagnosis reports: the yaw's peak to valley about its line over the steps'
    // positions, 0 .. d (steps - 1) (the yaw elsewhere enters no reading).
    const double span = d * (steps - 1);
    std::vector<double> xs, ys;
    for (int k = 0; k <= 400; ++k) {
      xs.push_back(span * k / 400.0);
      ys.push_back(yaw_amplitude * std::sin(kTwoPi * xs.back() / yaw_wavelength + yaw_phase));
    }
    const double mx = std::accumulate(xs.begin(), xs.end(), 0.0) / xs.size(),
                 my = std::accumulate(ys.begin(), ys.end(), 0.0) / ys.size();
    double sxy = 0.0, sxx = 0.0;
    for (std::size_t k = 0; k < xs.size(); ++k) {
      sxy += (xs[k] - mx) * (ys[k] - my);
      sxx += (xs[k] - mx) * (xs[k] - mx);
    }
    double lo = 0.0, hi = 0.0;
    for (std::size_t k = 0; k < xs.size(); ++k) {
      const double about = ys[k] - my - sxy / sxx * (xs[k] - mx);
      lo = std::min(lo, about);
      hi = std::max(hi, about);
    }
    c.truth.push_back({"carriage_yaw",
                       {{"amplitude", yaw_amplitude},
                        {"wavelength", yaw_wavelength},
                        {"short", short_wave ? 1.0 : 0.0},
                        {"yaw_peak_to_valley", hi - lo}}});
  }
  auto& run = c.run;
  run.source = fmt::format("hidden-effect EST campaign {}", seed);
  run.spacing_mm = d;
  // What probe 3 reads less the two-probe prediction, noise-free, with the effects given.
  const auto residual = [&](bool zeros, bool spacing, bool yaw) {
    std::vector<double> v1, v2, v3, r;
    for (int k = 0; k < steps; ++k) {
      const double x = d * k, g = yaw ? 1e-6 * yaw_amplitude * std::sin(kTwoPi * x / yaw_wavelength + yaw_phase) : 0.0;
      const double p3 = 2 * d + (spacing ? spacing_error_mm : 0.0);
      v1.push_back(profile(x) + (zeros ? zero[0] : 0.0));
      v2.push_back(profile(x + d) - d * g * 1e3 + (zeros ? zero[1] : 0.0));
      v3.push_back(profile(x + p3) - p3 * g * 1e3 + (zeros ? zero[2] : 0.0));
    }
    for (int k = 0; k + 1 < steps; ++k) r.push_back(v3[k] - v2[k] - v2[k + 1] + v1[k + 1]);
    return r;
  };
  // Each effect's size: the RMS about its mean of what it adds to that residual (for the
  // zeros, which add a constant, the constant), against the residual's noise (2 x a probe's).
  const auto none = residual(false, false, false);
  c.probe_noise_um = noise_um;
  for (auto& h : c.truth) {
    const auto with = residual(h.effect == "probe_offset", h.effect == "scale_error", h.effect == "carriage_yaw");
    double mean = 0.0, ss = 0.0;
    for (std::size_t k = 0; k < with.size(); ++k) mean += (with[k] - none[k]) / static_cast<double>(with.size());
    for (std::size_t k = 0; k < with.size(); ++k) ss += std::pow(with[k] - none[k] - mean, 2);
    h.parameters["size_rms"] =
        h.effect == "probe_offset" ? std::abs(mean) : std::sqrt(ss / static_cast<double>(with.size()));
    h.parameters["noise_rms"] = 2.0 * noise_um;
  }
  // What each effect adds beside those before it in the truth, so that together they are what
  // the readings carry (a spacing error and a yaw together add their product too: the later's).
  // A yaw's mean rate and a spacing error (times the profile's mean slope) read as a constant on
  // probe 3 (constant_um), as the zeros' combination does. A long yaw's and a spacing error's is
  // the zeros' (three probes cannot tell them apart); a short wave's sine keeps its own.
  bool zeros = false, spacing = false, yaw = false;
  auto before = none;
  for (auto& h : c.truth) {
    zeros = zeros || h.effect == "probe_offset";
    spacing = spacing || h.effect == "scale_error";
    yaw = yaw || h.effect == "carriage_yaw";
    const auto after = residual(zeros, spacing, yaw);
    auto& added = c.added_um[h.effect];
    for (std::size_t k = 0; k < after.size(); ++k) added.push_back(after[k] - before[k]);
    if (h.effect == "scale_error" || h.effect == "carriage_yaw") {
      const double constant = std::accumulate(added.begin(), added.end(), 0.0) / static_cast<double>(added.size());
      h.parameters["constant_um"] = constant;
      if (h.effect == "scale_error" || h.parameters.at("short") == 0.0)
        c.simpler_part_um[h.effect].assign(added.size(), constant);
    }
    before = after;
  }
  for (int k = 0; k < steps; ++k) {
    const double x = d * k;
    const double carriage = draw.normal(20, static_cast<std::uint64_t>(k));
    const double yaw_rad = 1e-6 * yaw_amplitude * std::sin(kTwoPi * x / yaw_wavelength + yaw_phase);
    run.position_mm.push_back(x);
    const auto index = static_cast<std::uint64_t>(k);
    // v_i = m(x + (i - 1) d) - e - (i - 1) d gamma + c_i + noise (probe 3 at 2 d + its error).
    run.v1_um.push_back(profile(x) - carriage + zero[0] + noise_um * draw.normal(21, index));
    run.v2_um.push_back(profile(x + d) - carriage - d * yaw_rad * 1e3 + zero[1] + noise_um * draw.normal(22, index));
    run.v3_um.push_back(profile(x + 2 * d + spacing_error_mm) - carriage - (2 * d + spacing_error_mm) * yaw_rad * 1e3 +
                        zero[2] + noise_um * draw.normal(23, index));
    // Each step's reading the mean of kEstReadingsPerStep, their scatter drawn as a normal
    // sample's (independent of its mean): (n - 1) s^2 / sigma^2 is chi^2 of n - 1.
    run.readings.push_back(kEstReadingsPerStep);
    for (std::uint64_t p = 0; p < 3; ++p) {
      double chi2 = 0.0;
      for (std::uint64_t j = 0; j + 1 < static_cast<std::uint64_t>(kEstReadingsPerStep); ++j)
        chi2 += std::pow(draw.normal(24 + p, 16 * index + j), 2);
      run.scatter_um[p].push_back(noise_um * std::sqrt(kEstReadingsPerStep * chi2 / (kEstReadingsPerStep - 1.0)));
    }
  }
  return c;
}

std::string linearCampaignCsv(const HiddenEffectCampaign& campaign) {
  const auto& run = campaign.run;
  std::string csv = fmt::format("# {}\ntarget_mm,direction,cycle,deviation_um,time_s", run.source);
  for (const auto& c : run.channels) csv += "," + c.name;
  csv += "\n";
  for (std::size_t i = 0; i < run.position_mm.size(); ++i) {
    csv += fmt::format("{:.6f},{},{},{:.6f},{:.1f}", run.position_mm[i], run.direction[i] > 0 ? "+" : "-", run.cycle[i],
                       run.deviation_um[i], run.time_s[i]);
    for (const auto& c : run.channels) csv += fmt::format(",{:.6f}", c.values(static_cast<Eigen::Index>(i)));
    csv += "\n";
  }
  return csv;
}

}  // namespace mtcal::mocks
