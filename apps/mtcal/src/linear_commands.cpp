#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <map>
#include <sstream>

#include "cli_session.h"
#include "commands.h"
#include "mtcal/error.h"
#include "mtcal/services/archive.h"
#include "mtcal/services/linear.h"
#include "mtcal/services/plans.h"
#include "report.h"

namespace mtcal::app {

int printLinearRun(const Globals& g, const services::LinearRunResult& r, const std::string& plan_name) {
  if (g.json) {
    *g.out << r.document().dump() << "\n";
    return r.status == "completed" ? 0 : 1;
  }
  if (r.status != "completed") {
    *g.out << fmt::format("run {} interrupted after {} targets; continue it with: mtcal resume {}\n", r.run_id,
                          r.targets, r.run_id);
    return 1;
  }
  if (!r.iso230_2) {
    // Straightness and angular runs are not ISO 230-2 material: they feed the error model.
    *g.out << fmt::format(
        "run {} (campaign c{}) completed: {} ({}), {} targets. Identify it with: mtcal model identify {} "
        "(or c{}, the whole campaign) --machine ...\n",
        r.run_id, r.campaign_id, r.measures, r.unit, r.targets, r.run_id, r.campaign_id);
    return 0;
  }
  *g.out << fmt::format("run {} (campaign c{}) completed: {}\n\n", r.run_id, r.campaign_id, plan_name);
  printIso230(*g.out, *r.iso230_2);
  if (r.simulation_check) {
    *g.out << fmt::format(
        "\nSimulation check: the measured mean deviations match the virtual machine's true errors\n"
        "within {:.2f} um (RMS {:.2f} um), after removing the common datum offset of {:+.2f} um.\n",
        r.simulation_check->max_abs_um, r.simulation_check->rms_um, r.simulation_check->datum_offset_um);
  }
  const std::string db_option = g.db == Globals{}.db ? "" : fmt::format("--db '{}' ", g.db);
  *g.out << fmt::format("Stored in {} as run {}. See it again with: mtcal {}analyze iso230-2 {}\n", g.db, r.run_id,
                        db_option, r.run_id);
  return 0;
}

namespace {

struct RunOptions {
  bool triggered = false;                   ///< mock devices: the virtual CNC runs the part program
  std::string machine = "unnamed machine";  ///< real devices: the machine measured
};

int runLinear(const Globals& g, const std::vector<std::string>& plan_paths, const std::string& device_uri,
              const SimulationOptions& sim_options, const RunOptions& run_options) {
  services::LinearRunRequest request;
  for (const auto& path : plan_paths)
    request.plans.push_back(acquisition::LinearPlan::load(path));  // all valid before any run
  request.plan_path = plan_paths.empty() ? "" : plan_paths.front();
  request.device_uri = device_uri;
  request.simulation = sim_options;
  request.triggered = run_options.triggered;
  request.machine = run_options.machine;
  CliSession cli(g);
  const auto campaign = services::runLinear(cli.session, request);
  cli.observer.finish();
  const auto plans = request.plans.empty() ? std::vector{acquisition::LinearPlan::demo()} : request.plans;
  if (g.json && plans.size() > 1) {  // one document: the campaign's runs
    *g.out << campaign.document().dump() << "\n";
    return campaign.interrupted() ? 1 : 0;
  }
  for (std::size_t i = 0; i < campaign.runs.size(); ++i) {
    if (const int code = printLinearRun(g, campaign.runs[i], plans[i].name); code != 0)
      return code;  // interrupted: stop here
  }
  return 0;
}

int demo(const Globals& g, const SimulationOptions& sim) {
  {
    // Refused before anything is printed: the plant archive, or a file that is no store.
    CliSession cli(g);
    cli.session.requireLocalStore("demo");
    cli.session.open(services::Access::kCreate);
  }
  if (!g.json) {
    *g.out << "mtcal demo: ISO 230-2 calibration of the X axis of a simulated 3-axis machine\n"
           << "  laser interferometer: mock://interferometer through the real USB protocol driver\n"
           << "  plan: X 50 to 600 mm, a node every 20 mm, 9 cycles, both directions\n"
           << "  database: " << g.db << "\n\n";
  }
  return runLinear(g, {}, "mock://interferometer", sim, RunOptions{});  // no plan file: the demo plan
}

/// "Y=200,Z=50" (one or several options) as axis -> mm.
std::map<std::string, double> lineOf(const std::vector<std::string>& given) {
  std::map<std::string, double> line;
  for (const auto& list : given) {
    std::stringstream items(list);
    std::string item;
    while (std::getline(items, item, ',')) {
      const auto eq = item.find('=');
      const auto mm = eq == std::string::npos ? std::nullopt : decimalNumber(item.substr(eq + 1));
      if (!mm || !std::isfinite(*mm))
        throw InputError("--line-position-mm takes AXIS=MM pairs like Y=200,Z=50, got '" + item + "'");
      if (!line.emplace(item.substr(0, eq), *mm).second)
        throw InputError("--line-position-mm gives axis " + item.substr(0, eq) + " twice");
    }
  }
  return line;
}

int importLinear(const Globals& g, const std::string& path, acquisition::LinearImportOptions options) {
  CliSession cli(g);
  const auto imported = services::importLinear(cli.session, path, std::move(options));
  if (!jsonPrinted(g, imported.document())) {
    for (std::size_t k = 0; k < imported.run_ids.size(); ++k) {
      *g.out << fmt::format("imported run {}: {} readings of {}\n", imported.run_ids[k], imported.readings[k],
                            imported.measures[k]);
    }
  }
  return 0;
}

int importCampaign(const Globals& g, const std::string& path, const acquisition::CampaignImportOptions& options) {
  CliSession cli(g);
  const auto imported = services::importCampaign(cli.session, path, options);
  if (!jsonPrinted(g, {{"schema_version", 1},
                       {"campaign_id", imported.campaign_id},
                       {"run_ids", imported.run_ids},
                       {"warnings", imported.warnings}})) {
    *g.out << fmt::format("imported campaign c{}: {} run(s), {}\n", imported.campaign_id, imported.run_ids.size(),
                          fmt::join(imported.run_ids, ", "));
  }
  return 0;
}

int analyzeIso230(const Globals& g, storage::Id run_id) {
  CliSession cli(g);
  const auto a = services::analyzeIso230_2(cli.session, run_id);
  if (jsonPrinted(g, a.document())) return 0;
  *g.out << fmt::format("run {} '{}', axis {}: ISO 230-2 evaluation\n\n", run_id, a.run_name, a.axis);
  printIso230(*g.out, a);
  return 0;
}

/// What the standard's note says and what the simulated machine itself does, for people.
void printNotes(std::ostream& out, const services::PositioningAnalysis& a) {
  for (const auto& w : a.iso230_2.warnings) out << fmt::format("warning: run {}: {}\n", a.iso230_2.run_id, w);
  if (!a.evaluation.note.empty()) out << fmt::format("note: {}\n", a.evaluation.note);
  if (a.truth_E_um) {
    out << fmt::format(
        "the simulated machine itself at these targets (no scatter): E {:.2f} um, M {:.2f} um (ISO 230-2)\n",
        *a.truth_E_um, *a.truth_M_um);
  }
}

int analyzeLinear(const Globals& g, storage::Id run_id, const std::string& standard) {
  CliSession cli(g);
  const auto a = services::analyzeLinear(cli.session, run_id, standard);
  if (jsonPrinted(g, a.document())) return 0;
  *g.out << fmt::format("run {} '{}', axis {}: {}\n\n", run_id, a.iso230_2.run_name, a.iso230_2.axis,
                        a.evaluation.title);
  for (const auto& f : a.evaluation.figures)
    *g.out << fmt::format("  {:<18} {:>8.2f} um  {}\n", f.symbol, f.value_um, f.name);
  *g.out << "\n";
  printNotes(*g.out, a);
  return 0;
}

int compareRuns(const Globals& g, storage::Id before, storage::Id after, const std::string& standard) {
  CliSession cli(g);
  const auto c = services::compareRuns(cli.session, before, after, standard);
  if (jsonPrinted(g, c.document())) return 0;
  *g.out << fmt::format("axis {}, {}: run {} (before) and run {} (after)\n\n", c.before.iso230_2.axis,
                        c.before.evaluation.title, before, after);
  *g.out << fmt::format("  {:<18} {:>9} {:>9} {:>9}\n", "", "before", "after", "change");
  for (const auto& f : c.before.evaluation.figures) {
    const double now = c.after.evaluation.value(f.symbol);
    const std::string pct =
        f.value_um > 0.0 && now >= 0.0 ? fmt::format(" ({:+.0f} %)", 100.0 * (now - f.value_um) / f.value_um) : "";
    *g.out << fmt::format("  {:<18} {:>6.2f} um {:>6.2f} um {:>+6.2f} um{}\n", f.symbol, f.value_um, now,
                          now - f.value_um, pct);
  }
  *g.out << "\n";
  if (c.before.truth_E_um && c.after.truth_E_um) {
    *g.out << fmt::format(
        "the simulated machine itself at the runs' targets (no scatter, ISO 230-2): E {:.2f} -> {:.2f} um, M {:.2f} "
        "-> {:.2f} um\n",
        *c.before.truth_E_um, *c.after.truth_E_um, *c.before.truth_M_um, *c.after.truth_M_um);
  }
  for (const auto* a : {&c.before, &c.after})
    for (const auto& w : a->iso230_2.warnings) *g.out << fmt::format("warning: run {}: {}\n", a->iso230_2.run_id, w);
  for (const auto& w : c.warnings) *g.out << fmt::format("warning: {}\n", w);
  if (!c.before.evaluation.note.empty()) *g.out << fmt::format("note: {}\n", c.before.evaluation.note);
  return 0;
}

int airIndex(const Globals& g, const std::string& model, double temp_c, double pressure_pa, double humidity_pct,
             double co2_ppm, double wavelength_nm) {
  const auto a = services::airIndex(model, {temp_c, pressure_pa, humidity_pct, co2_ppm}, wavelength_nm);
  if (g.json) {
    *g.out << a.document().dump(-1, ' ', false) << "\n";
  } else {
    *g.out << fmt::format("{:.10f}\n", a.n);
  }
  return 0;
}

int planGcode(const Globals& g, const std::string& plan_path, const std::string& output_path,
              const std::string& machine_file) {
  const auto p = services::partProgram(plan_path, machine_file);
  const bool to_stdout = output_path.empty() || output_path == "-";
  if (!to_stdout) services::writeTextFile(output_path, p.program);
  if (!jsonPrinted(g, p.document(to_stdout ? "" : output_path)) && to_stdout) *g.out << p.program;
  return 0;
}

}  // namespace

void registerLinearCommands(CliContext& c) {
  auto* demo_cmd =
      c.app->add_subcommand("demo", "run a complete simulated X-axis calibration (ISO 230-2) and print it");
  addSimulationOptions(demo_cmd, c, "");
  c.on(
      demo_cmd, [&c] { return demo(c.g, c.sim); }, OnSignal::kStopAndWait);

  struct Run {
    std::vector<std::string> plan_paths;
    std::string device_uri = "mock://interferometer";
    RunOptions options;
    std::vector<std::string> compensation;  ///< [AXIS=]FILE
    std::string controller = "csv";
  };
  auto run = std::make_shared<Run>();
  auto* run_linear = c.run->add_subcommand("linear", "linear positioning plan (ISO 230-2 test cycle)");
  run_linear->add_option("PLAN", run->plan_paths, "plan file(s) (JSON); several run as one campaign (simulation only)")
      ->required();
  run_linear->add_option("--device", run->device_uri, "interferometer URI")->capture_default_str();
  run_linear->add_flag("--triggered", run->options.triggered,
                       "mock:// devices: the virtual CNC runs the part program and targets are captured when the "
                       "machine holds them (the workflow of a real machine)");
  run_linear->add_option("--machine", run->options.machine, "real devices: name of the machine measured")
      ->capture_default_str()
      ->check(notEmpty("a name", "NAME"));
  addSimulationOptions(run_linear, c, "virtual machine description for mock:// devices");
  run_linear->add_option("--compensation", run->compensation,
                         "mock:// devices: a compensation table the virtual CNC applies, [AXIS=]FILE (default axis: "
                         "the plan's); stored with the run");
  run_linear->add_option("--controller", run->controller, "the tables' format and how the CNC applies them")
      ->capture_default_str();
  c.on(
      run_linear,
      [&c, run, run_linear] {
        if (run_linear->count("--controller") && run->compensation.empty())
          throw InputError("--controller names the format of --compensation tables: none is given");
        for (const auto& given : run->compensation) {
          const auto equals = given.find('=');
          c.sim.compensation.push_back({equals == std::string::npos ? "" : given.substr(0, equals),
                                        equals == std::string::npos ? given : given.substr(equals + 1),
                                        run->controller});
        }
        return runLinear(c.g, run->plan_paths, run->device_uri, c.sim, run->options);
      },
      OnSignal::kStopAndWait);

  struct Import {
    std::string file;
    acquisition::LinearImportOptions options;
    std::string model = "edlen";
    std::vector<std::string> line_position;
    std::string reflector_offset_mm;
    CsvOptions csv;
  };
  auto import = std::make_shared<Import>();
  auto* import_linear = c.import->add_subcommand(
      "linear", "a linear run (CSV): positioning, straightness or angle along an axis, or all of them by column");
  import_linear->add_option("FILE", import->file, "CSV file")->required();
  import_linear->add_option("--axis", import->options.axis, "axis measured (X, Y, Z; x as X)")
      ->capture_default_str()
      ->transform(CLI::Validator(
          [](std::string& text) {
            std::transform(text.begin(), text.end(), text.begin(),
                           [](unsigned char c) { return static_cast<char>(std::toupper(c)); });
            return std::string();
          },
          "", "upper case"));
  import_linear->add_option("--measures", import->options.measures,
                            "the error measured, e.g. EYX (straightness in Y) or EBX (pitch); default positioning");
  import_linear->add_option("--units", import->options.value_unit,
                            "the value's unit when the header has none: um, mm, urad, arcsec, mm/m ...");
  import_linear->add_option("--line-position-mm", import->line_position,
                            "the other axes' positions on the measured line, e.g. Y=200,Z=50 (default 0)");
  const auto* reflector = addXyzOption(import_linear, "--reflector-offset-mm", import->reflector_offset_mm,
                                       "the optic's offset from the tool point: x,y,z");
  import_linear->add_option("--name", import->options.name, "run name (default: the file name)")
      ->check(notEmpty("a name", "NAME"));
  import_linear->add_option("--machine", import->options.machine, "machine the data belongs to")
      ->capture_default_str()
      ->check(notEmpty("a name", "NAME"));
  auto* raw = import_linear->add_flag(
      "--raw", import->options.raw,
      "measured_mm are uncompensated laser readings: compensate them from the environment columns");
  // The compensation's settings mean nothing without --raw: given alone, they are refused.
  import_linear->add_option("--model", import->model, "air index equation with --raw: edlen | ciddor")
      ->capture_default_str()
      ->needs(raw);
  import_linear->add_option("--wavelength-nm", import->options.wavelength_nm, "vacuum wavelength with --raw")
      ->capture_default_str()
      ->needs(raw);
  import_linear->add_option("--co2-ppm", import->options.co2_ppm, "CO2 with --raw")->capture_default_str()->needs(raw);
  import_linear
      ->add_option("--expansion-per-k", import->options.expansion_per_k,
                   "expansion coefficient for the normalisation to 20 degC with --raw")
      ->capture_default_str()
      ->needs(raw);
  import_linear->add_option("--datum-mm", import->options.datum_mm, "machine position of the laser zero with --raw")
      ->capture_default_str()
      ->needs(raw);
  addCsvOptions(import_linear, import->csv);
  c.on(import_linear, [&c, import, reflector] {
    if (import->model != "edlen" && import->model != "ciddor") throw InputError("--model must be edlen or ciddor");
    import->options.model =
        import->model == "ciddor" ? processing::AirIndexModel::kCiddor : processing::AirIndexModel::kEdlen;
    import->options.line_position_mm = lineOf(import->line_position);
    if (reflector->count())
      import->options.reflector_offset_mm = xyzOption("--reflector-offset-mm", import->reflector_offset_mm);
    import->options.csv = import->csv.dialect();
    return importLinear(c.g, import->file, import->options);
  });

  struct ImportCampaign {
    std::string file;
    acquisition::CampaignImportOptions options;
    CsvOptions csv;
  };
  auto campaign = std::make_shared<ImportCampaign>();
  auto* import_campaign = c.import->add_subcommand(
      "campaign", "a campaign of linear runs (direct 21-error or 9-line) from a manifest (JSON or CSV) and its files");
  import_campaign->add_option("MANIFEST", campaign->file, "manifest: file, axis, measures, line, reflector, units")
      ->required();
  import_campaign->add_option("--name", campaign->options.name, "campaign name (default: the manifest's)")
      ->check(notEmpty("a name", "NAME"));
  import_campaign
      ->add_option("--machine", campaign->options.machine,
                   "machine the data belongs to (default: the manifest's, else imported)")
      ->check(notEmpty("a name", "NAME"));
  addCsvOptions(import_campaign, campaign->csv);
  c.on(import_campaign, [&c, campaign] {
    campaign->options.csv = campaign->csv.dialect();
    return importCampaign(c.g, campaign->file, campaign->options);
  });

  auto run_id = std::make_shared<storage::Id>(0);
  auto* analyze_iso = c.analyze->add_subcommand("iso230-2", "positioning accuracy and repeatability (ISO 230-2:2014)");
  analyze_iso->add_option("RUN", *run_id, "run id")->required();
  c.on(analyze_iso, [&c, run_id] { return analyzeIso230(c.g, *run_id); });

  struct Standard {
    storage::Id run = 0, before = 0, after = 0;
    std::string standard = "iso230-2:2014";
  };
  const std::string standards = fmt::format("the standard: {}", fmt::join(processing::positioningStandards(), ", "));
  auto standard = std::make_shared<Standard>();
  auto* analyze_linear =
      c.analyze->add_subcommand("linear", "a positioning run's figures under a standard (ISO 230-2, VDI 3441, ...)");
  analyze_linear->add_option("RUN", standard->run, "run id")->required();
  analyze_linear->add_option("--standard", standard->standard, standards)->capture_default_str();
  c.on(analyze_linear, [&c, standard] { return analyzeLinear(c.g, standard->run, standard->standard); });
  auto* compare = c.app->add_subcommand(
      "compare", "two positioning runs of an axis side by side (before and after compensation), under a standard");
  compare->add_option("RUN_BEFORE", standard->before, "the run before (e.g. the bare machine)")->required();
  compare->add_option("RUN_AFTER", standard->after, "the run after (e.g. the compensated machine)")->required();
  compare->add_option("--standard", standard->standard, standards)->capture_default_str();
  c.on(compare, [&c, standard] { return compareRuns(c.g, standard->before, standard->after, standard->standard); });

  struct Air {
    std::string model = "edlen";
    double temp_c = 20.0, pressure_pa = 101325.0, humidity_pct = 50.0, co2_ppm = 450.0, wavelength_nm = 632.991;
  };
  auto air = std::make_shared<Air>();
  auto* air_cmd = c.app->add_subcommand("air-index", "refractive index of air (modified Edlen or Ciddor)");
  air_cmd->add_option("--model", air->model, "edlen | ciddor")->capture_default_str();
  air_cmd->add_option("--temp-c", air->temp_c, "air temperature, degC")->required();
  air_cmd->add_option("--pressure-pa", air->pressure_pa, "air pressure, Pa")->required();
  air_cmd->add_option("--humidity-pct", air->humidity_pct, "relative humidity, %")->required();
  air_cmd->add_option("--co2-ppm", air->co2_ppm, "CO2 content, umol/mol")->capture_default_str();
  air_cmd->add_option("--wavelength-nm", air->wavelength_nm, "vacuum wavelength, nm")->capture_default_str();
  c.on(air_cmd, [&c, air] {
    return airIndex(c.g, air->model, air->temp_c, air->pressure_pa, air->humidity_pct, air->co2_ppm,
                    air->wavelength_nm);
  });

  struct Gcode {
    std::string plan_path, output_path, machine_file;
  };
  auto gcode = std::make_shared<Gcode>();
  auto* plan_cmd = c.app->add_subcommand("plan", "work with plan files")->require_subcommand(1);
  auto* plan_gcode = plan_cmd->add_subcommand("gcode", "write the CNC part program of a plan (dwells in seconds)");
  plan_gcode->add_option("PLAN", gcode->plan_path, "plan file (JSON)")->required();
  plan_gcode->add_option("-o,--output", gcode->output_path, "program file (default: stdout)")
      ->check(notEmpty("a file name", "FILE"));
  plan_gcode->add_option("--machine-config", gcode->machine_file, "machine description (gantry plans: its kinematics)");
  c.on(plan_gcode, [&c, gcode] { return planGcode(c.g, gcode->plan_path, gcode->output_path, gcode->machine_file); });
}

}  // namespace mtcal::app
