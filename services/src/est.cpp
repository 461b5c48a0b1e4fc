#include "mtcal/services/est.h"

#include <fmt/format.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>

#include "mtcal/acquisition/csv.h"
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
  a.result_id =
      session
          .storeResult(run_id, "est", kVersion,
                       nlohmann::json{{"method", method.method}, {"start", method.start}}.dump(), a.document().dump())
          .value_or(0);
  return a;
}

}  // namespace

ProbeReadings readProbeCsv(const std::string& path, bool three_probes, const acquisition::CsvDialect& csv) {
  std::ifstream in(path);
  if (!in) throw InputError(path + ": cannot open file");
  std::vector<std::string> required{"x_mm", "v1_um", "v2_um"};
  if (three_probes) required.push_back("v3_um");
  const auto columns = acquisition::readColumnsCsv(in, path, required, {"v3_um"}, csv);
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

EstImport importEst(Session& session, const std::string& path, double spacing_mm, const std::string& name,
                    const std::string& machine, const acquisition::CsvDialect& csv) {
  const auto readings = readProbeCsv(path, false, csv);
  const auto n = readings.x_mm.size();
  if (n < 3) throw InputError(fmt::format("{}: {} rows: at least 3 positions are needed", path, n));
  acquisition::EstPlan plan;
  plan.name = name.empty() ? std::filesystem::path(path).filename().string() : name;
  plan.start_mm = readings.x_mm.front();
  plan.step_mm = readings.x_mm[1] - readings.x_mm[0];
  plan.points = static_cast<int>(n);
  plan.spacing_mm = spacing_mm;
  plan.probes = readings.v3_um.empty() ? 2 : 3;
  for (std::size_t k = 1; k < n; ++k) {
    if (std::abs(readings.x_mm[k] - readings.x_mm[k - 1] - plan.step_mm) >
        1e-6 * std::max(1.0, std::abs(plan.step_mm))) {
      throw InputError(fmt::format(
          "{}: column 'x_mm': row {} steps {} mm where the first row steps {} mm: the carriage must step evenly", path,
          k + 1, readings.x_mm[k] - readings.x_mm[k - 1], plan.step_mm));
    }
  }
  plan = acquisition::EstPlan::fromJson(plan.toJson(),
                                        path);  // the plan's own checks (spacing a whole number of steps ...)
  auto& store = session.store(Access::kCreate);
  storage::Transaction tx(store.database());
  storage::NewRun run;
  run.campaign_id = store.addCampaign(store.ensureMachine(machine, "", "{}"), "import " + path);
  run.kind = storage::run_kind::kEst;
  run.axis = plan.axis;
  run.name = plan.name;
  run.plan_json = plan.toJson().dump();
  run.status = storage::run_status::kImported;
  run.source = "imported";
  run.software_version = kVersion;
  EstImport r;
  r.run_id = store.addRun(run);
  for (std::size_t k = 0; k < n; ++k) {
    storage::ProbeStep step{static_cast<std::int64_t>(k), readings.x_mm[k], {}};
    step.channels.push_back({1, readings.v1_um[k], std::nullopt, 1});
    step.channels.push_back({2, readings.v2_um[k], std::nullopt, 1});
    if (plan.probes == 3) step.channels.push_back({3, readings.v3_um[k], std::nullopt, 1});
    store.addProbeStep(r.run_id, step);
  }
  tx.commit();
  session.recordRun(r.run_id, {});
  r.steps = n;
  r.probes = plan.probes;
  return r;
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

namespace {

/// Runs a plan on the simulated machine `machine` into the campaign `campaign` gives, or resumes
/// `resume_run` (whose plan `plan` is); separates the straightness when it completes.
EstRunResult acquireEst(Session& session, const acquisition::EstPlan& plan, const std::string& device_uri,
                        const mocks::VirtualMachineConfig& machine, double time_scale,
                        const std::function<storage::Id()>& campaign, std::optional<storage::Id> resume_run) {
  Simulation sim(machine, demoInterferometer(), time_scale);
  auto box = sim.registry.openAs<drivers::probes::ProbeBoxDevice>(device_uri);
  auto& store = session.store(Access::kRecord);
  const storage::Id instrument_id = session.instrument(box->info());
  const std::size_t done_before = resume_run ? store.probeSteps(*resume_run).size() : 0;
  const ProgressClock clock(static_cast<std::size_t>(plan.points), done_before);
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
  if (resume_run) {
    run.resume(*resume_run);
    r.run_id = *resume_run;
  } else {
    r.run_id = run.start(plan, campaign(), instrument_id);
    session.recordRun(r.run_id, {});
  }
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

}  // namespace

EstRunResult runEst(Session& session, const EstRunRequest& request) {
  const auto& plan = request.plan;
  if (drivers::DeviceUri::parse(request.device_uri).scheme != "mock") {
    throw InputError(
        "probe stepping runs step the simulated machine (mock://probes); stepping a real machine by a part "
        "program is not built yet: import its readings with `mtcal est FILE.csv`");
  }
  const auto machine = simulatedMachine(request.simulation);
  return acquireEst(
      session, plan, request.device_uri, machine.config, request.simulation.time_scale,
      [&] { return simulatedCampaign(session.store(Access::kRecord), machine, plan.name); }, std::nullopt);
}

EstRunResult resumeEst(Session& session, storage::Id run_id, double time_scale) {
  const auto rig = storedRig(session.store(), run_id);
  if (!rig.simulation) {
    throw InputError(fmt::format("run {} was not measured on the simulated machine: it cannot be resumed", run_id));
  }
  const auto plan =
      acquisition::EstPlan::fromJson(nlohmann::json::parse(rig.run.plan_json), fmt::format("run {} plan", run_id));
  return acquireEst(session, plan, rig.uriOf("measuring"), *rig.simulation, time_scale, {}, run_id);
}

}  // namespace mtcal::services
