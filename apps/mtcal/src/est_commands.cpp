// Guideway straightness by error separation: from probe readings in a CSV file (mtcal est),
// a probe stepping run on the simulated machine (mtcal run est) and a stored run (mtcal
// analyze est), rendered as one report.

#include <fmt/format.h>

#include "cli_session.h"
#include "commands.h"
#include "mtcal/services/est.h"

namespace mtcal::app {
namespace {

services::EstMethod methodOf(const EstOptions& o) { return {o.method, o.start, o.spacing_mm}; }

void report(const Globals& g, const services::EstAnalysis& a, const nlohmann::json& document) {
  if (g.json) {
    *g.out << document.dump() << "\n";
    return;
  }
  const auto& r = a.result;
  *g.out << fmt::format("{} separation, probe spacing {} mm, {} points\n\n", a.method.method, a.method.spacing_mm, r.x_mm.size());
  *g.out << "      x_mm   profile_um  carriage_um\n";
  for (std::size_t k = 0; k < r.x_mm.size(); ++k) {
    *g.out << fmt::format("{:>10.3f} {:>12.3f} {:>12}\n", r.x_mm[k], r.profile_um[k],
                          k < r.carriage_um.size() ? fmt::format("{:.3f}", r.carriage_um[k]) : "-");
  }
  *g.out << fmt::format("\nstraightness (um): least squares {:.3f}, minimum zone {:.3f}, end points {:.3f}\n",
                        a.straightness.least_squares_um, a.straightness.min_zone_um, a.straightness.end_point_um);
  if (!a.noise_um.empty()) *g.out << fmt::format("reading scatter alone: {:.3f} um (1 sigma) at the last point\n", a.noise_um.back());
  if (!r.lost_wavelengths_mm.empty()) {
    *g.out << fmt::format("harmonics lost by the frequency method: wavelengths {} mm\n", fmt::join(r.lost_wavelengths_mm, ", "));
  }
}

}  // namespace

int estimateStraightness(const Globals& g, const EstOptions& options) {
  const auto a = services::separate(services::readProbeCsv(options.csv_path, options.method == "three-probe"), methodOf(options));
  report(g, a, a.document());
  return 0;
}

int analyzeEst(const Globals& g, storage::Id run_id, const EstOptions& options) {
  CliSession cli(g);
  const auto a = services::analyzeEst(cli.session, run_id, methodOf(options));
  report(g, a, a.document());
  return 0;
}

int runEst(const Globals& g, const std::string& plan_path, const std::string& device_uri, const SimulationOptions& sim) {
  CliSession cli(g);
  const auto r = services::runEst(cli.session, {acquisition::EstPlan::load(plan_path), device_uri, sim});
  cli.observer.finish();
  if (!r.analysis) {
    *g.err << fmt::format("run {} interrupted; its steps are stored\n", r.run_id);
    return 1;
  }
  report(g, *r.analysis, r.document());
  if (!g.json) *g.out << fmt::format("\nStored as run {}. Again, or by another method: mtcal analyze est {}\n", r.run_id, r.run_id);
  return 0;
}

}  // namespace mtcal::app
