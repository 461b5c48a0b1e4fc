// Cam grinding with geometric error compensation (mtcal grind compensate) and a grinder
// axis' motion errors from ballbar length changes (mtcal grind identify), rendered for people
// or as JSON.

#include <fmt/format.h>

#include "cli_session.h"
#include "commands.h"
#include "mtcal/services/grind.h"

namespace mtcal::app {

int grindCompensate(const Globals& g, const GrindOptions& options) {
  CliSession cli(g);
  const auto r = services::grindCompensate(cli.session, options);
  if (g.json) {
    *g.out << r.document().dump() << "\n";
    return 0;
  }
  if (options.output_path.empty()) *g.out << r.csv() << "\n";
  *g.out << fmt::format("{} wheel-centre points; wheel-centre error with the ideal commands up to {:.3f} um, with the "
                        "corrected ones up to {:.4f} um ({} iterations at most); along the camshaft {:.3f} um, which X "
                        "and C cannot correct\n",
                        r.commands.size(), r.max_error_ideal_um, r.max_error_um, r.max_iterations, r.max_error_z_um);
  return 0;
}

int grindIdentify(const Globals& g, const std::string& readings_path, const std::string& machine_path,
                  const std::string& layout_path) {
  const auto r = services::grindIdentify(readings_path, machine_path, layout_path);
  if (g.json) {
    *g.out << r.document().dump() << "\n";
    return 0;
  }
  const auto& id = r.result;
  *g.out << fmt::format("{} axis from {} ball placements at {} positions (condition number {:.3g}, rms residual {:.4f} um)\n",
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

}  // namespace mtcal::app
