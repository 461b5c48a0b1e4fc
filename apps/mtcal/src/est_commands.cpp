// Guideway straightness by error separation: from probe readings in a CSV file (mtcal est),
// a probe stepping run on the simulated machine (mtcal run est) and a stored run (mtcal
// analyze est). One separation and one report for all three.

#include <fmt/format.h>

#include <cmath>
#include <fstream>
#include <optional>
#include <nlohmann/json.hpp>

#include "commands.h"
#include "mtcal/acquisition/columns_csv.h"
#include "mtcal/acquisition/est_run.h"
#include "mtcal/services/workshop.h"
#include "mtcal/services/version.h"
#include "mtcal/error.h"
#include "mtcal/processing/est.h"
#include "report.h"

namespace mtcal::app {
namespace {

struct ProbeColumns {
  std::vector<double> x_mm, v1_um, v2_um, v3_um;
  std::optional<double> sigma_mean_um;  ///< standard deviation of one step's mean reading (stored runs)
};

struct Separation {
  processing::EstResult result;
  processing::Straightness straightness;
  nlohmann::json json;
};

Separation separate(const ProbeColumns& c, const EstOptions& options) {
  Separation s;
  if (options.method == "two-probe") {
    s.result = processing::separateTwoProbe(c.x_mm, c.v1_um, c.v2_um, options.spacing_mm,
                                            options.start == "second-point" ? processing::EstStart::kSecondPointOnly
                                                                            : processing::EstStart::kCarriageAtRest);
  } else if (options.method == "three-probe") {
    if (c.v3_um.empty()) throw InputError("the three-probe method needs a third probe's readings");
    s.result = processing::separateThreeProbe(c.x_mm, c.v1_um, c.v2_um, c.v3_um, options.spacing_mm);
  } else if (options.method == "frequency") {
    s.result = processing::separateFrequency(c.x_mm, c.v1_um, c.v2_um, options.spacing_mm);
  } else {
    throw InputError("method must be two-probe, three-probe or frequency");
  }
  s.straightness = processing::evaluateStraightness(s.result.x_mm, s.result.profile_um);
  if (c.sigma_mean_um) {
    // What the readings' scatter alone makes of the profile (docs/est.md, noise propagation).
    nlohmann::json noise = nlohmann::json::array();
    for (std::size_t k = 0; k < c.x_mm.size(); ++k) {
      const int kk = static_cast<int>(k);
      noise.push_back(options.method == "three-probe" ? processing::threeProbeNoiseUm(kk, *c.sigma_mean_um)
                                                      : processing::twoProbeNoiseUm(kk, *c.sigma_mean_um));
    }
    s.json["noise_um"] = noise;
  }
  s.json.update(nlohmann::json{{"method", options.method},
            {"spacing_mm", options.spacing_mm},
            {"x_mm", s.result.x_mm},
            {"straightness_um", s.result.profile_um},
            {"carriage_um", s.result.carriage_um},
            {"straightness_lsq_um", s.straightness.least_squares_um},
            {"straightness_minzone_um", s.straightness.min_zone_um},
            {"straightness_endpoint_um", s.straightness.end_point_um},
            {"lost_wavelengths_mm", s.result.lost_wavelengths_mm}});
  return s;
}

void report(const Globals& g, const Separation& s, const EstOptions& options, nlohmann::json extra = {}) {
  if (g.json) {
    nlohmann::json out = s.json;
    if (extra.is_object()) out.update(extra);
    *g.out << out.dump() << "\n";
    return;
  }
  const auto& r = s.result;
  *g.out << fmt::format("{} separation, probe spacing {} mm, {} points\n\n", options.method, options.spacing_mm,
                        r.x_mm.size());
  *g.out << "      x_mm   profile_um  carriage_um\n";
  for (std::size_t k = 0; k < r.x_mm.size(); ++k) {
    *g.out << fmt::format("{:>10.3f} {:>12.3f} {:>12}\n", r.x_mm[k], r.profile_um[k],
                          k < r.carriage_um.size() ? fmt::format("{:.3f}", r.carriage_um[k]) : "-");
  }
  *g.out << fmt::format("\nstraightness (um): least squares {:.3f}, minimum zone {:.3f}, end points {:.3f}\n",
                        s.straightness.least_squares_um, s.straightness.min_zone_um, s.straightness.end_point_um);
  if (s.json.contains("noise_um")) {
    *g.out << fmt::format("reading scatter alone: {:.3f} um (1 sigma) at the last point\n",
                          s.json["noise_um"].back().get<double>());
  }
  if (!r.lost_wavelengths_mm.empty()) {
    *g.out << fmt::format("harmonics lost by the frequency method: wavelengths {} mm\n",
                          fmt::join(r.lost_wavelengths_mm, ", "));
  }
}

ProbeColumns storedColumns(storage::Store& store, storage::Id run_id, EstOptions& options) {
  const auto info = store.run(run_id);
  if (info.kind != "est") throw InputError(fmt::format("run {} is a {} run, not a probe stepping (est) run", run_id, info.kind));
  const auto plan = acquisition::EstPlan::fromJson(nlohmann::json::parse(info.plan_json), fmt::format("run {} plan", run_id));
  if (!(options.spacing_mm > 0.0)) options.spacing_mm = plan.spacing_mm;
  ProbeColumns c;
  double ss = 0.0;
  int dof = 0, readings = 0;
  for (const auto& step : store.probeSteps(run_id)) {
    c.x_mm.push_back(step.position_mm);
    for (const auto& ch : step.channels) {
      (ch.channel == 1 ? c.v1_um : ch.channel == 2 ? c.v2_um : c.v3_um).push_back(ch.value_um);
      if (ch.s_um) {
        ss += (ch.readings - 1) * *ch.s_um * *ch.s_um;
        dof += ch.readings - 1;
        readings = ch.readings;
      }
    }
  }
  if (dof > 0) c.sigma_mean_um = std::sqrt(ss / dof / readings);  // pooled s of one reading / sqrt(n)
  if (c.x_mm.size() < 3) throw InputError(fmt::format("run {} has {} steps stored: too few to separate", run_id, c.x_mm.size()));
  return c;
}

}  // namespace

int estimateStraightness(const Globals& g, const EstOptions& options) {
  std::ifstream in(options.csv_path);
  if (!in) throw InputError(options.csv_path + ": cannot open file");
  std::vector<std::string> required{"x_mm", "v1_um", "v2_um"};
  if (options.method == "three-probe") required.push_back("v3_um");
  const auto columns = acquisition::readColumnsCsv(in, options.csv_path, required, {"v3_um"});
  ProbeColumns c;
  c.x_mm = columns.at("x_mm");
  c.v1_um = columns.at("v1_um");
  c.v2_um = columns.at("v2_um");
  if (columns.count("v3_um")) c.v3_um = columns.at("v3_um");
  report(g, separate(c, options), options);
  return 0;
}

int analyzeEst(const Globals& g, storage::Id run_id, const EstOptions& given) {
  storage::Store store(g.db);
  EstOptions options = given;
  const auto columns = storedColumns(store, run_id, options);
  const auto s = separate(columns, options);
  store.addResult(run_id, "est", kVersion, nlohmann::json{{"method", options.method}, {"start", options.start}}.dump(),
                  s.json.dump());
  report(g, s, options, {{"run_id", run_id}});
  return 0;
}

int runEst(const Globals& g, const std::string& plan_path, const std::string& device_uri, const SimulationOptions& sim_options) {
  const auto plan = acquisition::EstPlan::load(plan_path);
  if (drivers::DeviceUri::parse(device_uri).scheme != "mock") {
    throw InputError("probe stepping runs step the simulated machine (mock://probes); stepping a real machine by a part "
                     "program is not built yet: import its readings with `mtcal est FILE.csv`");
  }
  std::string file_json;
  const auto config = machineConfig(sim_options, &file_json);
  Simulation sim(config, demoInterferometer(), sim_options.time_scale);
  auto box = sim.registry.openAs<drivers::probes::ProbeBoxDevice>(device_uri);
  storage::Store store(g.db);
  const auto info = box->info();
  const storage::Id instrument_id = store.ensureInstrument({info.kind, info.model, info.serial, info.firmware, device_uri});
  const storage::Id machine_id = store.ensureMachine(machineName(config, !file_json.empty()), "simulated machine",
                                                     simulationDescription(config, file_json));
  const storage::Id campaign_id = store.addCampaign(machine_id, plan.name);
  ProgressBar bar(*g.err, g.terminal);
  acquisition::EstRunOptions options;
  options.stop_requested = g.stop;
  options.run_clock = &sim.run_clock;
  options.software_version = kVersion;
  if (!g.json) {
    options.on_progress = [&bar](const acquisition::EstProgress& p) {
      bar.update(static_cast<std::size_t>(p.done), static_cast<std::size_t>(p.total), fmt::format("{:>8.3f} mm", p.position_mm));
    };
  }
  acquisition::EstRun run(store, *box, sim.controller, options);
  const storage::Id run_id = run.start(plan, campaign_id, instrument_id);
  bar.finish();
  if (run.outcome() == acquisition::RunOutcome::kInterrupted) {
    *g.err << fmt::format("run {} interrupted; its steps are stored\n", run_id);
    return 1;
  }
  EstOptions est;
  est.method = plan.probes == 3 ? "three-probe" : "two-probe";
  est.spacing_mm = plan.spacing_mm;
  auto stored = est;
  const auto s = separate(storedColumns(store, run_id, stored), est);
  store.addResult(run_id, "est", kVersion, nlohmann::json{{"method", est.method}}.dump(), s.json.dump());
  report(g, s, est, {{"run_id", run_id}});
  if (!g.json) *g.out << fmt::format("\nStored as run {}. Again, or by another method: mtcal analyze est {}\n", run_id, run_id);
  return 0;
}

}  // namespace mtcal::app
