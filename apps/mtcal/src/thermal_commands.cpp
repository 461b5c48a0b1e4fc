// Thermal error (docs/thermal.md): import and export logger data (mtcal import thermal,
// export thermal), fit the time-series model with sensor selection (mtcal thermal fit), run a
// monitoring plan (mtcal run thermal); rendered for people or as JSON.

#include <fmt/format.h>

#include <fstream>
#include <sstream>

#include "cli_session.h"
#include "commands.h"
#include "mtcal/error.h"
#include "mtcal/services/diagnose.h"
#include "mtcal/services/thermal.h"

namespace mtcal::app {
namespace {

using ThermalFitCommandOptions = services::ThermalFitRequest;

struct ThermalRunCommandOptions {
  std::string plan_path;
  storage::Id resume_run = 0;  ///< continue this run (its plan) instead of a new one
  std::string logger_uri = "mock://logger", probes_uri = "mock://probes", interferometer_uri = "mock://interferometer";
  std::string machine = "unnamed machine";  ///< real instruments: the machine measured
};

std::string inputList(const processing::ThermalCandidate& c) {
  if (c.method == "all") return fmt::format("every usable sensor ({})", c.sensors.size());
  return fmt::format("{}", fmt::join(processing::thermalInputNames(c), ", "));
}

std::string candidateLine(const processing::ThermalCandidate& c) {
  return fmt::format(
      "  {:<8} {:<6} {:<40} cv {:7.3f} / {:7.3f}  validation {:7.3f} / {:7.3f}  test {:7.3f} / {:7.3f} (peak "
      "{:7.3f})  phi {:5.3f}  DW {:4.2f}/{:4.2f}  LB p {}  BIC {:8.1f}",
      c.method, processing::thermalFamilyName(c.family), inputList(c), c.cv_rms_um, c.cv_rms_one_step_um,
      c.validation_rms_um, c.validation_rms_one_step_um, c.rms_test_um, c.rms_test_one_step_um, c.peak_test_um, c.phi,
      c.durbin_watson, c.durbin_watson_innovations, services::pValueText(c.ljung_box_p), c.bic);
}

int runThermal(const Globals& g, const ThermalRunCommandOptions& options, const SimulationOptions& sim) {
  services::ThermalRunRequest request;
  if (options.resume_run == 0) {
    request.plan = acquisition::ThermalPlan::fromJson(services::readJsonFile(options.plan_path), options.plan_path);
  }
  request.resume_run = options.resume_run;
  request.logger_uri = options.logger_uri;
  request.probes_uri = options.probes_uri;
  request.interferometer_uri = options.interferometer_uri;
  request.machine = options.machine;
  request.simulation = sim;
  CliSession cli(g);
  const auto r = services::runThermal(cli.session, request);
  cli.observer.finish();
  return printThermalRun(g, r);
}

int importThermal(const Globals& g, const std::string& path, acquisition::ThermalImportOptions options) {
  CliSession cli(g);
  const auto r = services::importThermal(cli.session, path, std::move(options));
  if (g.json) {
    *g.out << r.document().dump() << "\n";
  } else {
    *g.out << fmt::format("imported run {}: {} samples of {} channels ({} values missing)\n", r.run_id, r.samples,
                          r.channels.size(), r.missing_values);
  }
  return 0;
}

int thermalFit(const Globals& g, storage::Id run_id, const ThermalFitCommandOptions& options) {
  CliSession cli(g);
  const auto a = services::fitThermal(cli.session, run_id, options);
  if (jsonPrinted(g, a.document())) return 0;
  const auto& r = a.fit;
  *g.out << fmt::format(
      "thermal model of run {}, target {}: {} rows, trained on the first {} (to t = {:.0f} s), tested on the rest\n",
      run_id, options.target, r.n_rows, r.n_train_rows, r.split_time_s);
  *g.out << fmt::format("model ({}, {}): delta = {:.3f} um", r.chosen.method,
                        processing::thermalFamilyName(r.chosen.family), r.chosen.coefficients(0));
  for (std::size_t i = 0; i < r.chosen.sensors.size(); ++i) {
    *g.out << fmt::format(" {:+.3f} um/K * {}", r.chosen.coefficients(static_cast<Eigen::Index>(i) + 1),
                          processing::thermalInputName(r.chosen, i));
  }
  *g.out << (r.chosen.family == processing::ThermalFamily::kAr1
                 ? fmt::format(" + eps, eps AR(1) with phi {:.3f}\n", r.chosen.phi)
                 : std::string(" + eps\n"));
  *g.out << fmt::format("test: open loop rms {:.3f} um, peak {:.3f} um; one step ahead rms {:.3f} um, peak {:.3f} um\n",
                        r.chosen.rms_test_um, r.chosen.peak_test_um, r.chosen.rms_test_one_step_um,
                        r.chosen.peak_test_one_step_um);
  *g.out << "a compensation predicts open loop (it has no measured error): the model kept predicts the validation "
            "block (the training part's last quarter, which no search saw) best open loop\n";
  *g.out << fmt::format("baseline (one sensor, {}, linear): test rms {:.3f} um, peak {:.3f} um; gain {:.1f} %\n",
                        r.baseline.sensors.front(), r.baseline.rms_test_um, r.baseline.peak_test_um, 100.0 * r.gain);
  if (r.all_sensors) {
    *g.out << fmt::format("every sensor ({}, least squares): test rms {:.3f} um, peak {:.3f} um\n",
                          r.all_sensors->sensors.size(), r.all_sensors->rms_test_um, r.all_sensors->peak_test_um);
  }
  *g.out << fmt::format(
      "the test part's own standard deviation: {:.3f} um (what its mean, unknown beforehand, would "
      "leave)\n",
      r.test_sd_um);
  *g.out << fmt::format("grey relational grades ({} normalisation, rho {}):\n",
                        processing::greyNormalisationName(r.normalisation), r.rho);
  for (const auto& s : r.sensors) {
    if (s.usable) {
      *g.out << fmt::format("  {:>2}. {:<16} grade {:.4f}  r {:+.3f}  cluster {}\n", s.rank, s.name, s.grade,
                            s.correlation, s.cluster);
    } else {
      *g.out << fmt::format("   -  {:<16} not used: {}\n", s.name, s.note);
    }
  }
  *g.out << "candidates (um, open loop / one step ahead; cv: rolling-origin cross-validation on the search's rows; "
            "validation: the training part's last quarter):\n";
  for (const auto& path : r.paths) {
    for (const auto& c : path.models) *g.out << candidateLine(c) << "\n";
  }
  if (r.all_sensors) *g.out << candidateLine(*r.all_sensors) << "\n";
  *g.out << candidateLine(r.baseline) << "\n";
  *g.out << "families compared (each path's model of least validation rms):\n";
  for (const auto* c : processing::bestOfEachPath(r)) *g.out << candidateLine(*c) << "\n";
  if (a.needed) {
    *g.out << fmt::format("{} um needs {} sensors ({})\n", options.accuracy_um, a.needed->sensors.size(),
                          fmt::join(a.needed->sensors, ", "));
  } else if (options.accuracy_um > 0.0) {
    *g.out << fmt::format("no candidate reaches {} um on the test part\n", options.accuracy_um);
  }
  for (const auto& n : r.notes) *g.out << "note: " << n << "\n";
  return 0;
}

}  // namespace

int printThermalRun(const Globals& g, const services::ThermalRunResult& r) {
  if (!jsonPrinted(g, r.document())) {
    *g.out << fmt::format("run {}: {} of {} samples ({} values missing this session)\n", r.run_id, r.samples, r.planned,
                          r.missing_values);
    if (!r.complete)
      *g.out << fmt::format("interrupted: {}; continue it with: mtcal resume {}\n", r.stopped_because, r.run_id);
    else
      *g.out << fmt::format("fit its model: mtcal thermal fit {} --target {}\n", r.run_id, r.displacement_name);
  }
  return r.complete ? 0 : 1;
}

void registerThermalCommands(CliContext& c) {
  auto run = std::make_shared<ThermalRunCommandOptions>();
  auto* run_thermal =
      c.run->add_subcommand("thermal", "thermal monitoring plan: temperatures and drift for hours, spindle program");
  run_thermal->add_option("PLAN", run->plan_path, "plan file (JSON, type thermal)");
  run_thermal->add_option("--resume", run->resume_run, "continue an interrupted thermal run (its own plan)");
  run_thermal->add_option("--logger", run->logger_uri, "temperature logger URI")->capture_default_str();
  run_thermal->add_option("--probes", run->probes_uri, "probe box URI (the displacement)")->capture_default_str();
  run_thermal
      ->add_option("--interferometer", run->interferometer_uri, "interferometer URI (displacement or environment)")
      ->capture_default_str();
  run_thermal->add_option("--machine", run->machine, "real instruments: the machine measured")
      ->capture_default_str()
      ->check(notEmpty("a name", "NAME"));
  addSimulationOptions(run_thermal, c, "virtual machine description with a thermal object");
  c.on(
      run_thermal,
      [&c, run] {
        if (run->plan_path.empty() == (run->resume_run == 0))
          throw InputError("run thermal: give a PLAN or --resume RUN");
        return runThermal(c.g, *run, c.sim);
      },
      OnSignal::kStopAndWait);

  struct Import {
    std::string file;
    acquisition::ThermalImportOptions options;
    CsvOptions csv;
  };
  auto import = std::make_shared<Import>();
  auto* import_thermal = c.import->add_subcommand("thermal",
                                                  "thermal monitoring data (CSV): time_s, displacement columns (a "
                                                  "length unit: _um, [mm]), temperatures (degC); empty cells missing");
  import_thermal->add_option("FILE", import->file, "CSV file")->required();
  import_thermal
      ->add_option("--interval-s", import->options.interval_s,
                   fmt::format("seconds between rows, for a file without a time column (default {:g})",
                               acquisition::kRowIntervalS))
      ->check(positive());
  import_thermal->add_option("--target", import->options.target,
                             "the displacement column (um), when its name does not end in _um");
  import_thermal->add_option("--name", import->options.name, "run name (default: the file name)")
      ->check(notEmpty("a name", "NAME"));
  import_thermal->add_option("--machine", import->options.machine, "machine the data belongs to")
      ->capture_default_str()
      ->check(notEmpty("a name", "NAME"));
  addCsvOptions(import_thermal, import->csv);
  c.on(import_thermal, [&c, import] {
    import->options.csv = import->csv.dialect();
    return importThermal(c.g, import->file, import->options);
  });

  struct Stored {
    storage::Id run_id = 0;
    std::string csv;
    ThermalFitCommandOptions fit;
  };
  auto o = std::make_shared<Stored>();
  auto* thermal_cmd =
      c.app->add_subcommand("thermal", "thermal error: time-series model of the drift from temperatures")
          ->require_subcommand(1);
  auto* thermal_fit =
      thermal_cmd->add_subcommand("fit", "fit, select sensors (grey relational + stepwise) and validate on later data");
  thermal_fit->add_option("RUN", o->run_id, "run id (a thermal run)")->required();
  thermal_fit->add_option("--target", o->fit.target, "displacement channel to model (um)")->required();
  thermal_fit->add_option("--train-fraction", o->fit.train_fraction, "first part of the rows that fits; the rest tests")
      ->capture_default_str()
      ->check(between(0.05, 0.95));
  thermal_fit
      ->add_option("--validation-fraction", o->fit.validation_fraction,
                   "last part of the training rows that compares the models (no search sees it)")
      ->capture_default_str()
      ->check(between(0.05, 0.5));
  thermal_fit->add_option("--max-sensors", o->fit.max_sensors, "largest model tried")
      ->capture_default_str()
      ->transform(wholeBetween(1, 32));
  thermal_fit
      ->add_option("--normalisation", o->fit.normalisation, "grey relational normalisation: range, initial, mean")
      ->capture_default_str()
      ->check(CLI::IsMember({"range", "initial", "mean"}));
  thermal_fit->add_option("--rho", o->fit.rho, "grey resolution coefficient")
      ->capture_default_str()
      ->check(between(0.01, 1.0));
  thermal_fit->add_flag("--with-speed", o->fit.with_speed, "the spindle speed (rpm channels) is an input too");
  thermal_fit->add_option("--accuracy-um", o->fit.accuracy_um, "report the fewest sensors reaching this test RMS")
      ->check(positive());
  thermal_fit->add_option("--predictions", o->fit.predictions_path, "write the model's predictions (CSV)");
  c.on(thermal_fit, [&c, o] { return thermalFit(c.g, o->run_id, o->fit); });
}

}  // namespace mtcal::app
