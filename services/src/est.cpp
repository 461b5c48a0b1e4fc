#include "mtcal/services/est.h"

#include <fmt/format.h>

#include <cmath>
#include <fstream>

#include "mtcal/acquisition/columns_csv.h"
#include "mtcal/drivers/uri.h"
#include "mtcal/error.h"
#include "mtcal/services/version.h"

namespace mtcal::services {

namespace {

ProbeReadings storedReadings(storage::Store& store, storage::Id run_id, EstMethod& method) {
  const auto info = store.run(run_id);
  if (info.kind != storage::run_kind::kEst) {
    throw InputError(fmt::format("run {} is a {} run, not a probe stepping (est) run", run_id, info.kind));
  }
  const auto plan =
      acquisition::EstPlan::fromJson(nlohmann::json::parse(info.plan_json), fmt::format("run {} plan", run_id));
  if (!(method.spacing_mm > 0.0)) method.spacing_mm = plan.spacing_mm;
  ProbeReadings c;
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
  if (c.x_mm.size() < 3)
    throw InputError(fmt::format("run {} has {} steps stored: too few to separate", run_id, c.x_mm.size()));
  return c;
}

EstAnalysis separateAndStore(Session& session, storage::Id run_id, EstMethod method) {
  const auto readings = storedReadings(session.store(), run_id, method);
  auto a = separate(readings, method);
  a.run_id = run_id;
  a.result_id = session.store().addResult(run_id, "est", kVersion,
                                          nlohmann::json{{"method", method.method}, {"start", method.start}}.dump(),
                                          a.document().dump());
  return a;
}

}  // namespace

ProbeReadings readProbeCsv(const std::string& path, bool three_probes) {
  std::ifstream in(path);
  if (!in) throw InputError(path + ": cannot open file");
  std::vector<std::string> required{"x_mm", "v1_um", "v2_um"};
  if (three_probes) required.push_back("v3_um");
  const auto columns = acquisition::readColumnsCsv(in, path, required, {"v3_um"});
  ProbeReadings c;
  c.x_mm = columns.at("x_mm");
  c.v1_um = columns.at("v1_um");
  c.v2_um = columns.at("v2_um");
  if (columns.count("v3_um")) c.v3_um = columns.at("v3_um");
  return c;
}

EstAnalysis separate(const ProbeReadings& c, const EstMethod& method) {
  EstAnalysis a;
  a.method = method;
  if (method.method == "two-probe") {
    a.result = processing::separateTwoProbe(c.x_mm, c.v1_um, c.v2_um, method.spacing_mm,
                                            method.start == "second-point" ? processing::EstStart::kSecondPointOnly
                                                                           : processing::EstStart::kCarriageAtRest);
  } else if (method.method == "three-probe") {
    if (c.v3_um.empty()) throw InputError("the three-probe method needs a third probe's readings");
    a.result = processing::separateThreeProbe(c.x_mm, c.v1_um, c.v2_um, c.v3_um, method.spacing_mm);
  } else if (method.method == "frequency") {
    a.result = processing::separateFrequency(c.x_mm, c.v1_um, c.v2_um, method.spacing_mm);
  } else {
    throw InputError("method must be two-probe, three-probe or frequency");
  }
  a.straightness = processing::evaluateStraightness(a.result.x_mm, a.result.profile_um);
  if (c.sigma_mean_um) {
    // What the readings' scatter alone makes of the profile (docs/est.md, noise propagation).
    for (std::size_t k = 0; k < c.x_mm.size(); ++k) {
      const int kk = static_cast<int>(k);
      a.noise_um.push_back(method.method == "three-probe" ? processing::threeProbeNoiseUm(kk, *c.sigma_mean_um)
                                                          : processing::twoProbeNoiseUm(kk, *c.sigma_mean_um));
    }
  }
  return a;
}

nlohmann::json EstAnalysis::document() const {
  nlohmann::json j{{"schema_version", 1},
                   {"method", method.method},
                   {"spacing_mm", method.spacing_mm},
                   {"x_mm", result.x_mm},
                   {"straightness_um", result.profile_um},
                   {"carriage_um", result.carriage_um},
                   {"straightness_lsq_um", straightness.least_squares_um},
                   {"straightness_minzone_um", straightness.min_zone_um},
                   {"straightness_endpoint_um", straightness.end_point_um},
                   {"lost_wavelengths_mm", result.lost_wavelengths_mm}};
  if (!noise_um.empty()) j["noise_um"] = noise_um;
  if (run_id != 0) j["run_id"] = run_id;
  return j;
}

EstAnalysis analyzeEst(Session& session, storage::Id run_id, EstMethod method) {
  return separateAndStore(session, run_id, method);
}

nlohmann::json EstRunResult::document() const {
  nlohmann::json j = analysis ? analysis->document() : nlohmann::json{{"schema_version", 1}, {"run_id", run_id}};
  j["status"] = status;
  j["steps"] = steps;
  return j;
}

EstRunResult runEst(Session& session, const EstRunRequest& request) {
  const auto& plan = request.plan;
  if (drivers::DeviceUri::parse(request.device_uri).scheme != "mock") {
    throw InputError(
        "probe stepping runs step the simulated machine (mock://probes); stepping a real machine by a part "
        "program is not built yet: import its readings with `mtcal est FILE.csv`");
  }
  const auto machine = simulatedMachine(request.simulation);
  Simulation sim(machine.config, demoInterferometer(), request.simulation.time_scale);
  auto box = sim.registry.openAs<drivers::probes::ProbeBoxDevice>(request.device_uri);
  auto& store = session.store();
  const storage::Id instrument_id = session.instrument(box->info());
  const storage::Id campaign_id = simulatedCampaign(store, machine, plan.name);
  const ProgressClock clock(static_cast<std::size_t>(plan.points));
  acquisition::EstRunOptions options;
  options.stop_requested = session.stopRequested();
  options.run_clock = &sim.run_clock;
  options.software_version = kVersion;
  options.on_progress = [&](const acquisition::EstProgress& p) {
    session.observer().onProgress(
        clock.at(static_cast<std::size_t>(p.done), fmt::format("{:>8.3f} mm", p.position_mm)));
  };
  acquisition::EstRun run(store, *box, sim.controller, options);
  EstRunResult r;
  r.run_id = run.start(plan, campaign_id, instrument_id);
  session.recordRun(r.run_id, {});
  r.steps = store.probeSteps(r.run_id).size();
  if (run.outcome() == acquisition::RunOutcome::kInterrupted) {
    r.status = storage::run_status::kInterrupted;
    return r;
  }
  r.status = storage::run_status::kCompleted;
  r.analysis = separateAndStore(session, r.run_id,
                                {plan.probes == 3 ? "three-probe" : "two-probe", "carriage-at-rest", plan.spacing_mm});
  return r;
}

}  // namespace mtcal::services
