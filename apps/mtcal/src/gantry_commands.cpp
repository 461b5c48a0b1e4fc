// mtcal run gantry / analyze gantry / gantry evaluate / gantry export: point accuracy of a
// gantry drilling machine with a laser tracker (patent CN106017326, docs/gantry.md), rendered
// for people or as JSON.

#include <fmt/format.h>

#include <limits>

#include "cli_session.h"
#include "commands.h"
#include "mtcal/services/gantry.h"

namespace mtcal::app {
namespace {

using services::GantryEvaluateOptions;

void printText(std::ostream& out, const services::GantryAnalysis& a) {
  const auto& ev = a.evaluation;
  const auto& u = a.uncertainty;
  const auto& mpe = a.mpe;
  out << fmt::format("{}\n", a.title);
  out << fmt::format("gantry point accuracy (patent CN106017326): {} holes, targets by {}, TCP0 from {}\n",
                     ev.holes.size(), ev.target_fit,
                     a.options.tcp0 == "axes" ? "the A and C axes" : "the tool-point nest");
  out << fmt::format(
      "global frame: XY plane rms {:.1f} um, side faces {:.1f} / {:.1f} um; gantry line rms {:.1f} um, "
      "tilt {:.1f} urad, passes within {:.1f} urad\n",
      ev.xy_plane.rms_mm * 1000.0, ev.side_1_rms_um, ev.side_2_rms_um, ev.gantry_line_rms_um, ev.gantry_tilt_urad,
      ev.gantry_passes_spread_urad);
  for (const auto* axis : {&ev.c_axis, &ev.a_axis}) {
    out << fmt::format(
        "{} axis: centre ({:.3f}, {:.3f}, {:.3f}) mm, direction ({:.6f}, {:.6f}, {:.6f}), radius {:.3f} mm, "
        "radial rms {:.1f} um, arc {:.0f} deg\n",
        axis == &ev.c_axis ? "C" : "A", axis->centre.x(), axis->centre.y(), axis->centre.z(), axis->normal.x(),
        axis->normal.y(), axis->normal.z(), axis->radius_mm, axis->radial_rms_mm * 1000.0, axis->arc_deg);
  }
  out << fmt::format("A and C axes: {:.1f} um apart (common perpendicular), {:+.1f} urad out of square\n",
                     ev.axes.distance_mm * 1000.0, ev.axes_squareness_urad);
  out << fmt::format("wrist centre ({:.3f}, {:.3f}, {:.3f}) mm; TCP0 ({:.3f}, {:.3f}, {:.3f}) mm\n",
                     ev.wrist_centre_mm.x(), ev.wrist_centre_mm.y(), ev.wrist_centre_mm.z(), ev.tcp0_mm.x(),
                     ev.tcp0_mm.y(), ev.tcp0_mm.z());
  if (ev.tcp0_axes_minus_tool_point_um) {
    const auto& d = *ev.tcp0_axes_minus_tool_point_um;
    out << fmt::format("TCP0 from the axes minus the tool-point nest: ({:+.1f}, {:+.1f}, {:+.1f}) um, |{:.1f}| um\n",
                       d.x(), d.y(), d.z(), d.norm());
  }
  out << fmt::format("\n{:<10} {:>3} {:>8} {:>8} {:>8} {:>8} {:>8}{}\n", "hole", "pos", "dX um", "dY um", "dZ um",
                     "|dP| um", "perp um", u ? "  U95 |dP|  U95 perp" : "");
  for (std::size_t i = 0; i < ev.holes.size(); ++i) {
    const auto& h = ev.holes[i];
    out << fmt::format("{:<10} {:>3} {:>8.1f} {:>8.1f} {:>8.1f} {:>8.1f} {:>8.1f}", h.id, h.gantry_position,
                       h.dp_um.x(), h.dp_um.y(), h.dp_um.z(), h.dp_norm_um, h.dp_perp_um);
    if (u) out << fmt::format("  {:>9.1f} {:>9.1f}", u->holes[i].norm_u95_um, u->holes[i].perp_u95_um);
    out << "\n";
  }
  out << "\n";
  for (const auto& s : ev.summaries) {
    out << fmt::format(
        "{:<14} {:>3} holes: |dP| mean {:.1f} max {:.1f} ({}) rms {:.1f} um; perpendicular mean {:.1f} max {:.1f} "
        "rms {:.1f} um\n",
        s.gantry_position == 0 ? "all" : fmt::format("position {}", s.gantry_position), s.holes, s.mean_norm_um,
        s.max_norm_um, s.worst_hole, s.rms_norm_um, s.mean_perp_um, s.max_perp_um, s.rms_perp_um);
  }
  if (u) {
    out << fmt::format(
        "uncertainty (Monte Carlo, {} trials, tracker MPE {:g} um + {:g} um/m along, {:g} um + {:g} um/m across): "
        "U95 of |dP| up to {:.1f} um, of the perpendicular error up to {:.1f} um\n",
        u->trials, mpe.distance_um, mpe.distance_um_per_m, mpe.transverse_um, mpe.transverse_um_per_m,
        u->max_norm_u95_um, u->max_perp_u95_um);
  }
  for (const auto& n : ev.notes) out << "note: " << n << "\n";
}

void render(const Globals& g, const services::GantryAnalysis& a, const nlohmann::json& document) {
  if (g.json) {
    *g.out << document.dump() << "\n";
  } else {
    printText(*g.out, a);
  }
}

int runGantry(const Globals& g, const std::string& plan_path, const std::string& device_uri,
              const SimulationOptions& sim, const GantryEvaluateOptions& evaluate) {
  services::GantryRunRequest request;
  request.plan = acquisition::GantryPlan::fromJson(services::readJsonFile(plan_path), plan_path);
  request.plan_path = plan_path;
  request.device_uri = device_uri;
  request.simulation = sim;
  request.evaluation = evaluate;
  CliSession cli(g);
  const auto r = services::runGantry(cli.session, request);
  cli.observer.finish();
  return printGantryRun(g, r);
}

int analyzeGantry(const Globals& g, storage::Id run_id, const GantryEvaluateOptions& options) {
  CliSession cli(g);
  const auto a = services::analyzeGantry(cli.session, run_id, options);
  render(g, a, a.document());
  return 0;
}

int gantryEvaluate(const Globals& g, const std::string& path, const GantryEvaluateOptions& options) {
  const auto a = services::evaluateGantryFile(path, options);
  render(g, a, a.document());
  return 0;
}

}  // namespace

int printGantryRun(const Globals& g, const services::GantryRunResult& r) {
  if (!r.analysis) {
    if (!jsonPrinted(g, r.document()))
      *g.out << fmt::format(
          "run {} interrupted: {}; the features measured are stored; continue it with: mtcal resume "
          "{}\n",
          r.run_id, r.reason, r.run_id);
    return 1;
  }
  if (!g.json) *g.out << fmt::format("run {}: {} tracker points\n\n", r.run_id, r.points);
  render(g, *r.analysis, r.document());
  return 0;
}

void registerGantryCommands(CliContext& c) {
  struct Gantry {
    GantryEvaluateOptions evaluation;
    std::string plan_path, device_uri = "mock://tracker", file;
    storage::Id run_id = 0;
  };
  auto o = std::make_shared<Gantry>();
  const auto add_evaluation = [o](CLI::App* cmd) {
    cmd->add_option("--tcp0", o->evaluation.tcp0, "TCP0 from the A/C axes (the patent) or from the tool-point nest")
        ->capture_default_str()
        ->check(CLI::IsMember({"axes", "tool-point"}));
    cmd->add_option("--fit", o->evaluation.fit, "target motion: patent (three-point frame), lsq (Umeyama) or auto")
        ->capture_default_str()
        ->check(CLI::IsMember({"auto", "patent", "lsq"}));
    cmd->add_option("--trials", o->evaluation.trials,
                    "Monte Carlo trials of the tracker's MPE, 0 (none) or 2 to 100000 (default: the plan's)")
        ->transform(wholeBetween(0, 100000))
        ->check(CLI::Validator(
            [](const std::string& value) {
              return value == "1" ? std::string("one trial has no spread: 0 (none) or 2 to 100000") : std::string();
            },
            "0 or 2..100000"));
    cmd->add_option("--mc-seed", o->evaluation.seed, "seed of the Monte Carlo")
        ->capture_default_str()
        ->transform(wholeBetween(0, std::numeric_limits<long long>::max()));
  };
  const auto add_run = [&](CLI::App* cmd) {
    cmd->add_option("PLAN", o->plan_path, "plan file (JSON, type gantry)")->required();
    cmd->add_option("--device", o->device_uri, "tracker URI")->capture_default_str();
    addSimulationOptions(cmd, c,
                         "the gantry: virtual (examples/machines/gantry-drilling.json) or a real one's kinematics");
    add_evaluation(cmd);
    c.on(
        cmd, [&c, o] { return runGantry(c.g, o->plan_path, o->device_uri, c.sim, o->evaluation); },
        OnSignal::kStopAndWait);
  };
  add_run(c.run->add_subcommand("gantry", "gantry point accuracy plan (patent CN106017326) with a laser tracker"));
  auto* gantry_cmd = c.app->add_subcommand("gantry", "gantry point accuracy with a laser tracker (patent CN106017326)")
                         ->require_subcommand(1);
  add_run(gantry_cmd->add_subcommand("run", "same as `run gantry`"));
  auto* gantry_evaluate =
      gantry_cmd->add_subcommand("evaluate", "evaluate exported tracker measurements (docs/gantry.md)");
  gantry_evaluate->add_option("FILE", o->file, "measurement file (JSON)")->required();
  add_evaluation(gantry_evaluate);
  c.on(gantry_evaluate, [&c, o] { return gantryEvaluate(c.g, o->file, o->evaluation); });
  auto* analyze_gantry =
      c.analyze->add_subcommand("gantry", "gantry point accuracy: dP per hole, summaries, uncertainty");
  analyze_gantry->add_option("RUN", o->run_id, "run id")->required();
  add_evaluation(analyze_gantry);
  c.on(analyze_gantry, [&c, o] { return analyzeGantry(c.g, o->run_id, o->evaluation); });
}

}  // namespace mtcal::app
