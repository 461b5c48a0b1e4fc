#include "mtcal/services/est.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>

#include "imported_file.h"
#include "mtcal/acquisition/csv.h"
#include "mtcal/drivers/uri.h"
#include "mtcal/error.h"
#include "mtcal/services/version.h"

namespace mtcal::services {

namespace {

ProbeReadings storedReadings(storage::Store& store, storage::Id run_id, EstMethod& method) {
  const auto info = store.run(run_id);
  if (info.kind != storage::run_kind::kEst) {
    throw InputError(
        fmt::format("run {} is {}, not a probe stepping (est) run", run_id, storage::run_kind::aRunOf(info.kind)));
  }
  const auto stored = acquisition::storedEstRun(store, info);
  if (!(method.spacing_mm > 0.0)) method.spacing_mm = stored.spacing_mm;
  if (method.method.empty()) method.method = stored.v3_um.empty() ? "two-probe" : "three-probe";  // the run's own
  ProbeReadings c;
  static_cast<processing::EstRunInput&>(c) = stored;
  c.zeroing = acquisition::storedZeroing(store, run_id);
  if (c.position_mm.size() < 3)
    throw InputError(fmt::format("run {} has {} steps stored: too few to separate", run_id, c.position_mm.size()));
  return c;
}

/// The standard deviation of one step's mean reading: the variance of one reading pooled over
/// the probes the method reads and every step, times the mean over the steps of 1 / the count
/// averaged there; nothing where no scatter is known.
std::optional<double> stepMeanSigmaUm(const ProbeReadings& c, const std::string& method) {
  const auto pooled = processing::pooledProbeScatter(c);
  const std::size_t probes = method == "three-probe" ? 3 : 2;
  double sum_of_squares = 0.0, dof = 0.0;
  for (std::size_t p = 0; p < probes; ++p) {
    sum_of_squares += pooled.dof[p] * pooled.variance_um2[p];
    dof += pooled.dof[p];
  }
  if (!(dof > 0.0)) return std::nullopt;
  double inverse_count = 0.0;
  for (const int n : c.readings) inverse_count += 1.0 / n / static_cast<double>(c.readings.size());
  return std::sqrt(sum_of_squares / dof * inverse_count);
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

/// More readings than this averaged at one step is no count (a million a second for 20 minutes);
/// the message says it as 1e9.
constexpr double kMostReadingsPerStep = 1e9;

ProbeReadings readProbeCsv(std::istream& in, const std::string& path, bool three_probes,
                           const acquisition::CsvDialect& csv) {
  acquisition::CsvReader reader(in, path, csv);
  std::string need = "x_mm, v1_um, v2_um";
  if (three_probes) need += ", v3_um";
  const auto x = reader.require("x_mm", need);
  std::array<std::optional<acquisition::CsvColumn>, 3> value{reader.require("v1_um", need),
                                                             reader.require("v2_um", need), std::nullopt};
  value[2] = three_probes ? reader.require("v3_um", need) : reader.find("v3_um");
  const std::size_t probes = value[2] ? 3 : 2;
  // The probes' scatter: all of them or none, with the counts it is over.
  std::array<std::optional<acquisition::CsvColumn>, 3> scatter;
  for (std::size_t p = 0; p < 3; ++p) scatter[p] = reader.find(fmt::format("s{}_um", p + 1));
  const auto count = reader.find("readings");
  reader.refuseUnusedMappings();
  if (scatter[2] && probes == 2)
    throw InputError(fmt::format("{}:{}: column '{}' is a third probe's scatter, but the file has no v3_um", path,
                                 reader.headerLine(), scatter[2]->header));
  const bool stated = count || std::any_of(scatter.begin(), scatter.end(), [](const auto& c) { return c.has_value(); });
  if (stated) {
    const std::string scatter_need = fmt::format(
        "s1_um, s2_um{} and readings (each probe's standard deviation of one reading and how many "
        "were averaged at each step)",
        probes == 3 ? ", s3_um" : "");
    for (std::size_t p = 0; p < probes; ++p)
      if (!scatter[p]) reader.require(fmt::format("s{}_um", p + 1), scatter_need);
    if (!count) reader.require("readings", scatter_need);
  }
  ProbeReadings c;
  c.source = path;
  while (const auto row = reader.row()) {
    c.position_mm.push_back(reader.required(*row, x));
    // Even steps, said where one is not (the separation needs them).
    if (const auto& at = c.position_mm; at.size() >= 2) {
      const double first = at[1] - at[0], last = at.back() - at[at.size() - 2];
      if (!(last > 0.0))
        throw reader.error(
            x.header, fmt::format("{:g} mm after {:g} mm: the positions must increase", at.back(), at[at.size() - 2]));
      if (!processing::sameStep(last, first))
        throw reader.error(x.header, fmt::format("{:g} mm after {:g} mm: a step of {:g} mm where the file steps by "
                                                 "{:g} mm (the steps must be even)",
                                                 at.back(), at[at.size() - 2], last, first));
    }
    for (std::size_t p = 0; p < probes; ++p) c.probeUm(p).push_back(reader.required(*row, *value[p]));
    if (!stated) continue;
    const double n = reader.required(*row, *count);
    if (!(n >= 1.0) || n != std::floor(n))
      throw reader.error(count->header, fmt::format("{:g} readings: a step averages a whole number, at least 1", n));
    if (n > kMostReadingsPerStep)
      throw reader.error(count->header, fmt::format("{:.0f} readings: more than 1e9 at one step is not a count", n));
    c.readings.push_back(static_cast<int>(n));
    for (std::size_t p = 0; p < probes; ++p) {
      const auto s = reader.number(*row, *scatter[p]);
      if (s && *s < 0.0) throw reader.error(scatter[p]->header, fmt::format("{:g} um: a scatter is not negative", *s));
      if (!s && n > 1.0)
        throw reader.error(
            scatter[p]->header,
            fmt::format("empty where {:g} readings were averaged (empty only where a step read once)", n));
      c.scatter_um[p].push_back(n > 1.0 ? *s : NAN);  // one reading has no scatter, whatever the cell says
    }
  }
  if (c.position_mm.empty()) throw InputError(path + ": no data rows");
  return c;
}

}  // namespace

ProbeReadings readProbeCsv(const std::string& path, bool three_probes, const acquisition::CsvDialect& csv) {
  std::ifstream in = acquisition::openInputFile(path);
  return readProbeCsv(in, path, three_probes, csv);
}

EstAnalysis separate(const ProbeReadings& c, const EstMethod& method) {
  EstAnalysis a;
  a.method = method;
  if (method.start != "carriage-at-rest" && method.method != "two-probe") {
    throw InputError(fmt::format("--start {}: an initial condition of the two-probe method, not of the {} method",
                                 method.start, method.method));
  }
  if (method.method == "two-probe") {
    a.result = processing::separateTwoProbe(c.position_mm, c.v1_um, c.v2_um, method.spacing_mm,
                                            method.start == "second-point" ? processing::EstStart::kSecondPointOnly
                                                                           : processing::EstStart::kCarriageAtRest);
  } else if (method.method == "three-probe") {
    if (c.v3_um.empty())
      throw InputError(fmt::format("{}: the three-probe method needs a third probe's readings (v3_um)", c.source));
    // The zeros' combination c = z3 - 2 z2 + z1 adds c k(k-1)/2 to the profile: taken off the
    // third probe, it leaves V3 - 2 V2 + V1 - c (docs/est.md).
    std::vector<double> v3 = c.v3_um;
    if (c.zeroing && c.zeroing->zero_um.size() != 3)
      throw InputError(fmt::format("{}: 3 probes, but {} zero readings given", c.source, c.zeroing->zero_um.size()));
    if (c.zeroing) {
      for (auto& v : v3) v -= c.zeroing->combinationUm();
      a.zeroing = c.zeroing;
    } else {
      const auto k = static_cast<double>(c.position_mm.size() - 1);
      a.warnings.push_back(fmt::format(
          "three-probe separation without a zeroing: the probes' zero combination c = z3 - 2 z2 + z1 adds "
          "c k(k-1)/2 to the profile, {:.0f} um per um of c at the last of these {} steps; zero the probes on a "
          "reference flat (a plan's \"zeroing\") or give their readings there (--zero-readings-um)",
          k * (k - 1) / 2, c.position_mm.size()));
    }
    a.result = processing::separateThreeProbe(c.position_mm, c.v1_um, c.v2_um, v3, method.spacing_mm);
  } else if (method.method == "frequency") {
    a.result = processing::separateFrequency(c.position_mm, c.v1_um, c.v2_um, method.spacing_mm);
  } else {
    throw InputError("method must be two-probe, three-probe or frequency");
  }
  a.straightness = processing::evaluateStraightness(a.result.x_mm, a.result.profile_um);
  if (const auto sigma_um = stepMeanSigmaUm(c, method.method)) {
    // What the readings' scatter alone makes of the profile (docs/est.md, noise propagation).
    for (std::size_t k = 0; k < c.position_mm.size(); ++k) {
      const int kk = static_cast<int>(k);
      a.noise_um.push_back(method.method == "three-probe" ? processing::threeProbeNoiseUm(kk, *sigma_um)
                                                          : processing::twoProbeNoiseUm(kk, *sigma_um));
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
  if (zeroing) j["zeroing"] = zeroing->toJson();
  j["warnings"] = warnings;
  return j;
}

acquisition::EstZeroing givenZeroing(const std::string& readings_um) {
  acquisition::EstZeroing z;
  z.method = "given";
  std::stringstream items(readings_um + ",");  // a last comma: an empty last reading, refused
  std::string item;
  while (std::getline(items, item, ',')) {
    std::size_t used = 0;
    double v = 0.0;
    try {
      v = std::stod(item, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used == 0 || used != item.size() || !std::isfinite(v))
      throw InputError("--zero-readings-um takes the probes' readings on a reference flat, z1,z2,z3 in um; got '" +
                       readings_um + "'");
    if (!(std::abs(v) <= acquisition::kLargestDeviationUm)) {
      throw InputError(fmt::format("--zero-readings-um: '{}' is beyond +-{:g} um: not a probe's reading on a flat",
                                   item, acquisition::kLargestDeviationUm));
    }
    z.zero_um.push_back(v);
  }
  if (z.zero_um.size() < 2 || z.zero_um.size() > 3)
    throw InputError("--zero-readings-um takes 2 or 3 readings (one per probe), got '" + readings_um + "'");
  return z;
}

EstImport importEst(Session& session, const std::string& path, double spacing_mm, const std::string& name,
                    const std::string& machine, const acquisition::CsvDialect& csv,
                    const std::optional<acquisition::EstZeroing>& zeroing) {
  auto file = detail::readImportedFile(path);
  const auto readings = readProbeCsv(file.bytes, path, false, csv);
  const auto n = readings.position_mm.size();
  if (n < 3) throw InputError(fmt::format("{}: {} rows: at least 3 positions are needed", path, n));
  acquisition::EstPlan plan;
  plan.name = name.empty() ? std::filesystem::path(path).filename().string() : name;
  plan.start_mm = readings.position_mm.front();
  plan.step_mm = readings.position_mm[1] - readings.position_mm[0];
  plan.points = static_cast<int>(n);
  plan.spacing_mm = spacing_mm;
  plan.probes = readings.v3_um.empty() ? 2 : 3;
  // What the file's steps averaged (the most of them), or one reading each.
  plan.readings_per_step =
      readings.readings.empty() ? 1 : *std::max_element(readings.readings.begin(), readings.readings.end());
  plan.zeroing = "none";  // not zeroed by mtcal: given with the file, or not at all
  plan.imported_from = std::filesystem::path(path).filename().string();
  plan.imported_sha256 = file.sha256;
  if (zeroing && static_cast<int>(zeroing->zero_um.size()) != plan.probes) {
    throw InputError(
        fmt::format("{}: {} probes, but {} zero readings given", path, plan.probes, zeroing->zero_um.size()));
  }
  for (std::size_t k = 1; k < n; ++k) {
    if (std::abs(readings.position_mm[k] - readings.position_mm[k - 1] - plan.step_mm) >
        1e-6 * std::max(1.0, std::abs(plan.step_mm))) {
      throw InputError(fmt::format(
          "{}: column 'x_mm': row {} steps {} mm where the first row steps {} mm: the carriage must step evenly", path,
          k + 1, readings.position_mm[k] - readings.position_mm[k - 1], plan.step_mm));
    }
  }
  try {
    plan = acquisition::EstPlan::fromJson(plan.toJson(), path);  // the plan's own checks (spacing, steps ...)
  } catch (const InputError& e) {
    // The spacing and the step were given as the option and the file's rows, not as a plan's keys.
    std::string message = e.what();
    const std::string key = path + ": key 'spacing_mm': ";
    if (message.rfind(key, 0) != 0) throw;
    const std::string reason = message.substr(key.size());
    throw InputError(fmt::format("{}: --spacing-mm {:g} (the file steps by {:g} mm): {}", path, spacing_mm,
                                 plan.step_mm,
                                 reason.find("whole number of steps") == std::string::npos ? reason
                                 : plan.probes == 3 ? std::string("three probes need a spacing of one step")
                                                    : std::string("must be a whole multiple of the file's step")));
  }
  auto& store = session.store(Access::kCreate);
  storage::Transaction tx(store.database());
  storage::NewRun run;
  run.campaign_id = store.addCampaign(store.ensureMachine(machine, "", "{}"), "import " + plan.imported_from);
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
    storage::ProbeStep step{static_cast<std::int64_t>(k), readings.position_mm[k], {}};
    for (int p = 0; p < plan.probes; ++p) {
      const auto& scatter = readings.scatter_um[static_cast<std::size_t>(p)];
      const auto s = scatter.empty() || std::isnan(scatter[k]) ? std::nullopt : std::optional<double>(scatter[k]);
      step.channels.push_back({p + 1, readings.probeUm(static_cast<std::size_t>(p))[k], s,
                               readings.readings.empty() ? 1 : readings.readings[k]});
    }
    store.addProbeStep(r.run_id, step);
  }
  if (zeroing) acquisition::storeZeroing(store, r.run_id, *zeroing, kVersion);
  tx.commit();
  session.recordRun(r.run_id, {});
  r.steps = n;
  r.probes = plan.probes;
  r.scatter = processing::pooledProbeScatter(readings).known();
  r.warnings = detail::importedBefore(store, plan.imported_sha256, path, {r.run_id});
  for (const auto& warning : r.warnings) session.observer().onMessage("warning", warning);
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

/// Runs (or resumes) a plan with `box` and `controller` into the campaign `campaign` gives;
/// separates the straightness when it completes.
EstRunResult acquireEst(Session& session, const acquisition::EstPlan& plan, drivers::probes::ProbeBoxDevice& box,
                        acquisition::MachineController& controller, acquisition::EstRunOptions options,
                        const std::function<storage::Id()>& campaign, std::optional<storage::Id> resume_run) {
  auto& store = session.store(Access::kRecord);
  const storage::Id instrument_id = session.instrument(box.info());
  const std::size_t done_before = resume_run ? store.probeSteps(*resume_run).size() : 0;
  const ProgressClock clock(static_cast<std::size_t>(plan.points), done_before);
  options.stop_requested = session.stopRequested();
  options.software_version = kVersion;
  options.on_progress = [&](const acquisition::EstProgress& p) {
    session.observer().onProgress(
        clock.at(static_cast<std::size_t>(p.done), fmt::format("{:>8.3f} mm", p.position_mm)));
  };
  acquisition::EstRun run(store, box, controller, options);
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

/// On the simulated machine `machine`: mtcal steps it, or the simulated operator does
/// (stepping "hand"), and sets the probes on the reference flat.
EstRunResult simulatedEst(Session& session, const acquisition::EstPlan& plan, const std::string& device_uri,
                          const mocks::VirtualMachineConfig& machine, double time_scale,
                          const std::function<storage::Id()>& campaign, std::optional<storage::Id> resume_run) {
  Simulation sim(machine, demoInterferometer(), time_scale);
  auto box = sim.registry.openAs<drivers::probes::ProbeBoxDevice>(device_uri);
  acquisition::EstRunOptions options;
  options.run_clock = &sim.run_clock;
  options.reference_flat = [&sim](bool on_flat) { sim.world.probes.setOnReferenceFlat(on_flat); };
  acquisition::HandStepping hand([&](const std::string& axis, double position_mm) {
    // The simulated operator moves the carriage there and lets it settle before answering.
    if (const auto at = sim.controller.moveTo(axis, position_mm)) sim.run_clock.advanceTo(*at + plan.settle_s);
  });
  acquisition::MachineController& controller =
      plan.stepping == "hand" ? static_cast<acquisition::MachineController&>(hand) : sim.controller;
  return acquireEst(session, plan, *box, controller, options, campaign, resume_run);
}

}  // namespace

namespace {

/// Every step of the carriage and the other axes' positions inside the machine's travel, before
/// anything moves (a run stopped half-way by a move it could never make cannot be resumed).
void checkEstInTravel(const acquisition::EstPlan& plan, const mocks::VirtualMachineConfig& machine) {
  const auto what = fmt::format("plan '{}' (start_mm, step_mm, points, line_position_mm)", plan.name);
  for (const auto& [other, position_mm] : plan.line_position_mm)
    requireInTravel(machine, mocks::parseAxis(other), position_mm, what);
  const auto axis = mocks::parseAxis(plan.axis);
  for (int k = 0; k < plan.points; ++k) requireInTravel(machine, axis, plan.start_mm + k * plan.step_mm, what);
}

}  // namespace

EstRunResult runEst(Session& session, const EstRunRequest& request) {
  const auto& plan = request.plan;
  if (drivers::DeviceUri::parse(request.device_uri).scheme != "mock") {
    if (plan.stepping != "hand") {
      throw InputError(
          "a real machine's carriage is stepped by hand (\"stepping\": \"hand\" in the plan: the operator moves it "
          "to each step and confirms); stepping by the CNC's part program is not built yet");
    }
    Operator& person = session.person("a probe stepping run by hand: the operator moves the carriage to each step");
    drivers::Registry registry;
    drivers::registerBuiltInDrivers(registry);
    auto box = registry.openAs<drivers::probes::ProbeBoxDevice>(request.device_uri);
    acquisition::EstRunOptions options;
    options.reference_flat = [&](bool on_flat) {
      person.confirm(on_flat ? "Set the probes on the reference flat (a flat or straightedge, straighter than the "
                               "guideway), hold the carriage still and press Enter"
                             : "Set the probes back on the guideway and press Enter");
    };
    acquisition::HandStepping hand([&](const std::string& axis, double position_mm) {
      person.confirm(fmt::format("Move {} to {:.3f} mm, hold it there and press Enter", axis, position_mm));
    });
    return acquireEst(
        session, plan, *box, hand, options,
        [&] { return realCampaign(session.store(Access::kRecord), request.machine, plan.name); }, std::nullopt);
  }
  const auto machine = simulatedMachine(request.simulation);
  checkEstInTravel(plan, machine.config);
  return simulatedEst(
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
  return simulatedEst(session, plan, rig.uriOf("measuring"), *rig.simulation, time_scale, {}, run_id);
}

}  // namespace mtcal::services
