// The `mtcal model` commands: error models from measured curves or identified from runs,
// their prediction of the volumetric error, key errors, the bands of the plane random process,
// validation against runs and the compensation table; rendered for people or as JSON.

#include <fmt/format.h>

#include <fstream>

#include "cli_session.h"
#include "commands.h"
#include "mtcal/error.h"
#include "mtcal/services/model.h"

namespace mtcal::app {
namespace {

void printStored(const Globals& g, const services::StoredModel& m) {
  if (g.json) {
    *g.out << m.document().dump() << "\n";
  } else {
    *g.out << m.model_id << "\n";
  }
}

/// CSV to stdout, or to a file with a line saying so.
void writeCsv(const Globals& g, const std::string& csv, const std::string& path, std::size_t rows, const std::string& what) {
  if (path.empty()) {
    *g.out << csv;
    return;
  }
  std::ofstream out(path);
  if (!(out << csv) || !out.flush()) throw InputError(path + ": cannot write");
  *g.out << fmt::format("{} {} written to {}\n", rows, what, path);
}

}  // namespace

int modelImport(const Globals& g, const ModelImportOptions& options) {
  CliSession cli(g);
  printStored(g, services::importModel(cli.session, options));
  return 0;
}

int modelIdentify(const Globals& g, const std::vector<std::string>& sources, const ModelImportOptions& options) {
  CliSession cli(g);
  const auto m = services::identifyModel(cli.session, sources, options);
  if (!g.json) {
    for (const auto& a : m.axes) {
      *g.err << fmt::format("axis {}: {} from {} (condition number {:.3g})\n", a.coordinate, fmt::join(a.terms, " "),
                            fmt::join(a.lines, ", "), a.condition_number);
    }
    for (const auto& note : m.notes) *g.err << "note: " << note << "\n";
  }
  printStored(g, m);
  return 0;
}

int modelList(const Globals& g) {
  CliSession cli(g);
  const auto models = services::listModels(cli.session);
  if (g.json) {
    *g.out << services::modelListDocument(models).dump() << "\n";
    return 0;
  }
  if (models.empty()) {
    *g.out << fmt::format("no models in {} (make one: mtcal model import or mtcal model identify)\n", g.db);
    return 0;
  }
  *g.out << fmt::format("{:>4}  {:<24} {:<9} {}\n", "id", "created (UTC)", "method", "name");
  for (const auto& m : models) *g.out << fmt::format("{:>4}  {:<24} {:<9} {}\n", m.id, m.created_at, m.method, m.name);
  return 0;
}

int modelPredict(const Globals& g, storage::Id model_id, const std::string& grid, const std::string& points_csv,
                 const std::string& out_csv) {
  CliSession cli(g);
  const auto p = services::predictModel(cli.session, model_id, grid, points_csv);
  if (g.json) {
    *g.out << p.document().dump() << "\n";
  } else {
    writeCsv(g, p.csv(), out_csv, p.points.size(), "points");
  }
  return 0;
}

int modelKeyErrors(const Globals& g, storage::Id model_id, const std::string& at, int sobol_samples) {
  CliSession cli(g);
  const auto k = services::keyErrors(cli.session, model_id, at, sobol_samples);
  if (g.json) {
    *g.out << k.document().dump() << "\n";
    return 0;
  }
  *g.out << fmt::format("key errors of model {} at ({}): share of each error in the variance of E\n", model_id,
                        fmt::join(std::vector<double>(k.at.begin(), k.at.end()), ", "));
  *g.out << fmt::format("  sigma of E: x {:.3f} um, y {:.3f} um, z {:.3f} um\n", k.sigma_um(0), k.sigma_um(1), k.sigma_um(2));
  *g.out << fmt::format("  {:<6} {:>8} {:>8} {:>8}{}\n", "error", "x", "y", "z", k.sobol.empty() ? "" : "   Sobol x / y / z");
  for (const auto& key : k.keys) {
    if (key.share[0] + key.share[1] + key.share[2] < 1e-6) continue;
    std::string line = fmt::format("  {:<6} {:>8.3f} {:>8.3f} {:>8.3f}", key.name, key.share[0], key.share[1], key.share[2]);
    for (const auto& s : k.sobol) {
      if (s.name == key.name) line += fmt::format("   {:.3f} / {:.3f} / {:.3f}", s.first_order[0], s.first_order[1], s.first_order[2]);
    }
    *g.out << line << "\n";
  }
  return 0;
}

int modelBands(const Globals& g, storage::Id model_id, const std::string& plane, const std::string& at, int grid_n) {
  CliSession cli(g);
  const auto b = services::modelBands(cli.session, model_id, plane, at, grid_n);
  if (g.json) {
    *g.out << b.document().dump() << "\n";
    return 0;
  }
  *g.out << fmt::format("plane {} of model {}: error band +-{:.2f} sigma (3 sigma, t-corrected for the repeats)\n",
                        processing::planeName(b.plane), model_id, b.coverage_k);
  *g.out << fmt::format("{:>9} {:>9} {:>9} {:>9} {:>9} {:>10}\n", "x_mm", "y_mm", "z_mm", "mean_a", "mean_b", "band_um");
  for (const auto& p : b.bands) {
    *g.out << fmt::format("{:>9.2f} {:>9.2f} {:>9.2f} {:>9.3f} {:>9.3f} {:>10.3f}\n", p.point_mm[0], p.point_mm[1], p.point_mm[2],
                          p.mean_um[0], p.mean_um[1], p.widestBandUm());
  }
  *g.out << fmt::format("widest band: +-{:.3f} um\n", b.widest_band_um);
  return 0;
}

int modelValidate(const Globals& g, storage::Id model_id, const std::vector<storage::Id>& runs) {
  CliSession cli(g);
  const auto v = services::validateModel(cli.session, model_id, runs);
  if (g.json) {
    *g.out << v.document().dump() << "\n";
    return 0;
  }
  *g.out << "run    error  points   RMS      peak     (um or urad; the line's zero removed)\n";
  for (const auto& r : v.runs) {
    *g.out << fmt::format("{:<6} {:<6} {:>6}   {:<8.3f} {:<8.3f}\n", r.run_id, r.measures, r.comparison.residual.size(),
                          r.comparison.rms, r.comparison.peak);
  }
  if (v.outside > 0) {
    *g.err << fmt::format("note: {} point(s) outside the range the model was measured over were not compared\n", v.outside);
  }
  return 0;
}

int modelCompensation(const Globals& g, storage::Id model_id, const CompensationOptions& o) {
  CliSession cli(g);
  const auto t = services::compensationTable(cli.session, model_id, {o.axis, o.from_mm, o.to_mm, o.step_mm, o.at});
  if (g.json) {
    *g.out << t.document().dump() << "\n";
    return 0;
  }
  writeCsv(g, t.csv(), o.output_path, t.position_mm.size(), "positions");
  if (!t.applied.empty()) *g.err << fmt::format("extensions included: {}\n", fmt::join(t.applied, ", "));
  if (!t.left_out.empty()) {
    *g.err << fmt::format("extensions left out (they depend on time or temperatures, not on the position): {}\n", fmt::join(t.left_out, ", "));
  }
  if (t.outside > 0) *g.err << fmt::format("note: {} position(s) outside the model's measured range were left out\n", t.outside);
  return 0;
}

}  // namespace mtcal::app
