// Thermal error (docs/thermal.md): import logger data (mtcal import thermal), fit the
// time-series model with sensor selection (mtcal thermal fit), run a monitoring plan on the
// simulated machine or with a real logger (mtcal run thermal).

#include <fmt/format.h>

#include <cmath>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>

#include "commands.h"
#include "mtcal/acquisition/thermal_data.h"
#include "mtcal/acquisition/thermal_run.h"
#include "mtcal/services/workshop.h"
#include "mtcal/drivers/registry.h"
#include "mtcal/services/version.h"
#include "mtcal/error.h"
#include "report.h"

namespace mtcal::app {
namespace {

/// NaN (undefined) as JSON null.
nlohmann::json number(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(); }

nlohmann::json candidateJson(const processing::ThermalCandidate& c) {
  nlohmann::json coefficients = {{"intercept_um", c.coefficients(0)}};
  for (std::size_t i = 0; i < c.sensors.size(); ++i) coefficients[c.sensors[i]] = c.coefficients(static_cast<Eigen::Index>(i) + 1);
  return {{"method", c.method},
          {"sensors", c.sensors},
          {"coefficients", coefficients},
          {"phi", c.phi},
          {"n_train", c.n_train},
          {"n_test", c.n_test},
          {"cv_rms_um", number(c.cv_rms_um)},
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

std::string candidateLine(const processing::ThermalCandidate& c) {
  return fmt::format("  {:<9} {:<28} cv {:7.3f}  train {:7.3f}  test {:7.3f} (peak {:7.3f})  1-step {:6.3f}  phi {:5.3f}  DW {:4.2f}/{:4.2f}  "
                     "LB p {:.3g}  BIC {:8.1f}",
                     c.method, fmt::format("{}", fmt::join(c.sensors, ",")), c.cv_rms_um, c.rms_train_um, c.rms_test_um,
                     c.peak_test_um, c.rms_test_one_step_um, c.phi, c.durbin_watson, c.durbin_watson_innovations, c.ljung_box_p, c.bic);
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
  explicit OperatorSpindle(const Globals& g) : g_(g) {}
  void startProgram(const std::vector<acquisition::ThermalPhase>& phases, double) override {
    *g_.err << "The logger is recording. Start the spindle program on the CNC now (mtcal plan gcode PLAN):\n";
    for (const auto& p : phases) *g_.err << fmt::format("  {}: {:.1f} min at {:.0f} rpm\n", p.name, p.duration_s / 60.0, p.speed_rpm);
    *g_.err << "Press Enter when it runs.\n";
    std::string line;
    if (!g_.in || !std::getline(*g_.in, line)) throw InputError("run thermal: no answer from the operator (the input is closed)");
  }

 private:
  const Globals& g_;
};

}  // namespace

int runThermal(const Globals& g, const ThermalRunCommandOptions& options, const SimulationOptions& sim_options) {
  storage::Store store(g.db);
  storage::Id run_id = options.resume_run;
  acquisition::ThermalPlan plan;
  if (run_id != 0) {
    const auto info = store.run(run_id);
    if (info.kind != "thermal" || info.source != "acquired") throw InputError(fmt::format("run {} is not an acquired thermal run", run_id));
    if (info.status == storage::run_status::kCompleted) throw InputError(fmt::format("run {} is complete", run_id));
    plan = acquisition::ThermalPlan::fromJson(nlohmann::json::parse(info.plan_json), fmt::format("run {}", run_id));
  } else {
    plan = acquisition::ThermalPlan::fromJson(nlohmann::json::parse(readTextFile(options.plan_path)), options.plan_path);
  }
  const auto is_mock = [](const std::string& uri) { return drivers::DeviceUri::parse(uri).scheme == "mock"; };
  const bool simulated = is_mock(options.logger_uri);
  const bool needs_interferometer = plan.displacement_device == "interferometer" || plan.environment;
  if (is_mock(options.probes_uri) != simulated || (needs_interferometer && is_mock(options.interferometer_uri) != simulated)) {
    throw InputError("run thermal: the instruments are either all simulated (mock://) or all real");
  }
  // The simulated machine and its instruments, or the real instruments with the operator
  // starting the spindle program on the CNC.
  std::unique_ptr<Simulation> sim;
  drivers::Registry real_registry;
  drivers::Registry* registry = &real_registry;
  std::unique_ptr<acquisition::SpindleController> spindle;
  std::string file_json, machine_name = options.machine, machine_description = "real machine";
  std::chrono::milliseconds record_timeout{(plan.interval_s + 60) * 1000LL};
  if (simulated) {
    auto config = machineConfig(sim_options, &file_json);
    if (!config.thermal) {
      if (!file_json.empty()) throw InputError(sim_options.machine_file + ": the machine has no thermal object (docs/thermal.md)");
      config.thermal = mocks::MachineThermalConfig{};
      config.thermal->ambient_swing_k = 0.8;  // the demo shop's daily swing
    }
    sim = std::make_unique<Simulation>(config, demoInterferometer(), sim_options.time_scale);
    const int along = plan.displacement_axis == "Z" ? 2 : 1;
    sim->world.probes.setMeasuring(along);
    sim->world.interferometer->mount(along == 2 ? mocks::Axis::kZ : mocks::Axis::kY, along, {0.0, 0.0, 0.0});
    registry = &sim->registry;
    spindle = std::make_unique<VirtualSpindle>(*sim->world.machine.thermal());
    machine_name = machineName(config, !file_json.empty());
    machine_description = simulationDescription(config, file_json);
    record_timeout = std::chrono::milliseconds(static_cast<long long>(1000.0 * (plan.interval_s / sim_options.time_scale)) + 5000);
  } else {
    drivers::registerBuiltInDrivers(real_registry);
    spindle = std::make_unique<OperatorSpindle>(g);
  }
  auto logger = registry->openAs<drivers::logger::TemperatureLoggerDevice>(options.logger_uri);
  std::unique_ptr<drivers::probes::ProbeBoxDevice> probes;
  std::unique_ptr<drivers::interferometer::InterferometerDevice> interferometer;
  if (plan.displacement_device == "probes") probes = registry->openAs<drivers::probes::ProbeBoxDevice>(options.probes_uri);
  if (needs_interferometer) interferometer = registry->openAs<drivers::interferometer::InterferometerDevice>(options.interferometer_uri);
  if (run_id == 0) {
    const auto info = logger->info();
    const storage::Id instrument_id = store.ensureInstrument({info.kind, info.model, info.serial, info.firmware, options.logger_uri});
    const storage::Id machine_id = store.ensureMachine(machine_name, simulated ? "simulated machine" : "", machine_description);
    storage::NewRun run;
    run.campaign_id = store.addCampaign(machine_id, plan.name);
    run.instrument_id = instrument_id;
    run.kind = "thermal";
    run.name = plan.name;
    run.plan_json = plan.toJson().dump();
    run.software_version = kVersion;
    run_id = store.addRun(run);
  }
  ProgressBar bar(*g.err, g.terminal);
  acquisition::ThermalRunOptions run_options;
  run_options.stop_requested = g.stop;
  run_options.record_timeout = record_timeout;
  if (sim) run_options.run_clock = &sim->run_clock;
  if (!g.json) {
    run_options.on_progress = [&bar](std::int64_t done, std::int64_t total, double drift_um) {
      bar.update(static_cast<std::size_t>(done), static_cast<std::size_t>(total), fmt::format("{:>8.2f} um", drift_um));
    };
  }
  const auto summary = acquisition::runThermalMonitoring(plan, {*logger, probes.get(), interferometer.get()}, *spindle, store, run_id, run_options);
  bar.finish();
  if (g.json) {
    *g.out << nlohmann::json{{"run_id", run_id}, {"samples", summary.samples}, {"planned", plan.sampleCount()},
                             {"missing_values", summary.missing_values}, {"complete", summary.complete},
                             {"stopped_because", summary.stopped_because}}
                  .dump()
           << "\n";
  } else {
    *g.out << fmt::format("run {}: {} of {} samples ({} values missing this session)\n", run_id, summary.samples, plan.sampleCount(),
                          summary.missing_values);
    if (!summary.complete) *g.out << fmt::format("interrupted: {}; continue with: mtcal run thermal --resume {}\n", summary.stopped_because, run_id);
    else *g.out << fmt::format("fit its model: mtcal thermal fit {} --target {}\n", run_id, plan.displacement_name);
  }
  return summary.complete ? 0 : 1;
}

int exportThermal(const Globals& g, storage::Id run_id, const std::string& path) {
  storage::Store store(g.db);
  if (path.empty() || path == "-") {
    acquisition::writeThermalCsv(store, run_id, *g.out);
    return 0;
  }
  std::ofstream out(path);
  if (!out) throw InputError(path + ": cannot write");
  acquisition::writeThermalCsv(store, run_id, out);
  *g.err << fmt::format("run {} written to {}\n", run_id, path);
  return 0;
}

int importThermal(const Globals& g, const std::string& path, acquisition::ThermalImportOptions options) {
  storage::Store store(g.db);
  options.software_version = kVersion;
  const storage::Id id = acquisition::importThermalCsv(store, path, options);
  const auto channels = store.thermalChannels(id);
  const auto samples = store.thermalSamples(id);
  std::size_t missing = 0;
  for (const auto& s : samples) {
    for (const auto& v : s.values) missing += v ? 0 : 1;
  }
  if (g.json) {
    nlohmann::json names = nlohmann::json::array();
    for (const auto& c : channels) names.push_back({{"name", c.name}, {"kind", c.kind}, {"unit", c.unit}});
    *g.out << nlohmann::json{{"run_id", id}, {"samples", samples.size()}, {"channels", names}, {"missing_values", missing}}.dump() << "\n";
  } else {
    *g.out << fmt::format("imported run {}: {} samples of {} channels ({} values missing)\n", id, samples.size(), channels.size(), missing);
  }
  return 0;
}

int thermalFit(const Globals& g, storage::Id run_id, const ThermalFitCommandOptions& options) {
  storage::Store store(g.db);
  const processing::ThermalData data = acquisition::thermalDataOfRun(store, run_id, options.target, options.with_speed);
  processing::ThermalFitOptions fit_options;
  fit_options.train_fraction = options.train_fraction;
  fit_options.max_sensors = options.max_sensors;
  fit_options.normalisation = processing::greyNormalisationFromName(options.normalisation);
  fit_options.rho = options.rho;
  const processing::ThermalFitResult r = processing::fitThermalModel(data, fit_options);

  const nlohmann::json model = candidateJson(r.chosen);
  nlohmann::json sensors = nlohmann::json::array();
  for (const auto& s : r.sensors) {
    sensors.push_back({{"name", s.name},
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
  nlohmann::json grey = nlohmann::json::array(), stepwise = nlohmann::json::array();
  for (const auto& c : r.grey) grey.push_back(candidateJson(c));
  for (const auto& c : r.stepwise) stepwise.push_back(candidateJson(c));
  // How many sensors a given accuracy needs: the fewest of either path whose test RMS reaches it.
  nlohmann::json needed = nullptr;
  if (options.accuracy_um > 0.0) {
    for (const auto* path : {&r.stepwise, &r.grey}) {
      for (const auto& c : *path) {
        if (c.rms_test_um <= options.accuracy_um && (needed.is_null() || c.sensors.size() < needed["sensors"].size())) {
          needed = {{"accuracy_um", options.accuracy_um}, {"method", c.method}, {"sensors", c.sensors}, {"rms_test_um", c.rms_test_um}};
        }
      }
    }
  }
  const nlohmann::json out = {{"run_id", run_id},
                              {"target", options.target},
                              {"rows", r.n_rows},
                              {"train_rows", r.n_train_rows},
                              {"split_time_s", r.split_time_s},
                              {"normalisation", processing::greyNormalisationName(r.normalisation)},
                              {"rho", r.rho},
                              {"selected_sensors", r.chosen.sensors},
                              {"selection", r.chosen.method},
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
                              {"model", model},
                              {"baseline", candidateJson(r.baseline)},
                              {"sensors", sensors},
                              {"grey_path", grey},
                              {"stepwise_path", stepwise},
                              {"sensors_needed", needed},
                              {"notes", r.notes}};
  store.addResult(run_id, "thermal-fit", kVersion,
                  nlohmann::json{{"target", options.target},
                                 {"train_fraction", options.train_fraction},
                                 {"max_sensors", options.max_sensors},
                                 {"normalisation", options.normalisation},
                                 {"rho", options.rho},
                                 {"with_speed", options.with_speed}}
                      .dump(),
                  out.dump());
  if (!options.predictions_path.empty()) {
    std::ofstream csv(options.predictions_path);
    if (!csv) throw InputError(options.predictions_path + ": cannot write");
    csv << "time_s,measured_um,open_loop_um,one_step_um,part\n";
    for (Eigen::Index i = 0; i < data.time_s.size(); ++i) {
      auto cell = [](double v) { return std::isfinite(v) ? fmt::format("{:.4f}", v) : std::string(); };
      csv << fmt::format("{:.3f},{},{},{},{}\n", data.time_s(i), cell(data.target_um(i)), cell(r.predicted_open_loop_um(i)),
                         cell(r.predicted_one_step_um(i)), i < r.n_train_rows ? "train" : "test");
    }
  }
  if (g.json) {
    *g.out << out.dump() << "\n";
    return 0;
  }
  *g.out << fmt::format("thermal model of run {}, target {}: {} rows, trained on the first {} (to t = {:.0f} s), tested on the rest\n",
                        run_id, options.target, r.n_rows, r.n_train_rows, r.split_time_s);
  *g.out << fmt::format("model ({}): delta = {:.3f} um", r.chosen.method, r.chosen.coefficients(0));
  for (std::size_t i = 0; i < r.chosen.sensors.size(); ++i) {
    *g.out << fmt::format(" {:+.3f} um/K * {}", r.chosen.coefficients(static_cast<Eigen::Index>(i) + 1), r.chosen.sensors[i]);
  }
  *g.out << fmt::format(" + eps, eps AR(1) with phi {:.3f}\n", r.chosen.phi);
  *g.out << fmt::format("test: open loop rms {:.3f} um, peak {:.3f} um; one step ahead rms {:.3f} um, peak {:.3f} um\n",
                        r.chosen.rms_test_um, r.chosen.peak_test_um, r.chosen.rms_test_one_step_um, r.chosen.peak_test_one_step_um);
  *g.out << fmt::format("baseline (one sensor, {}, linear): test rms {:.3f} um, peak {:.3f} um; gain {:.1f} %\n",
                        r.baseline.sensors.front(), r.baseline.rms_test_um, r.baseline.peak_test_um, 100.0 * r.gain);
  *g.out << fmt::format("grey relational grades ({} normalisation, rho {}):\n", processing::greyNormalisationName(r.normalisation), r.rho);
  for (const auto& s : r.sensors) {
    if (s.usable) {
      *g.out << fmt::format("  {:>2}. {:<16} grade {:.4f}  r {:+.3f}  cluster {}\n", s.rank, s.name, s.grade, s.correlation, s.cluster);
    } else {
      *g.out << fmt::format("   -  {:<16} not used: {}\n", s.name, s.note);
    }
  }
  *g.out << "candidates (um; cv = rolling-origin cross-validation on the training part):\n";
  for (const auto& c : r.grey) *g.out << candidateLine(c) << "\n";
  for (const auto& c : r.stepwise) *g.out << candidateLine(c) << "\n";
  *g.out << candidateLine(r.baseline) << "\n";
  if (!needed.is_null()) {
    *g.out << fmt::format("{} um needs {} sensors ({})\n", options.accuracy_um, needed["sensors"].size(),
                          fmt::join(needed["sensors"].get<std::vector<std::string>>(), ", "));
  } else if (options.accuracy_um > 0.0) {
    *g.out << fmt::format("no candidate reaches {} um on the test part\n", options.accuracy_um);
  }
  for (const auto& n : r.notes) *g.out << "note: " << n << "\n";
  return 0;
}

}  // namespace mtcal::app
