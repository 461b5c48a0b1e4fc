#include "mtcal/app/cli.h"

#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include "commands.h"
#include "mtcal/services/logging.h"
#include "mtcal/services/version.h"
#include "mtcal/error.h"

namespace mtcal::app {

int runCli(const std::vector<std::string>& args, std::ostream& out, std::ostream& err, const std::atomic<bool>* stop,
           std::istream* in) {
  Globals g;
  g.out = &out;
  g.err = &err;
  g.in = in;
  g.stop = stop;
  g.terminal = &err == &std::cerr && isatty(STDERR_FILENO);

  CLI::App app{"mtcal: open calibration of machine tools (laser interferometer, ballbar, probes, laser tracker)"};
  app.set_version_flag("--version", std::string("mtcal ") + kVersion);
  app.require_subcommand(1);
  app.fallthrough();
  app.add_option("--db", g.db, "SQLite database file")->capture_default_str();
  app.add_flag("--json", g.json, "print one JSON object on stdout");
  std::string log_level = "warn";
  app.add_option("--log-level", log_level, "diagnostics on stderr: off, error, warn, info, debug")
      ->capture_default_str()
      ->check(CLI::IsMember({"off", "error", "warn", "info", "debug"}));

  SimulationOptions sim;
  auto add_sim = [&sim](CLI::App* cmd) {
    cmd->add_option("--seed", sim.seed, "seed of the simulated machine and instrument")->capture_default_str();
    cmd->add_option("--time-scale", sim.time_scale, "simulated seconds per wall-clock second")
        ->capture_default_str()
        ->check(CLI::PositiveNumber);
  };

  auto* demo_cmd = app.add_subcommand("demo", "run a complete simulated X-axis calibration (ISO 230-2) and print it");
  add_sim(demo_cmd);

  auto* runs_cmd = app.add_subcommand("runs", "list the runs in the database");

  storage::Id run_id = 0;
  auto* show_cmd = app.add_subcommand("show", "show one run: metadata, plan, events");
  show_cmd->add_option("RUN", run_id, "run id")->required();

  auto* import_cmd = app.add_subcommand("import", "import measurements exported by other software");
  import_cmd->require_subcommand(1);
  auto* import_linear = import_cmd->add_subcommand("linear", "linear positioning data (CSV)");
  std::string file;
  acquisition::LinearImportOptions import_options;
  std::string import_model = "edlen";
  import_linear->add_option("FILE", file, "CSV file")->required();
  import_linear->add_option("--axis", import_options.axis, "axis measured (X, Y, Z)")->capture_default_str();
  import_linear->add_option("--name", import_options.name, "run name (default: the file name)");
  import_linear->add_option("--machine", import_options.machine, "machine the data belongs to")->capture_default_str();
  import_linear->add_flag("--raw", import_options.raw,
                          "measured_mm are uncompensated laser readings: compensate them from the environment columns");
  import_linear->add_option("--model", import_model, "air index equation with --raw: edlen | ciddor")->capture_default_str();
  import_linear->add_option("--wavelength-nm", import_options.wavelength_nm, "vacuum wavelength with --raw")
      ->capture_default_str();
  import_linear->add_option("--co2-ppm", import_options.co2_ppm, "CO2 with --raw")->capture_default_str();
  import_linear->add_option("--expansion-per-k", import_options.expansion_per_k,
                            "expansion coefficient for the normalisation to 20 degC with --raw")
      ->capture_default_str();
  import_linear->add_option("--datum-mm", import_options.datum_mm, "machine position of the laser zero with --raw")
      ->capture_default_str();

  auto* import_circle = import_cmd->add_subcommand("circle", "circular test (ballbar) data: angle_deg,direction,deviation_um (CSV)");
  acquisition::CircleImportOptions circle_options;
  std::string circle_plane = "XY";
  import_circle->add_option("FILE", file, "CSV file")->required();
  import_circle->add_option("--radius-mm", circle_options.radius_mm, "nominal radius (the bar's length)")
      ->required()
      ->check(CLI::PositiveNumber);
  import_circle->add_option("--plane", circle_plane, "XY, YZ or ZX")->capture_default_str();
  import_circle->add_option("--feed-mm-min", circle_options.feed_mm_per_min, "feed of the test")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  import_circle->add_option("--name", circle_options.name, "run name (default: the file name)");
  import_circle->add_option("--machine", circle_options.machine, "machine the data belongs to")->capture_default_str();

  auto* import_thermal = import_cmd->add_subcommand(
      "thermal", "thermal monitoring data (CSV): time_s, displacement columns (_um), temperatures (degC); empty cells missing");
  acquisition::ThermalImportOptions thermal_import;
  import_thermal->add_option("FILE", file, "CSV file")->required();
  import_thermal->add_option("--interval-s", thermal_import.interval_s, "seconds between rows when there is no time_s column")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  import_thermal->add_option("--target", thermal_import.target, "the displacement column (um), when its name does not end in _um");
  import_thermal->add_option("--name", thermal_import.name, "run name (default: the file name)");
  import_thermal->add_option("--machine", thermal_import.machine, "machine the data belongs to")->capture_default_str();

  auto* thermal_cmd = app.add_subcommand("thermal", "thermal error: time-series model of the drift from temperatures");
  thermal_cmd->require_subcommand(1);
  auto* thermal_export = thermal_cmd->add_subcommand("export", "write a thermal run as CSV (the format import thermal reads)");
  std::string thermal_csv;
  thermal_export->add_option("RUN", run_id, "run id")->required();
  thermal_export->add_option("FILE", thermal_csv, "CSV file to write (- for stdout)")->required();
  auto* thermal_fit = thermal_cmd->add_subcommand("fit", "fit, select sensors (grey relational + stepwise) and validate on later data");
  ThermalFitCommandOptions thermal_fit_options;
  thermal_fit->add_option("RUN", run_id, "run id (a thermal run)")->required();
  thermal_fit->add_option("--target", thermal_fit_options.target, "displacement channel to model (um)")->required();
  thermal_fit->add_option("--train-fraction", thermal_fit_options.train_fraction, "first part of the rows that fits; the rest tests")
      ->capture_default_str()
      ->check(CLI::Range(0.05, 0.95));
  thermal_fit->add_option("--max-sensors", thermal_fit_options.max_sensors, "largest model tried")
      ->capture_default_str()
      ->check(CLI::Range(1, 32));
  thermal_fit->add_option("--normalisation", thermal_fit_options.normalisation, "grey relational normalisation: range, initial, mean")
      ->capture_default_str()
      ->check(CLI::IsMember({"range", "initial", "mean"}));
  thermal_fit->add_option("--rho", thermal_fit_options.rho, "grey resolution coefficient")->capture_default_str()->check(CLI::Range(0.01, 1.0));
  thermal_fit->add_flag("--with-speed", thermal_fit_options.with_speed, "the spindle speed (rpm channels) is an input too");
  thermal_fit->add_option("--accuracy-um", thermal_fit_options.accuracy_um, "report the fewest sensors reaching this test RMS");
  thermal_fit->add_option("--predictions", thermal_fit_options.predictions_path, "write the model's predictions (CSV)");

  auto* analyze_cmd = app.add_subcommand("analyze", "evaluate a stored run");
  analyze_cmd->require_subcommand(1);
  auto* analyze_iso = analyze_cmd->add_subcommand("iso230-2", "positioning accuracy and repeatability (ISO 230-2:2014)");
  analyze_iso->add_option("RUN", run_id, "run id")->required();
  auto* analyze_iso4 = analyze_cmd->add_subcommand("iso230-4", "circular test: G, G(b), H, centre, radius (ISO 230-4)");
  analyze_iso4->add_option("RUN", run_id, "run id")->required();
  auto* analyze_ballbar = analyze_cmd->add_subcommand("ballbar", "circular test: diagnosis of the machine's errors");
  analyze_ballbar->add_option("RUN", run_id, "run id")->required();
  EstOptions analyze_est_options;
  auto* analyze_gantry = analyze_cmd->add_subcommand("gantry", "gantry point accuracy: dP per hole, summaries, uncertainty");
  analyze_gantry->add_option("RUN", run_id, "run id")->required();
  auto* analyze_est = analyze_cmd->add_subcommand("est", "guideway straightness of a probe stepping run");
  analyze_est->add_option("RUN", run_id, "run id")->required();
  analyze_est->add_option("--method", analyze_est_options.method, "two-probe, three-probe or frequency")
      ->capture_default_str()
      ->check(CLI::IsMember({"two-probe", "three-probe", "frequency"}));
  analyze_est->add_option("--start", analyze_est_options.start, "two-probe: carriage-at-rest or second-point")
      ->capture_default_str()
      ->check(CLI::IsMember({"carriage-at-rest", "second-point"}));

  auto* air_cmd = app.add_subcommand("air-index", "refractive index of air (modified Edlen or Ciddor)");
  std::string air_model = "edlen";
  double temp_c = 20.0, pressure_pa = 101325.0, humidity_pct = 50.0, co2_ppm = 450.0, wavelength_nm = 632.991;
  air_cmd->add_option("--model", air_model, "edlen | ciddor")->capture_default_str();
  air_cmd->add_option("--temp-c", temp_c, "air temperature, degC")->required();
  air_cmd->add_option("--pressure-pa", pressure_pa, "air pressure, Pa")->required();
  air_cmd->add_option("--humidity-pct", humidity_pct, "relative humidity, %")->required();
  air_cmd->add_option("--co2-ppm", co2_ppm, "CO2 content, umol/mol")->capture_default_str();
  air_cmd->add_option("--wavelength-nm", wavelength_nm, "vacuum wavelength, nm")->capture_default_str();

  auto* run_cmd = app.add_subcommand("run", "run a measurement plan");
  run_cmd->require_subcommand(1);
  std::string est_plan_path, est_device_uri = "mock://probes";
  auto* run_est = run_cmd->add_subcommand("est", "probe stepping plan: guideway straightness by error separation");
  run_est->add_option("PLAN", est_plan_path, "plan file (JSON, type est)")->required();
  run_est->add_option("--device", est_device_uri, "probe box URI")->capture_default_str();
  run_est->add_option("--machine-config", sim.machine_file, "virtual machine description for mock:// devices");
  add_sim(run_est);
  auto* run_thermal = run_cmd->add_subcommand("thermal", "thermal monitoring plan: temperatures and drift for hours, spindle program");
  ThermalRunCommandOptions thermal_run;
  run_thermal->add_option("PLAN", thermal_run.plan_path, "plan file (JSON, type thermal)");
  run_thermal->add_option("--resume", thermal_run.resume_run, "continue an interrupted thermal run (its own plan)");
  run_thermal->add_option("--logger", thermal_run.logger_uri, "temperature logger URI")->capture_default_str();
  run_thermal->add_option("--probes", thermal_run.probes_uri, "probe box URI (the displacement)")->capture_default_str();
  run_thermal->add_option("--interferometer", thermal_run.interferometer_uri, "interferometer URI (displacement or environment)")
      ->capture_default_str();
  run_thermal->add_option("--machine-config", sim.machine_file, "virtual machine description with a thermal object");
  run_thermal->add_option("--machine", thermal_run.machine, "real instruments: the machine measured")->capture_default_str();
  add_sim(run_thermal);
  auto* run_ballbar = run_cmd->add_subcommand("ballbar", "circular test plan (ISO 230-4) with a ballbar");
  std::string ballbar_plan_path, ballbar_uri = "mock://ballbar";
  run_ballbar->add_option("PLAN", ballbar_plan_path, "plan file (JSON, type circle)")->required();
  run_ballbar->add_option("--device", ballbar_uri, "ballbar URI")->capture_default_str();
  run_ballbar->add_option("--machine-config", sim.machine_file, "virtual machine description for mock:// devices");
  add_sim(run_ballbar);
  GantryEvaluateOptions gantry_eval;
  auto add_gantry_eval = [&gantry_eval](CLI::App* cmd) {
    cmd->add_option("--tcp0", gantry_eval.tcp0, "TCP0 from the A/C axes (the patent) or from the tool-point nest")
        ->capture_default_str()
        ->check(CLI::IsMember({"axes", "tool-point"}));
    cmd->add_option("--fit", gantry_eval.fit, "target motion: patent (three-point frame), lsq (Umeyama) or auto")
        ->capture_default_str()
        ->check(CLI::IsMember({"auto", "patent", "lsq"}));
    cmd->add_option("--trials", gantry_eval.trials, "Monte Carlo trials of the tracker's MPE (0: none; default: the plan's)");
    cmd->add_option("--mc-seed", gantry_eval.seed, "seed of the Monte Carlo")->capture_default_str();
  };
  std::string gantry_plan_path, gantry_uri = "mock://tracker";
  auto add_gantry_run = [&](CLI::App* cmd) {
    cmd->add_option("PLAN", gantry_plan_path, "plan file (JSON, type gantry)")->required();
    cmd->add_option("--device", gantry_uri, "tracker URI")->capture_default_str();
    cmd->add_option("--machine-config", sim.machine_file, "virtual gantry machine (examples/machines/gantry-drilling.json)");
    add_sim(cmd);
    add_gantry_eval(cmd);
  };
  auto* run_gantry = run_cmd->add_subcommand("gantry", "gantry point accuracy plan (patent CN106017326) with a laser tracker");
  add_gantry_run(run_gantry);
  auto* run_linear = run_cmd->add_subcommand("linear", "linear positioning plan (ISO 230-2 test cycle)");
  std::string plan_path, device_uri = "mock://interferometer";
  std::vector<std::string> plan_paths;
  run_linear->add_option("PLAN", plan_paths, "plan file(s) (JSON); several run as one campaign (simulation only)")
      ->required();
  run_linear->add_option("--device", device_uri, "interferometer URI")->capture_default_str();
  run_linear->add_option("--machine-config", sim.machine_file, "virtual machine description for mock:// devices");
  RunOptions run_options;
  run_linear->add_flag("--triggered", run_options.triggered,
                       "mock:// devices: the virtual CNC runs the part program and targets are captured when the "
                       "machine holds them (the workflow of a real machine)");
  run_linear->add_option("--machine", run_options.machine, "real devices: name of the machine measured")
      ->capture_default_str();
  add_sim(run_linear);

  auto* resume_cmd = app.add_subcommand("resume", "continue an interrupted run");
  resume_cmd->add_option("RUN", run_id, "run id")->required();
  resume_cmd->add_option("--time-scale", sim.time_scale, "simulated seconds per wall-clock second")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);

  auto* plan_cmd = app.add_subcommand("plan", "work with plan files");
  plan_cmd->require_subcommand(1);
  auto* plan_gcode = plan_cmd->add_subcommand("gcode", "write the CNC part program of a plan");
  std::string output_path;
  plan_gcode->add_option("PLAN", plan_path, "plan file (JSON)")->required();
  plan_gcode->add_option("-o,--output", output_path, "program file (default: stdout)");
  std::string gcode_machine;
  plan_gcode->add_option("--machine-config", gcode_machine, "machine description (gantry plans: its kinematics)");

  auto* devices_cmd = app.add_subcommand("devices", "list the instruments the drivers can find");

  auto* model_cmd = app.add_subcommand("model", "geometric error models: import, predict, key errors, bands");
  model_cmd->require_subcommand(1);
  storage::Id model_id = 0;
  ModelImportOptions model_import;
  auto* model_import_cmd = model_cmd->add_subcommand("import", "a model from error curves measured elsewhere (CSV)");
  model_import_cmd->add_option("FILE", model_import.csv_path, "CSV: error,position_mm,value[,s,n]")->required();
  model_import_cmd->add_option("--machine", model_import.machine_path, "kinematic description (JSON)")->required();
  model_import_cmd->add_option("--name", model_import.name, "model name (default: the file name)");
  model_import_cmd->add_option("--knot-spacing-mm", model_import.min_knot_spacing_mm, "smallest B-spline knot spacing")
      ->capture_default_str();
  std::vector<std::string> identify_sources;
  auto* model_identify_cmd = model_cmd->add_subcommand("identify", "a model from stored measurement runs");
  model_identify_cmd->add_option("RUN", identify_sources, "run ids, or cN for every completed linear run of campaign N")
      ->required();
  model_identify_cmd->add_option("--machine", model_import.machine_path, "kinematic description (JSON)")->required();
  model_identify_cmd
      ->add_option("--method", model_import.method,
                   "direct (each error from the runs that measure it) or 9-line (three displacement lines per axis)")
      ->capture_default_str()
      ->check(CLI::IsMember({"direct", "9-line"}));
  model_identify_cmd->add_option("--max-condition", model_import.max_condition_number,
                                 "refuse line layouts whose condition number exceeds this")
      ->capture_default_str();
  model_identify_cmd->add_option("--name", model_import.name, "model name");
  model_identify_cmd->add_option("--knot-spacing-mm", model_import.min_knot_spacing_mm, "smallest B-spline knot spacing")
      ->capture_default_str();
  auto* model_list_cmd = model_cmd->add_subcommand("list", "list the stored models");
  std::string grid, points_csv, out_csv, at;
  auto* model_predict_cmd = model_cmd->add_subcommand("predict", "volumetric error at a grid or at points");
  model_predict_cmd->add_option("MODEL", model_id, "model id")->required();
  model_predict_cmd->add_option("--grid", grid, "X0:X1:N,Y0:Y1:N,Z0:Z1:N");
  model_predict_cmd->add_option("--points", points_csv, "CSV with x_mm,y_mm,z_mm");
  model_predict_cmd->add_option("-o,--out", out_csv, "write the CSV here instead of stdout");
  int sobol_samples = 0;
  auto* model_keys_cmd = model_cmd->add_subcommand("key-errors", "share of each error term in the spatial error");
  model_keys_cmd->add_option("MODEL", model_id, "model id")->required();
  model_keys_cmd->add_option("--at", at, "x,y,z (default: the centre of the measured ranges)");
  model_keys_cmd->add_option("--sobol", sobol_samples, "also Monte Carlo Sobol indices with this many samples");
  std::string plane = "XY";
  int band_grid = 5;
  auto* model_bands_cmd = model_cmd->add_subcommand("bands", "error band of the plane random process on a plane");
  model_bands_cmd->add_option("MODEL", model_id, "model id")->required();
  model_bands_cmd->add_option("--plane", plane, "XY, YZ or XZ")->capture_default_str();
  model_bands_cmd->add_option("--at", at, "x,y,z fixing the third coordinate (default: the centre)");
  model_bands_cmd->add_option("--grid", band_grid, "points per side of the plane")->capture_default_str();
  std::vector<storage::Id> validate_runs;
  auto* model_validate_cmd =
      model_cmd->add_subcommand("validate", "compare a model with runs it was not built from (residual RMS and peak)");
  model_validate_cmd->add_option("MODEL", model_id, "model id")->required();
  model_validate_cmd->add_option("RUN", validate_runs, "run ids, e.g. random points every ~3 mm")->required();

  CompensationOptions compensation;
  auto* model_compensation_cmd =
      model_cmd->add_subcommand("compensation", "pitch compensation table of an axis (with the model's extensions), per direction");
  model_compensation_cmd->add_option("MODEL", model_id, "model id")->required();
  model_compensation_cmd->add_option("--axis", compensation.axis, "X, Y or Z")->capture_default_str();
  model_compensation_cmd->add_option("--from-mm", compensation.from_mm, "first position (default: the measured range's)");
  model_compensation_cmd->add_option("--to-mm", compensation.to_mm, "last position (default: the measured range's)");
  model_compensation_cmd->add_option("--step-mm", compensation.step_mm, "spacing of the table")->capture_default_str()->check(CLI::PositiveNumber);
  model_compensation_cmd->add_option("--at", compensation.at, "x,y,z of the other axes (default: the centre)");
  model_compensation_cmd->add_option("-o,--out", compensation.output_path, "write the CSV here instead of stdout");

  EstOptions est_options;
  auto* est_cmd = app.add_subcommand("est", "guideway straightness by error separation from probe readings (CSV)");
  est_cmd->add_option("FILE", est_options.csv_path, "CSV: x_mm,v1_um,v2_um[,v3_um]")->required();
  est_cmd->add_option("--spacing-mm", est_options.spacing_mm, "probe spacing (a whole number of steps)")->required();
  est_cmd->add_option("--method", est_options.method, "two-probe, three-probe or frequency")
      ->capture_default_str()
      ->check(CLI::IsMember({"two-probe", "three-probe", "frequency"}));
  est_cmd->add_option("--start", est_options.start, "two-probe initial condition: carriage-at-rest or second-point")
      ->capture_default_str()
      ->check(CLI::IsMember({"carriage-at-rest", "second-point"}));

  auto* gantry_cmd = app.add_subcommand("gantry", "gantry point accuracy with a laser tracker (patent CN106017326)");
  gantry_cmd->require_subcommand(1);
  auto* gantry_run = gantry_cmd->add_subcommand("run", "same as `run gantry`");
  add_gantry_run(gantry_run);
  auto* gantry_evaluate = gantry_cmd->add_subcommand("evaluate", "evaluate exported tracker measurements (docs/gantry.md)");
  std::string gantry_file;
  gantry_evaluate->add_option("FILE", gantry_file, "measurement file (JSON)")->required();
  add_gantry_eval(gantry_evaluate);
  auto* gantry_export = gantry_cmd->add_subcommand("export", "write a stored run's measurements as a measurement file");
  gantry_export->add_option("RUN", run_id, "run id")->required();
  gantry_export->add_option("FILE", gantry_file, "measurement file (JSON) to write")->required();
  add_gantry_eval(analyze_gantry);
  auto* grind_cmd = app.add_subcommand("grind", "cam grinding on an X + C grinder");
  grind_cmd->require_subcommand(1);
  auto* grind_compensate = grind_cmd->add_subcommand("compensate", "corrected X/C commands for a cam profile and a model");
  GrindOptions grind;
  grind_compensate->add_option("PROFILE", grind.profile_path, "cam profile CSV: x_mm,y_mm or angle_deg,radius_mm")->required();
  grind_compensate->add_option("--model", grind.model_id, "stored error model of the grinder (mtcal model list)")->required();
  grind_compensate->add_option("--wheel-radius-mm", grind.wheel_radius_mm, "grinding wheel radius")
      ->required()
      ->check(CLI::PositiveNumber);
  grind_compensate->add_option("--points", grind.points, "wheel-centre points along the profile")
      ->capture_default_str()
      ->check(CLI::Range(4, 1000000));
  grind_compensate->add_option("--resolution-um", grind.resolution_x_um, "X slide resolution")->capture_default_str();
  grind_compensate->add_option("--resolution-deg", grind.resolution_c_deg, "C axis resolution")->capture_default_str();
  grind_compensate->add_option("-o,--output", grind.output_path, "command list CSV (default: stdout)");
  grind_compensate->add_option("--gcode", grind.gcode_path, "write the part program here");
  grind_compensate->add_option("--c-rpm", grind.c_rpm, "work head speed for the program's feed")->capture_default_str();

  auto* grind_identify = grind_cmd->add_subcommand("identify", "one axis' motion errors from ballbar length changes");
  std::string grind_readings, grind_machine, grind_layout;
  grind_identify->add_option("READINGS", grind_readings, "CSV: position,pair,delta_length_um")->required();
  grind_identify->add_option("--machine", grind_machine, "kinematic description (examples/machines/*.model.json)")->required();
  grind_identify->add_option("--layout", grind_layout, "ball placements (JSON: coordinate, pairs)")->required();

  DiagnoseOptions diagnose_options;
  auto* diagnose_cmd = app.add_subcommand(
      "diagnose", "what the model gets wrong in a run: residual, evidence, named causes, model extension, held-out gain");
  diagnose_cmd->add_option("RUN", diagnose_options.run_id, "run id (linear, circle, thermal or est)");
  diagnose_cmd->add_option("--against", diagnose_options.against, "model predicting the run (linear runs); a new model version stores the findings");
  diagnose_cmd->add_option("--report", diagnose_options.report_dir, "folder for the residual plots (SVG)");
  diagnose_cmd->add_option("--target", diagnose_options.thermal_target, "thermal runs: the displacement channel (default: the first)");
  diagnose_cmd->add_option("--est", diagnose_options.est_csv, "EST data from a file: x_mm,v1_um,v2_um,v3_um (three probes)");
  diagnose_cmd->add_option("--spacing-mm", diagnose_options.spacing_mm, "with --est: the probe spacing (= the step)");
  diagnose_cmd->add_option("--alpha", diagnose_options.alpha, "family-wise chance of a finding on effect-free data")
      ->capture_default_str()
      ->check(CLI::Range(1e-6, 0.5));
  diagnose_cmd->add_option("--max-findings", diagnose_options.max_findings, "most causes named")
      ->capture_default_str()
      ->check(CLI::Range(1, 10));
  diagnose_cmd->add_option("--validate", diagnose_options.validate_runs,
                           "other runs of the same kind (other positions or times): the findings applied with their coefficients fixed");
  diagnose_cmd->add_option("--knot-spacing-mm", diagnose_options.knot_spacing_mm, "the run's own baseline: smallest knot spacing")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);

  std::vector<std::string> reversed(args.rbegin(), args.rend());
  try {
    app.parse(reversed);
  } catch (const CLI::ParseError& e) {
    if (e.get_exit_code() == 0) {
      out << (e.get_name() == "CallForVersion" ? std::string("mtcal ") + kVersion + "\n" : app.help());
      return 0;
    }
    err << "mtcal: " << e.what() << "\n";
    return 2;
  }

  services::logToStderr(log_level);
  try {
    if (*demo_cmd) return demo(g, sim);
    if (*runs_cmd) return listRuns(g);
    if (*show_cmd) return showRun(g, run_id);
    if (*import_linear) {
      if (import_model != "edlen" && import_model != "ciddor") throw InputError("--model must be edlen or ciddor");
      import_options.model =
          import_model == "ciddor" ? processing::AirIndexModel::kCiddor : processing::AirIndexModel::kEdlen;
      return importLinear(g, file, import_options);
    }
    if (*import_circle) {
      circle_options.plane = processing::parsePlane(circle_plane);
      return importCircle(g, file, circle_options);
    }
    if (*run_thermal) {
      if (thermal_run.plan_path.empty() == (thermal_run.resume_run == 0)) throw InputError("run thermal: give a PLAN or --resume RUN");
      return runThermal(g, thermal_run, sim);
    }
    if (*import_thermal) return importThermal(g, file, thermal_import);
    if (*thermal_export) return exportThermal(g, run_id, thermal_csv);
    if (*thermal_fit) return thermalFit(g, run_id, thermal_fit_options);
    if (*analyze_iso) return analyzeIso230(g, run_id);
    if (*analyze_iso4) return analyzeIso230_4(g, run_id);
    if (*analyze_ballbar) return analyzeBallbar(g, run_id);
    if (*run_ballbar) return runBallbar(g, ballbar_plan_path, ballbar_uri, sim);
    if (*analyze_est) return analyzeEst(g, run_id, analyze_est_options);
    if (*run_est) return runEst(g, est_plan_path, est_device_uri, sim);
    if (*air_cmd) return airIndex(g, air_model, temp_c, pressure_pa, humidity_pct, co2_ppm, wavelength_nm);
    if (*run_linear) return runLinear(g, plan_paths, device_uri, sim, run_options);
    if (*resume_cmd) return resumeRun(g, run_id, sim.time_scale);
    if (*plan_gcode) return planGcode(g, plan_path, output_path, gcode_machine);
    if (*run_gantry || *gantry_run) return runGantry(g, gantry_plan_path, gantry_uri, sim, gantry_eval);
    if (*analyze_gantry) return analyzeGantry(g, run_id, gantry_eval);
    if (*gantry_evaluate) return gantryEvaluate(g, gantry_file, gantry_eval);
    if (*gantry_export) return gantryExport(g, run_id, gantry_file);
    if (*devices_cmd) return listDevices(g, sim);
    if (*model_import_cmd) return modelImport(g, model_import);
    if (*model_identify_cmd) return modelIdentify(g, identify_sources, model_import);
    if (*model_list_cmd) return modelList(g);
    if (*model_predict_cmd) return modelPredict(g, model_id, grid, points_csv, out_csv);
    if (*model_keys_cmd) return modelKeyErrors(g, model_id, at, sobol_samples);
    if (*model_bands_cmd) return modelBands(g, model_id, plane, at, band_grid);
    if (*model_validate_cmd) return modelValidate(g, model_id, validate_runs);
    if (*model_compensation_cmd) return modelCompensation(g, model_id, compensation);
    if (*est_cmd) return estimateStraightness(g, est_options);
    if (*diagnose_cmd) return diagnoseCommand(g, diagnose_options);
    if (*grind_compensate) return grindCompensate(g, grind);
    if (*grind_identify) return grindIdentify(g, grind_readings, grind_machine, grind_layout);
  } catch (const InputError& e) {
    err << "mtcal: error: " << e.what() << "\n";
    return 2;
  } catch (const Error& e) {
    err << "mtcal: error: " << e.what() << "\n";
    return 1;
  } catch (const std::exception& e) {
    err << "mtcal: internal error: " << e.what() << "\n";
    return 1;
  }
  err << "mtcal: no command given\n";
  return 2;
}

}  // namespace mtcal::app
