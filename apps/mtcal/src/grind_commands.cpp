// Cam grinding with geometric error compensation (mtcal grind compensate) and a grinder
// axis' motion errors from ballbar length changes (mtcal grind identify), rendered for people
// or as JSON.

#include <fmt/format.h>

#include "cli_session.h"
#include "commands.h"
#include "mtcal/services/grind.h"

namespace mtcal::app {
namespace {

using GrindOptions = services::GrindRequest;

int grindCompensate(const Globals& g, const GrindOptions& options) {
  CliSession cli(g);
  const auto r = services::grindCompensate(cli.session, options);
  if (jsonPrinted(g, r.document())) return 0;
  if (options.output_path.empty()) *g.out << r.csv() << "\n";
  *g.out << fmt::format(
      "{} wheel-centre points; wheel-centre error with the ideal commands up to {:.3f} um, with the "
      "corrected ones up to {:.4f} um ({} iterations at most); along the camshaft {:.3f} um, which X "
      "and C cannot correct\n",
      r.commands.size(), r.max_error_ideal_um, r.max_error_um, r.max_iterations, r.max_error_z_um);
  return 0;
}

int grindIdentify(const Globals& g, const std::string& readings_path, const std::string& machine_path,
                  const std::string& layout_path) {
  const auto r = services::grindIdentify(readings_path, machine_path, layout_path);
  if (jsonPrinted(g, r.document())) return 0;
  const auto& id = r.result;
  *g.out << fmt::format(
      "{} axis from {} ball placements at {} positions (condition number {:.3g}, rms residual {:.4f} um)\n",
      r.coordinate, r.placements, id.coordinate.size(), id.condition_number, id.rms_residual_um);
  if (!id.not_determined.empty()) {
    *g.out << fmt::format("not determined by this layout: {} (docs/grinding.md)\n", fmt::join(id.not_determined, " "));
  }
  *g.out << fmt::format("{:>10}", "position");
  for (const auto& t : id.terms) *g.out << fmt::format(" {:>10}", t);
  *g.out << "\n";
  for (Eigen::Index j = 0; j < id.values.rows(); ++j) {
    *g.out << fmt::format("{:>10.3f}", id.coordinate[static_cast<std::size_t>(j)]);
    for (Eigen::Index t = 0; t < id.values.cols(); ++t) *g.out << fmt::format(" {:>10.4f}", id.values(j, t));
    *g.out << "\n";
  }
  return 0;
}

}  // namespace

void registerGrindCommands(CliContext& c) {
  auto* grind_cmd = c.app->add_subcommand("grind", "cam grinding on an X + C grinder")->require_subcommand(1);
  auto grind = std::make_shared<GrindOptions>();
  auto* grind_compensate =
      grind_cmd->add_subcommand("compensate", "corrected X/C commands for a cam profile and a model");
  grind_compensate->add_option("PROFILE", grind->profile_path, "cam profile CSV: x_mm,y_mm or angle_deg,radius_mm")
      ->required();
  grind_compensate->add_option("--model", grind->model_id, "stored error model of the grinder (mtcal model list)")
      ->required();
  grind_compensate->add_option("--wheel-radius-mm", grind->wheel_radius_mm, "grinding wheel radius")
      ->required()
      ->check(positive());
  grind_compensate->add_option("--points", grind->points, "wheel-centre points along the profile")
      ->capture_default_str()
      ->transform(wholeBetween(4, 1000000));
  grind_compensate->add_option("--resolution-um", grind->resolution_x_um, "X slide resolution")
      ->capture_default_str()
      ->check(positive());
  grind_compensate->add_option("--resolution-deg", grind->resolution_c_deg, "C axis resolution")
      ->capture_default_str()
      ->check(positive());
  grind_compensate->add_option("-o,--output", grind->output_path, "command list CSV (default: stdout)")
      ->check(notEmpty("a file name", "FILE"));
  grind_compensate->add_option("--gcode", grind->gcode_path, "write the part program here")
      ->check(notEmpty("a file name", "FILE"));
  grind_compensate->add_option("--c-rpm", grind->c_rpm, "work head speed for the program's feed")
      ->capture_default_str()
      ->check(positive());
  c.on(grind_compensate, [&c, grind] { return grindCompensate(c.g, *grind); });

  struct Identify {
    std::string readings, machine, layout;
  };
  auto identify = std::make_shared<Identify>();
  auto* grind_identify = grind_cmd->add_subcommand("identify", "one axis' motion errors from ballbar length changes");
  grind_identify->add_option("READINGS", identify->readings, "CSV: position,pair,delta_length_um")->required();
  grind_identify->add_option("--machine", identify->machine, "kinematic description (examples/machines/*.model.json)")
      ->required();
  grind_identify->add_option("--layout", identify->layout, "ball placements (JSON: coordinate, pairs)")->required();
  c.on(grind_identify,
       [&c, identify] { return grindIdentify(c.g, identify->readings, identify->machine, identify->layout); });
}

}  // namespace mtcal::app
