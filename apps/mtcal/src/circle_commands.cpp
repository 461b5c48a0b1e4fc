// Circular tests with a ballbar: run a plan on the simulated machine (mtcal run ballbar),
// import circle data (mtcal import circle), evaluate (mtcal analyze iso230-4) and diagnose
// (mtcal analyze ballbar) a stored test.

#include <fmt/format.h>

#include <cctype>
#include <nlohmann/json.hpp>

#include "cli_session.h"
#include "commands.h"
#include "mtcal/services/circle.h"

namespace mtcal::app {
namespace {

std::string shown(const std::optional<double>& v, const char* unit) {
  return v ? fmt::format("{:.3f} {}", *v, unit) : std::string("not detected");
}

// The plane's two axes, as the tables name them (XY -> X, Y).
std::pair<char, char> axisNames(processing::Plane plane) {
  const auto a = processing::planeAxes(plane);
  return {"XYZ"[a.first], "XYZ"[a.second]};
}

void printIso230_4(std::ostream& out, const services::Iso230_4Analysis& a) {
  const auto& s = a.setting;
  const auto [first, second] = axisNames(s.plane);
  out << fmt::format("ISO 230-4 circular test, run {}: {} plane, radius {} mm, feed {} mm/min\n\n", a.run_id,
                     processing::planeName(s.plane), s.radius_mm, s.feed_mm_per_min);
  out << "direction  points  span_deg    G_um  radius_dev_um  centre_um\n";
  for (const auto& [path, name] : {std::pair{&a.result.ccw, "ccw"}, std::pair{&a.result.cw, "cw"}}) {
    if (!*path) continue;
    const auto& p = **path;
    out << fmt::format("{:<9} {:>7} {:>9.1f} {:>7.2f} {:>14.2f}  {}={:.2f} {}={:.2f}\n", name, p.points,
                       p.angle_span_deg, p.g_um, services::roundedTo(p.radius_deviation_um, 2),
                       static_cast<char>(std::tolower(first)), services::roundedTo(p.centre_first_um, 2),
                       static_cast<char>(std::tolower(second)), services::roundedTo(p.centre_second_um, 2));
  }
  if (a.result.g_b_um) out << fmt::format("\nG(b) bidirectional circular deviation: {:.2f} um\n", *a.result.g_b_um);
  if (a.result.h_um) out << fmt::format("H bidirectional circular hysteresis:    {:.2f} um\n", *a.result.h_um);
}

void printBallbar(std::ostream& out, const services::BallbarAnalysis& a) {
  const auto& s = a.setting;
  const auto& d = a.diagnosis;
  const auto [F1, F2] = axisNames(s.plane);
  out << fmt::format("Ballbar diagnosis, run {}: {} plane, radius {} mm, feed {} mm/min\n\n", a.run_id,
                     processing::planeName(s.plane), s.radius_mm, s.feed_mm_per_min);
  out << fmt::format("  squareness                {}\n", shown(d.squareness_urad, "urad"));
  out << fmt::format("  servo mismatch            {}\n", shown(d.servo_mismatch_ms, "ms"));
  out << fmt::format("  scale mismatch {}          {}\n", F1, shown(d.scale_mismatch_first_ppm, "ppm"));
  out << fmt::format("  scale mismatch {}          {}\n", F2, shown(d.scale_mismatch_second_ppm, "ppm"));
  out << fmt::format("  backlash {}                {}\n", F1, shown(d.backlash_first_um, "um"));
  out << fmt::format("  backlash {}                {}\n", F2, shown(d.backlash_second_um, "um"));
  out << fmt::format("  reversal spike {}          {}\n", F1, shown(d.reversal_spike_first_um, "um"));
  out << fmt::format("  reversal spike {}          {}\n", F2, shown(d.reversal_spike_second_um, "um"));
  out << fmt::format("  straightness {}            {}\n", F1, shown(d.straightness_first_um, "um"));
  out << fmt::format("  straightness {}            {}\n", F2, shown(d.straightness_second_um, "um"));
  if (d.cyclic_amplitude_um) {
    out << fmt::format("  cyclic error              {:.3f} um, period {:.2f} mm, axis {}\n", *d.cyclic_amplitude_um,
                       *d.cyclic_period_mm, d.cyclic_axis == 0 ? F1 : F2);
  } else {
    out << "  cyclic error              not detected\n";
  }
  out << fmt::format("\nradial deviation about the LSQ circles: RMS {:.3f} um; left by the signatures: {:.3f} um\n",
                     d.rms_before_um, d.rms_after_um);
  for (const auto& n : d.notes) out << "note: " << n << "\n";
}

int importCircle(const Globals& g, const std::string& path, acquisition::CircleImportOptions options) {
  CliSession cli(g);
  const auto imported = services::importCircle(cli.session, path, std::move(options));
  if (!jsonPrinted(g, imported.document())) {
    *g.out << fmt::format("imported run {}: {} circle points\n", imported.run_id, imported.points);
  }
  return 0;
}

int analyzeIso230_4(const Globals& g, storage::Id run_id) {
  CliSession cli(g);
  const auto a = services::analyzeIso230_4(cli.session, run_id);
  if (g.json) {
    *g.out << a.document().dump() << "\n";
  } else {
    printIso230_4(*g.out, a);
  }
  return 0;
}

int analyzeBallbar(const Globals& g, storage::Id run_id) {
  CliSession cli(g);
  const auto a = services::analyzeBallbar(cli.session, run_id);
  if (g.json) {
    *g.out << a.document().dump() << "\n";
  } else {
    printBallbar(*g.out, a);
  }
  return 0;
}

int runBallbar(const Globals& g, const std::string& plan_path, const std::string& device_uri,
               const SimulationOptions& sim_options, bool triggered, const std::string& machine) {
  services::CircleRunRequest request;
  request.plan = acquisition::CirclePlan::fromJson(services::readJsonFile(plan_path), plan_path);
  request.device_uri = device_uri;
  request.simulation = sim_options;
  request.triggered = triggered;
  request.plan_path = plan_path;
  request.machine = machine;
  CliSession cli(g);
  const auto r = services::runCircle(cli.session, request);
  cli.observer.finish();
  return printCircleRun(g, r);
}

}  // namespace

int printCircleRun(const Globals& g, const services::CircleRunResult& r) {
  if (r.status != "completed") {
    if (!jsonPrinted(g, r.document()))
      *g.out << fmt::format(
          "run {} interrupted: {}; the completed directions are stored; continue it with: mtcal "
          "resume {}\n",
          r.run_id, r.reason, r.run_id);
    return 1;
  }
  if (jsonPrinted(g, r.document())) return 0;
  *g.out << fmt::format("run {}: {} points, {} samples streamed{}, {} lost\n\n", r.run_id, r.points, r.samples,
                        r.resumed ? " since it resumed" : "", r.lost_samples);
  printIso230_4(*g.out, *r.iso230_4);
  *g.out << "\n";
  printBallbar(*g.out, *r.ballbar);
  return 0;
}

void registerCircleCommands(CliContext& c) {
  struct Run {
    std::string plan_path, device_uri = "mock://ballbar", machine = "real";
    bool triggered = false;
  };
  auto run = std::make_shared<Run>();
  auto* run_ballbar = c.run->add_subcommand("ballbar", "circular test plan (ISO 230-4) with a ballbar");
  run_ballbar->add_option("PLAN", run->plan_path, "plan file (JSON, type circle)")->required();
  run_ballbar->add_option("--device", run->device_uri, "ballbar URI")->capture_default_str();
  run_ballbar->add_flag("--triggered", run->triggered,
                        "the virtual CNC runs the plan's part program and each direction is found by its feed-in and "
                        "feed-out, as with a real machine (a real device always is)");
  run_ballbar->add_option("--machine", run->machine, "a real machine's name (a real device)")
      ->capture_default_str()
      ->check(notEmpty("a name", "NAME"));
  addSimulationOptions(run_ballbar, c, "virtual machine description for mock:// devices");
  c.on(
      run_ballbar,
      [&c, run] { return runBallbar(c.g, run->plan_path, run->device_uri, c.sim, run->triggered, run->machine); },
      OnSignal::kStopAndWait);

  struct Import {
    std::string file, plane = "XY";
    std::string centre_mm;
    acquisition::CircleImportOptions options;
    CsvOptions csv;
  };
  auto import = std::make_shared<Import>();
  auto* import_circle =
      c.import->add_subcommand("circle", "circular test (ballbar) data: angle_deg,direction,deviation_um (CSV)");
  import_circle->add_option("FILE", import->file, "CSV file")->required();
  import_circle->add_option("--radius-mm", import->options.radius_mm, "nominal radius (the bar's length)")
      ->required()
      ->check(positive());
  import_circle
      ->add_option("--plane", import->plane,
                   "XY, YZ or ZX (ZX, not XZ: the order fixes which way is counter-clockwise)")
      ->capture_default_str();
  import_circle
      ->add_option("--feed-mm-min", import->options.feed_mm_per_min,
                   "feed of the test (the servo mismatch in ms scales with its inverse; default 1000, with a warning)")
      ->check(positive());
  const auto* centre =
      addXyzOption(import_circle, "--centre-mm", import->centre_mm,
                   "machine coordinates of the table ball, X,Y,Z (lets diagnose --against a model predict the circle)");
  import_circle->add_option("--name", import->options.name, "run name (default: the file name)")
      ->check(notEmpty("a name", "NAME"));
  import_circle->add_option("--machine", import->options.machine, "machine the data belongs to")
      ->capture_default_str()
      ->check(notEmpty("a name", "NAME"));
  addCsvOptions(import_circle, import->csv);
  c.on(import_circle, [&c, import, centre] {
    import->options.plane = processing::parsePlane(import->plane);
    if (centre->count()) {
      const auto xyz = xyzOption("--centre-mm", import->centre_mm);
      import->options.centre_mm = Eigen::Vector3d(xyz[0], xyz[1], xyz[2]);
    }
    import->options.csv = import->csv.dialect();
    return importCircle(c.g, import->file, import->options);
  });

  auto run_id = std::make_shared<storage::Id>(0);
  auto* analyze_iso4 = c.analyze->add_subcommand("iso230-4", "circular test: G, G(b), H, centre, radius (ISO 230-4)");
  analyze_iso4->add_option("RUN", *run_id, "run id")->required();
  c.on(analyze_iso4, [&c, run_id] { return analyzeIso230_4(c.g, *run_id); });
  auto* analyze_ballbar = c.analyze->add_subcommand("ballbar", "circular test: diagnosis of the machine's errors");
  analyze_ballbar->add_option("RUN", *run_id, "run id")->required();
  c.on(analyze_ballbar, [&c, run_id] { return analyzeBallbar(c.g, *run_id); });
}

}  // namespace mtcal::app
