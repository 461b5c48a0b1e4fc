#include "mtcal/services/thermal.h"

#include <fmt/format.h>

#include <cmath>
#include <sstream>

#include "imported_file.h"
#include "mtcal/acquisition/diagnosis_data.h"
#include "mtcal/drivers/registry.h"
#include "mtcal/drivers/uri.h"
#include "mtcal/error.h"
#include "mtcal/services/version.h"

namespace mtcal::services {

namespace {

/// NaN (undefined) as JSON null.
nlohmann::json number(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(); }

nlohmann::json candidateJson(const processing::ThermalCandidate& c) {
  nlohmann::json coefficients = {{"intercept_um", c.coefficients(0)}}, inputs = nlohmann::json::array();
  for (std::size_t i = 0; i < c.sensors.size(); ++i) {
    const std::string name = processing::thermalInputName(c, i);
    coefficients[name] = c.coefficients(static_cast<Eigen::Index>(i) + 1);
    inputs.push_back({{"name", name}, {"sensor", c.sensors[i]}, {"lag_s", c.lag_s[i]}});
  }
  nlohmann::json levels = nlohmann::json::object();
  for (const auto& [segment, level] : c.segment_level_um) levels[std::to_string(segment)] = level;
  return {{"method", c.method},
          {"family", processing::thermalFamilyName(c.family)},
          {"sensors", c.sensors},
          {"inputs", inputs},
          {"coefficients", coefficients},
          {"segment_levels_um", levels},
          {"phi", c.phi},
          {"n_train", c.n_train},
          {"n_test", c.n_test},
          {"cv_rms_um", number(c.cv_rms_um)},
          {"cv_rms_one_step_um", number(c.cv_rms_one_step_um)},
          {"validation_rms_um", number(c.validation_rms_um)},
          {"validation_rms_one_step_um", number(c.validation_rms_one_step_um)},
          {"rms_train_um", c.rms_train_um},
          {"peak_train_um", c.peak_train_um},
          {"rms_test_um", c.rms_test_um},
          {"peak_test_um", c.peak_test_um},
          {"rms_test_one_step_um", c.rms_test_one_step_um},
          {"peak_test_one_step_um", c.peak_test_one_step_um},
          {"durbin_watson", c.durbin_watson},
          {"durbin_watson_innovations", c.durbin_watson_innovations},
          {"ljung_box_q", c.ljung_box_q},
          {"ljung_box_p", c.ljung_box_p},
          {"ljung_box_q_static", c.ljung_box_q_static},
          {"ljung_box_p_static", c.ljung_box_p_static},
          {"aic", c.aic},
          {"bic", c.bic},
          {"aic_static", c.aic_static},
          {"bic_static", c.bic_static}};
}

void writePredictions(const std::string& path, const processing::ThermalData& data,
                      const processing::ThermalFitResult& r) {
  std::ostringstream csv;
  csv << "time_s,measured_um,open_loop_um,one_step_um,part\n";
  for (Eigen::Index i = 0; i < data.time_s.size(); ++i) {
    auto cell = [](double v) { return std::isfinite(v) ? fmt::format("{:.4f}", v) : std::string(); };
    csv << fmt::format("{:.3f},{},{},{},{}\n", data.time_s(i), cell(data.target_um(i)),
                       cell(r.predicted_open_loop_um(i)), cell(r.predicted_one_step_um(i)),
                       i < r.n_train_rows ? "train" : "test");
  }
  writeTextFile(path, csv.str());
}

/// The virtual machine's CNC runs the spindle program.
class VirtualSpindle final : public acquisition::SpindleController {
 public:
  explicit VirtualSpindle(mocks::MachineThermal& thermal) : thermal_(thermal) {}
  void startProgram(const std::vector<acquisition::ThermalPhase>& phases, double start_s) override {
    std::vector<mocks::SpindlePhase> program;
    for (const auto& p : phases) program.push_back({p.duration_s, p.speed_rpm});
    thermal_.startProgram(program, start_s);
  }

 private:
  mocks::MachineThermal& thermal_;
};

/// A real machine: the operator starts the plan's spindle program (`mtcal plan gcode PLAN`).
class OperatorSpindle final : public acquisition::SpindleController {
 public:
  explicit OperatorSpindle(Operator& person) : person_(person) {}
  void startProgram(const std::vector<acquisition::ThermalPhase>& phases, double) override {
    std::string program;
    for (const auto& p : phases)
      program += fmt::format("\n  {}: {:.1f} min at {:.0f} rpm", p.name, p.duration_s / 60.0, p.speed_rpm);
    person_.tell("The logger is recording. The spindle program (mtcal plan gcode PLAN):" + program);
    person_.confirm("Start the spindle program on the CNC now; confirm when it runs");
  }

 private:
  Operator& person_;
};

bool isMock(const std::string& uri) { return drivers::DeviceUri::parse(uri).scheme == "mock"; }

}  // namespace

nlohmann::json ThermalImport::document() const {
  nlohmann::json names = nlohmann::json::array();
  for (const auto& c : channels) names.push_back({{"name", c.name}, {"kind", c.kind}, {"unit", c.unit}});
  return {{"schema_version", 1},
          {"run_id", run_id},
          {"samples", samples},
          {"channels", names},
          {"missing_values", missing_values},
          {"warnings", warnings}};
}

ThermalImport importThermal(Session& session, const std::string& path, acquisition::ThermalImportOptions options) {
  options.software_version = kVersion;
  acquisition::checkThermalImportOptions(options);  // before a file (or a pipe) is read whole
  auto file = detail::readImportedFile(path);
  options.source_sha256 = file.sha256;
  auto imported = acquisition::importThermalCsv(detail::storeWhenNeeded(session), file.bytes, path, options);
  auto& store = session.store(Access::kCreate);
  ThermalImport r;
  r.run_id = imported.run_id;
  session.recordRun(r.run_id, {});
  r.warnings = std::move(imported.warnings);
  for (auto& warning : detail::importedBefore(store, options.source_sha256, path, {r.run_id}))
    r.warnings.push_back(std::move(warning));
  for (const auto& warning : r.warnings) session.observer().onMessage("warning", warning);
  r.channels = store.thermalChannels(r.run_id);
  const auto samples = store.thermalSamples(r.run_id);
  r.samples = samples.size();
  for (const auto& s : samples) {
    for (const auto& v : s.values) r.missing_values += v ? 0 : 1;
  }
  return r;
}

void exportThermal(Session& session, storage::Id run_id, std::ostream& out) {
  acquisition::writeThermalCsv(session.store(), run_id, out);
}

nlohmann::json ThermalFitAnalysis::document() const {
  const auto& r = fit;
  const nlohmann::json model = candidateJson(r.chosen);
  nlohmann::json sensors = nlohmann::json::array();
  for (const auto& s : r.sensors) {
    sensors.push_back(
        {{"name", s.name},
         {"usable", s.usable},
         {"grey_grade", s.usable ? number(s.grade) : nlohmann::json()},
         {"grey_rank", s.usable ? nlohmann::json(s.rank) : nlohmann::json()},
         {"grey_grade_by_normalisation",
          {{"range", number(s.grade_range)}, {"initial", number(s.grade_initial)}, {"mean", number(s.grade_mean)}}},
         {"correlation", s.usable ? number(s.correlation) : nlohmann::json()},
         {"cluster", s.cluster >= 0 ? nlohmann::json(s.cluster) : nlohmann::json()},
         {"missing", s.missing},
         {"interpolated", s.interpolated},
         {"note", s.note}});
  }
  nlohmann::json paths = nlohmann::json::array(), families = nlohmann::json::array();
  for (const auto& path : r.paths) {
    nlohmann::json models = nlohmann::json::array();
    for (const auto& c : path.models) models.push_back(candidateJson(c));
    paths.push_back(
        {{"method", path.method}, {"family", processing::thermalFamilyName(path.family)}, {"models", models}});
  }
  for (const auto* c : processing::bestOfEachPath(r)) families.push_back(candidateJson(*c));
  nlohmann::json sensors_needed = nullptr;
  if (needed) {
    sensors_needed = {{"accuracy_um", needed->accuracy_um},
                      {"method", needed->method},
                      {"sensors", needed->sensors},
                      {"rms_test_um", needed->rms_test_um}};
  }
  return {{"schema_version", 1},
          {"run_id", run_id},
          {"target", request.target},
          {"rows", r.n_rows},
          {"train_rows", r.n_train_rows},
          {"split_time_s", r.split_time_s},
          {"normalisation", processing::greyNormalisationName(r.normalisation)},
          {"rho", r.rho},
          {"selected_sensors", r.chosen.sensors},
          {"selection", r.chosen.method},
          {"family", processing::thermalFamilyName(r.chosen.family)},
          {"compensation_uses", "open loop"},
          {"coefficients", model["coefficients"]},
          {"phi", r.chosen.phi},
          {"rms_train_um", r.chosen.rms_train_um},
          {"rms_test_um", r.chosen.rms_test_um},
          {"peak_test_um", r.chosen.peak_test_um},
          {"rms_test_one_step_um", r.chosen.rms_test_one_step_um},
          {"peak_test_one_step_um", r.chosen.peak_test_one_step_um},
          {"rms_test_baseline_um", r.baseline.rms_test_um},
          {"peak_test_baseline_um", r.baseline.peak_test_um},
          {"gain", r.gain},
          {"test_sd_um", number(r.test_sd_um)},
          {"model", model},
          {"baseline", candidateJson(r.baseline)},
          {"sensors", sensors},
          {"all_sensors", r.all_sensors ? candidateJson(*r.all_sensors) : nlohmann::json()},
          {"families", families},
          {"paths", paths},
          {"sensors_needed", sensors_needed},
          {"notes", r.notes}};
}

ThermalFitAnalysis fitThermal(Session& session, storage::Id run_id, const ThermalFitRequest& request) {
  auto& store = session.store();
  const processing::ThermalData data = acquisition::thermalDataOfRun(store, run_id, request.target, request.with_speed);
  // A run cut short tests the model on what it recorded, not on the later part of its plan.
  if (const auto warning = acquisition::unfinishedRunWarning(store.run(run_id)))
    session.observer().onMessage("warning", *warning);
  processing::ThermalFitOptions fit_options;
  fit_options.train_fraction = request.train_fraction;
  fit_options.validation_fraction = request.validation_fraction;
  fit_options.max_sensors = request.max_sensors;
  fit_options.normalisation = processing::greyNormalisationFromName(request.normalisation);
  fit_options.rho = request.rho;
  ThermalFitAnalysis a;
  a.run_id = run_id;
  a.request = request;
  a.fit = processing::fitThermalModel(data, fit_options);
  if (request.accuracy_um > 0.0) {
    for (const auto& path : a.fit.paths) {
      for (const auto& c : path.models) {
        const auto sensors = processing::thermalSensorsOf(c);  // to install: one per sensor
        if (c.rms_test_um <= request.accuracy_um && (!a.needed || sensors.size() < a.needed->sensors.size())) {
          a.needed = SensorsNeeded{request.accuracy_um,
                                   fmt::format("{} ({})", c.method, processing::thermalFamilyName(c.family)), sensors,
                                   c.rms_test_um};
        }
      }
    }
  }
  // The predictions file before the result: a file that cannot be written stores nothing.
  if (!request.predictions_path.empty()) writePredictions(request.predictions_path, data, a.fit);
  a.result_id = session
                    .storeResult(run_id, "thermal-fit", kVersion,
                                 nlohmann::json{{"target", request.target},
                                                {"train_fraction", request.train_fraction},
                                                {"validation_fraction", request.validation_fraction},
                                                {"max_sensors", request.max_sensors},
                                                {"normalisation", request.normalisation},
                                                {"rho", request.rho},
                                                {"with_speed", request.with_speed}}
                                     .dump(),
                                 a.document().dump())
                    .value_or(0);
  return a;
}

nlohmann::json ThermalRunResult::document() const {
  return {{"schema_version", 1},
          {"run_id", run_id},
          {"samples", samples},
          {"planned", planned},
          {"missing_values", missing_values},
          {"complete", complete},
          {"stopped_because", stopped_because}};
}

ThermalRunResult runThermal(Session& session, const ThermalRunRequest& given) {
  ThermalRunRequest request = given;
  storage::Id run_id = request.resume_run;
  acquisition::ThermalPlan plan = request.plan;
  std::optional<mocks::VirtualMachineConfig> stored_machine;
  if (run_id != 0) {
    // Continued with the run's own plan, instruments and machine.
    const auto rig = storedRig(session.store(), run_id);
    if (rig.run.kind != storage::run_kind::kThermal)
      throw InputError(fmt::format("run {} is {}, not a thermal run", run_id, storage::run_kind::aRunOf(rig.run.kind)));
    plan = acquisition::ThermalPlan::fromJson(nlohmann::json::parse(rig.run.plan_json), fmt::format("run {}", run_id));
    request.logger_uri = rig.uriOf("measuring");
    const bool by_probe = plan.displacement_device == "probes";
    if (by_probe) request.probes_uri = rig.uriOf("displacement");
    if (!by_probe) request.interferometer_uri = rig.uriOf("displacement");
    if (plan.environment && by_probe) request.interferometer_uri = rig.uriOf("environment");
    stored_machine = rig.simulation;
  }
  const bool simulated = isMock(request.logger_uri);
  const bool needs_interferometer = plan.displacement_device == "interferometer" || plan.environment;
  if (isMock(request.probes_uri) != simulated ||
      (needs_interferometer && isMock(request.interferometer_uri) != simulated)) {
    throw InputError("run thermal: the instruments are either all simulated (mock://) or all real");
  }
  // The simulated machine and its instruments, or the real instruments with the operator
  // starting the spindle program on the CNC.
  std::unique_ptr<Simulation> sim;
  drivers::Registry real_registry;
  drivers::Registry* registry = &real_registry;
  std::unique_ptr<acquisition::SpindleController> spindle;
  std::optional<SimulatedMachine> machine;
  std::chrono::milliseconds record_timeout{(plan.interval_s + 60) * 1000LL};
  if (simulated) {
    machine = simulatedMachine(request.simulation);
    if (stored_machine) machine->config = *stored_machine;
    if (!machine->config.thermal) {
      if (!machine->file_json.empty()) {
        throw InputError(request.simulation.machine_file + ": the machine has no thermal object (docs/thermal.md)");
      }
      machine->config.thermal = mocks::MachineThermalConfig{};
      machine->config.thermal->ambient_swing_k = 0.8;  // the demo shop's daily swing
    }
    sim = std::make_unique<Simulation>(machine->config, demoInterferometer(), request.simulation.time_scale);
    const int along = plan.displacement_axis == "Z" ? 2 : 1;
    sim->world.probes.setMeasuring(along);
    sim->world.interferometer->mount(along == 2 ? mocks::Axis::kZ : mocks::Axis::kY, along, {0.0, 0.0, 0.0});
    registry = &sim->registry;
    spindle = std::make_unique<VirtualSpindle>(*sim->world.machine.thermal());
    record_timeout = std::chrono::milliseconds(
        static_cast<long long>(1000.0 * (plan.interval_s / request.simulation.time_scale)) + 5000);
  } else {
    drivers::registerBuiltInDrivers(real_registry);
    spindle = std::make_unique<OperatorSpindle>(
        session.person("a real machine's spindle program is started by the operator"));
  }
  auto logger = registry->openAs<drivers::logger::TemperatureLoggerDevice>(request.logger_uri);
  std::unique_ptr<drivers::probes::ProbeBoxDevice> probes;
  std::unique_ptr<drivers::interferometer::InterferometerDevice> interferometer;
  if (plan.displacement_device == "probes")
    probes = registry->openAs<drivers::probes::ProbeBoxDevice>(request.probes_uri);
  if (needs_interferometer) {
    interferometer = registry->openAs<drivers::interferometer::InterferometerDevice>(request.interferometer_uri);
  }
  auto& store = session.store(Access::kRecord);
  if (run_id != 0) store.claimRun(run_id);
  if (run_id == 0) {
    storage::NewRun run;
    run.campaign_id =
        machine ? simulatedCampaign(store, *machine, plan.name) : realCampaign(store, request.machine, plan.name);
    run.instrument_id = session.instrument(logger->info());
    run.kind = storage::run_kind::kThermal;
    run.name = plan.name;
    run.plan_json = plan.toJson().dump();
    run.software_version = kVersion;
    run_id = store.addRun(run);
    std::vector<std::pair<drivers::DeviceInfo, std::string>> others;
    if (probes) others.emplace_back(probes->info(), "displacement");
    if (interferometer)
      others.emplace_back(interferometer->info(),
                          plan.displacement_device == "interferometer" ? "displacement" : "environment");
    session.recordRun(run_id, others);
  }
  const ProgressClock clock(static_cast<std::size_t>(plan.sampleCount()),
                            static_cast<std::size_t>(store.thermalSampleCount(run_id)));
  acquisition::ThermalRunOptions run_options;
  run_options.stop_requested = session.stopRequested();
  run_options.record_timeout = record_timeout;
  if (sim) run_options.run_clock = &sim->run_clock;
  run_options.on_progress = [&](std::int64_t done, std::int64_t, double drift_um) {
    session.observer().onProgress(clock.at(static_cast<std::size_t>(done), fmt::format("{:>8.2f} um", drift_um)));
  };
  const auto summary = acquisition::runThermalMonitoring(plan, {*logger, probes.get(), interferometer.get()}, *spindle,
                                                         store, run_id, run_options);
  ThermalRunResult r;
  r.run_id = run_id;
  r.displacement_name = plan.displacement_name;
  r.samples = summary.samples;
  r.planned = plan.sampleCount();
  r.missing_values = summary.missing_values;
  r.complete = summary.complete;
  r.stopped_because = summary.stopped_because;
  return r;
}

}  // namespace mtcal::services
