// Guideway straightness by error separation: from probe readings in a CSV file (mtcal est),
// a probe stepping run on the simulated machine (mtcal run est) and a stored run (mtcal
// analyze est), rendered as one report.

#include <fmt/format.h>

#include "cli_session.h"
#include "commands.h"
#include "mtcal/services/est.h"

namespace mtcal::app {
namespace {

struct EstOptions {
  std::string csv_path;
  double spacing_mm = 0.0;
  std::string method = "two-probe";        ///< two-probe | three-probe | frequency
  std::string start = "carriage-at-rest";  ///< two-probe: carriage-at-rest | second-point
  std::string zero_readings_um;            ///< the file's probes on a reference flat: z1,z2[,z3]
  CsvOptions csv;
};

services::EstMethod methodOf(const EstOptions& o) { return {o.method, o.start, o.spacing_mm}; }

void report(const Globals& g, const services::EstAnalysis& a, const nlohmann::json& document) {
  for (const auto& w : a.warnings) *g.err << "warning: " << w << "\n";
  if (g.json) {
    *g.out << document.dump() << "\n";
    return;
  }
  const auto& r = a.result;
  *g.out << fmt::format("{} separation, probe spacing {} mm, {} points\n\n", a.method.method, a.method.spacing_mm,
                        r.x_mm.size());
  *g.out << "      x_mm   profile_um  carriage_um\n";
  for (std::size_t k = 0; k < r.x_mm.size(); ++k) {
    *g.out << fmt::format("{:>10.3f} {:>12.3f} {:>12}\n", r.x_mm[k], r.profile_um[k],
                          k < r.carriage_um.size() ? fmt::format("{:.3f}", r.carriage_um[k]) : "-");
  }
  *g.out << fmt::format("\nstraightness (um): least squares {:.3f}, minimum zone {:.3f}, end points {:.3f}\n",
                        a.straightness.least_squares_um, a.straightness.min_zone_um, a.straightness.end_point_um);
  if (!a.noise_um.empty())
    *g.out << fmt::format("reading scatter alone: {:.3f} um (1 sigma) at the last point\n", a.noise_um.back());
  if (a.zeroing) {
    *g.out << fmt::format("zeroed ({}): probes {:.3f} um on the flat, z3 - 2 z2 + z1 = {:.4f} um taken off\n",
                          a.zeroing->method == "given" ? "readings on a reference flat given" : "on a reference flat",
                          fmt::join(a.zeroing->zero_um, ", "), a.zeroing->combinationUm());
  }
  if (!r.lost_wavelengths_mm.empty()) {
    *g.out << fmt::format("harmonics lost by the frequency method: wavelengths {} mm\n",
                          fmt::join(r.lost_wavelengths_mm, ", "));
  }
}

int estimateStraightness(const Globals& g, const EstOptions& options) {
  auto readings = services::readProbeCsv(options.csv_path, options.method == "three-probe", options.csv.dialect());
  if (!options.zero_readings_um.empty()) {
    if (options.method != "three-probe") {
      throw InputError(
          fmt::format("--zero-readings-um: the {} method does not use the probes' zeros (the three-probe "
                      "method does: --method three-probe)",
                      options.method));
    }
    readings.zeroing = services::givenZeroing(options.zero_readings_um);
  }
  const auto a = services::separate(readings, methodOf(options));
  report(g, a, a.document());
  return 0;
}

struct EstImportOptions {
  std::string file, name, machine = storage::kImportedMachine, zero_readings_um;
  double spacing_mm = 0.0;
  CsvOptions csv;
};

int importEst(const Globals& g, const EstImportOptions& o) {
  CliSession cli(g);
  std::optional<acquisition::EstZeroing> zeroing;
  if (!o.zero_readings_um.empty()) zeroing = services::givenZeroing(o.zero_readings_um);
  const auto r = services::importEst(cli.session, o.file, o.spacing_mm, o.name, o.machine, o.csv.dialect(), zeroing);
  if (!jsonPrinted(g, r.document())) {
    *g.out << fmt::format("imported run {}: {} probe steps of {} probes{}\n", r.run_id, r.steps, r.probes,
                          r.scatter ? ", with the probes' scatter over the readings its steps averaged"
                                    : ", without the probes' scatter");
  }
  return 0;
}

int analyzeEst(const Globals& g, storage::Id run_id, const EstOptions& options) {
  CliSession cli(g);
  const auto a = services::analyzeEst(cli.session, run_id, methodOf(options));
  report(g, a, a.document());
  return 0;
}

int runEst(const Globals& g, const std::string& plan_path, const std::string& device_uri, const SimulationOptions& sim,
           const std::string& machine) {
  CliSession cli(g);
  services::EstRunRequest request;
  request.plan = acquisition::EstPlan::load(plan_path);
  request.device_uri = device_uri;
  request.simulation = sim;
  request.machine = machine;
  const auto r = services::runEst(cli.session, request);
  cli.observer.finish();
  return printEstRun(g, r);
}

}  // namespace

int printEstRun(const Globals& g, const services::EstRunResult& r) {
  if (!r.analysis) {
    if (!jsonPrinted(g, r.document()))
      *g.out << fmt::format(
          "run {} interrupted after {} steps; its steps are stored; continue it with: mtcal resume {}\n", r.run_id,
          r.steps, r.run_id);
    return 1;
  }
  report(g, *r.analysis, r.document());
  if (!g.json)
    *g.out << fmt::format("\nStored as run {}. Again, or by another method: mtcal analyze est {}\n", r.run_id,
                          r.run_id);
  return 0;
}

void registerEstCommands(CliContext& c) {
  const auto add_method = [](CLI::App* cmd, EstOptions& o) {
    cmd->add_option("--method", o.method, "two-probe, three-probe or frequency")
        ->capture_default_str()
        ->check(CLI::IsMember({"two-probe", "three-probe", "frequency"}));
    cmd->add_option("--start", o.start, "two-probe initial condition: carriage-at-rest or second-point")
        ->capture_default_str()
        ->check(CLI::IsMember({"carriage-at-rest", "second-point"}));
  };
  auto file = std::make_shared<EstOptions>();
  auto* est_cmd = c.app->add_subcommand("est", "guideway straightness by error separation from probe readings (CSV)");
  est_cmd->add_option("FILE", file->csv_path, "CSV: x_mm,v1_um,v2_um[,v3_um][,s1_um,s2_um[,s3_um],readings]")
      ->required();
  est_cmd->add_option("--spacing-mm", file->spacing_mm, "probe spacing (a whole number of steps)")
      ->required()
      ->check(positive());
  add_method(est_cmd, *file);
  est_cmd
      ->add_option("--zero-readings-um", file->zero_readings_um,
                   "the probes' readings on a reference flat, z1,z2,z3 (three probes: taken off the profile)")
      ->check(notEmpty("a reading per probe", "Z1,Z2,Z3"));
  addCsvOptions(est_cmd, file->csv);
  c.on(est_cmd, [&c, file] { return estimateStraightness(c.g, *file); });

  struct Run {
    std::string plan_path, device_uri = "mock://probes", machine = "real";
  };
  auto run = std::make_shared<Run>();
  auto* run_est = c.run->add_subcommand("est", "probe stepping plan: guideway straightness by error separation");
  run_est->add_option("PLAN", run->plan_path, "plan file (JSON, type est)")->required();
  run_est->add_option("--device", run->device_uri, "probe box URI")->capture_default_str();
  addSimulationOptions(run_est, c, "virtual machine description for mock:// devices");
  run_est->add_option("--machine", run->machine, "a real machine's name (a real probe box)")
      ->capture_default_str()
      ->check(notEmpty("a name", "NAME"));
  c.on(
      run_est, [&c, run] { return runEst(c.g, run->plan_path, run->device_uri, c.sim, run->machine); },
      OnSignal::kStopAndWait);

  auto import = std::make_shared<EstImportOptions>();
  auto* import_est = c.import->add_subcommand(
      "est", "probe readings (CSV: x_mm,v1_um,v2_um[,v3_um][,s1_um,s2_um[,s3_um],readings]) as a probe stepping run");
  import_est->add_option("FILE", import->file, "CSV file")->required();
  import_est->add_option("--spacing-mm", import->spacing_mm, "probe spacing (a whole number of steps)")
      ->required()
      ->check(positive());
  import_est->add_option("--name", import->name, "run name (default: the file name)")
      ->check(notEmpty("a name", "NAME"));
  import_est->add_option("--machine", import->machine, "machine the data belongs to")
      ->capture_default_str()
      ->check(notEmpty("a name", "NAME"));
  import_est
      ->add_option("--zero-readings-um", import->zero_readings_um,
                   "the probes' readings on a reference flat, z1,z2[,z3], stored with the run")
      ->check(notEmpty("a reading per probe", "Z1,Z2[,Z3]"));
  addCsvOptions(import_est, import->csv);
  c.on(import_est, [&c, import] { return importEst(c.g, *import); });

  auto stored = std::make_shared<EstOptions>();
  stored->method.clear();  // the run's own
  auto run_id = std::make_shared<storage::Id>(0);
  auto* analyze_est = c.analyze->add_subcommand("est", "guideway straightness of a probe stepping run");
  analyze_est->add_option("RUN", *run_id, "run id")->required();
  add_method(analyze_est, *stored);
  analyze_est->get_option("--method")
      ->description(
          "two-probe, three-probe or frequency (default: three-probe for a run of three probes, else two-probe)");
  c.on(analyze_est, [&c, run_id, stored] { return analyzeEst(c.g, *run_id, *stored); });
}

}  // namespace mtcal::app
