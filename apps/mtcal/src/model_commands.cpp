// The `mtcal model` commands: error models from measured curves or identified from runs,
// their prediction of the volumetric error, key errors, the bands of the plane random process,
// validation against runs; rendered for people or as JSON.

#include <fmt/format.h>

#include <fstream>

#include "cli_session.h"
#include "commands.h"
#include "mtcal/error.h"
#include "mtcal/services/model.h"

namespace mtcal::app {
namespace {

using ModelImportOptions = services::ModelFitRequest;

void printStored(const Globals& g, const services::StoredModel& m) {
  if (g.json) {
    *g.out << m.document().dump() << "\n";
  } else {
    *g.out << m.model_id << "\n";
    *g.err << fmt::format("stored as model {0}: `mtcal model predict|validate {0} ...`, `mtcal compensate m{0} ...`\n",
                          m.model_id);
    *g.err << fmt::format("it has {} of the machine's {} error terms: {}\n", m.errors.size(), m.machine_terms,
                          fmt::join(m.coverage, "; "));
  }
}

/// CSV to stdout, or to a file with a line saying so.
void writeCsv(const Globals& g, const std::string& csv, const std::string& path, std::size_t rows,
              const std::string& what) {
  if (path.empty()) {
    *g.out << csv;
    return;
  }
  services::writeTextFile(path, csv);
  *g.out << fmt::format("{} {} written to {}\n", rows, what, path);
}

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
  if (jsonPrinted(g, services::modelListDocument(models))) return 0;
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
  if (p.outside > 0) {
    cli.observer.onMessage("warning", fmt::format("{} of {} points lie outside the range the model was measured over: "
                                                  "extrapolated, not to be trusted (nor their sigma, which knows only "
                                                  "the fit's scatter)",
                                                  p.outside, p.points.size()));
  }
  if (!g.json) {
    writeCsv(g, p.csv(), out_csv, p.points.size(), "points");
    return 0;
  }
  if (!out_csv.empty()) services::writeTextFile(out_csv, p.csv());
  *g.out << p.document().dump() << "\n";
  return 0;
}

int modelKeyErrors(const Globals& g, storage::Id model_id, const std::string& at, int sobol_samples) {
  CliSession cli(g);
  const auto k = services::keyErrors(cli.session, model_id, at, sobol_samples);
  if (k.outside) {
    cli.observer.onMessage("warning",
                           "the point lies outside the range the model was measured over: extrapolated, "
                           "not to be trusted (nor its sigma, which knows only the fit's scatter)");
  }
  if (jsonPrinted(g, k.document())) return 0;
  *g.out << fmt::format("key errors of model {} at ({}): share of each error in the variance of E\n", model_id,
                        fmt::join(std::vector<double>(k.at.begin(), k.at.end()), ", "));
  *g.out << fmt::format("  sigma of E: x {:.3f} um, y {:.3f} um, z {:.3f} um\n", k.sigma_um(0), k.sigma_um(1),
                        k.sigma_um(2));
  *g.out << fmt::format("  {:<6} {:>8} {:>8} {:>8}{}\n", "error", "x", "y", "z",
                        k.sobol.empty() ? "" : "   Sobol x / y / z");
  for (const auto& key : k.keys) {
    if (key.share[0] + key.share[1] + key.share[2] < 1e-6) continue;
    std::string line =
        fmt::format("  {:<6} {:>8.3f} {:>8.3f} {:>8.3f}", key.name, key.share[0], key.share[1], key.share[2]);
    for (const auto& s : k.sobol) {
      if (s.name == key.name)
        line += fmt::format("   {:.3f} / {:.3f} / {:.3f}", s.first_order[0], s.first_order[1], s.first_order[2]);
    }
    *g.out << line << "\n";
  }
  return 0;
}

int modelBands(const Globals& g, storage::Id model_id, const std::string& plane, const std::string& at, int grid_n) {
  CliSession cli(g);
  const auto b = services::modelBands(cli.session, model_id, plane, at, grid_n);
  if (jsonPrinted(g, b.document())) return 0;
  *g.out << fmt::format("plane {} of model {}: error band +-{:.2f} sigma (3 sigma, t-corrected for the repeats)\n",
                        processing::planeName(b.plane), model_id, b.coverage_k);
  *g.out << fmt::format("{:>9} {:>9} {:>9} {:>9} {:>9} {:>10}\n", "x_mm", "y_mm", "z_mm", "mean_a", "mean_b",
                        "band_um");
  for (const auto& p : b.bands) {
    *g.out << fmt::format("{:>9.2f} {:>9.2f} {:>9.2f} {:>9.3f} {:>9.3f} {:>10.3f}\n", p.point_mm[0], p.point_mm[1],
                          p.point_mm[2], p.mean_um[0], p.mean_um[1], p.widestBandUm());
  }
  *g.out << fmt::format("widest band: +-{:.3f} um\n", b.widest_band_um);
  return 0;
}

int modelValidate(const Globals& g, storage::Id model_id, const std::vector<storage::Id>& runs) {
  CliSession cli(g);
  const auto v = services::validateModel(cli.session, model_id, runs);
  if (jsonPrinted(g, v.document())) return 0;
  *g.out << "run    error  points   RMS      peak     (um or urad; the line's zero removed)\n";
  for (const auto& r : v.runs) {
    *g.out << fmt::format("{:<6} {:<6} {:>6}   {:<8.3f} {:<8.3f}\n", r.run_id, r.measures, r.comparison.residual.size(),
                          r.comparison.rms, r.comparison.peak);
  }
  if (v.outside > 0) {
    *g.err << fmt::format("note: {} point(s) outside the range the model was measured over were not compared\n",
                          v.outside);
  }
  return 0;
}

}  // namespace

void registerModelCommands(CliContext& c) {
  struct Model {
    storage::Id model_id = 0;
    ModelImportOptions fit;
    CsvOptions csv;
    std::vector<std::string> sources;
    std::string grid, points_csv, out_csv, at, plane = "XY";
    int sobol_samples = 0, band_grid = 5;
    std::vector<storage::Id> runs;
  };
  auto o = std::make_shared<Model>();
  auto* model_cmd =
      c.app->add_subcommand("model", "geometric error models: import, identify, predict, key errors, bands")
          ->require_subcommand(1);
  auto* import_cmd = model_cmd->add_subcommand("import", "a model from error curves measured elsewhere (CSV)");
  import_cmd->add_option("FILE", o->fit.csv_path, "CSV: error,position_mm,value[,s,n]")->required();
  import_cmd->add_option("--machine", o->fit.machine_path, "kinematic description (JSON)")->required();
  import_cmd->add_option("--name", o->fit.name, "model name (default: the file name)")
      ->check(notEmpty("a name", "NAME"));
  import_cmd->add_option("--knot-spacing-mm", o->fit.min_knot_spacing_mm, "smallest B-spline knot spacing")
      ->capture_default_str()
      ->check(between(processing::kFinestKnotSpacingMm, processing::kCoarsestKnotSpacingMm));
  addCsvOptions(import_cmd, o->csv);
  c.on(import_cmd, [&c, o] {
    o->fit.csv = o->csv.dialect();
    return modelImport(c.g, o->fit);
  });

  auto* identify_cmd = model_cmd->add_subcommand("identify", "a model from stored measurement runs");
  identify_cmd
      ->add_option("RUN", o->sources, "run ids, or cN for every completed linear run of campaign N (mtcal runs)")
      ->required();
  identify_cmd->add_option("--machine", o->fit.machine_path, "kinematic description (JSON)")->required();
  identify_cmd
      ->add_option("--method", o->fit.method,
                   "direct (each error from the runs that measure it) or 9-line (three displacement lines per axis)")
      ->capture_default_str()
      ->check(CLI::IsMember({"direct", "9-line"}));
  identify_cmd
      ->add_option("--max-condition", o->fit.max_condition_number,
                   "refuse line layouts whose condition number exceeds this (1 or more)")
      ->capture_default_str()
      ->check(between(1.0, 1e300));
  identify_cmd->add_option("--name", o->fit.name, "model name")->check(notEmpty("a name", "NAME"));
  identify_cmd->add_option("--knot-spacing-mm", o->fit.min_knot_spacing_mm, "smallest B-spline knot spacing")
      ->capture_default_str()
      ->check(between(processing::kFinestKnotSpacingMm, processing::kCoarsestKnotSpacingMm));
  c.on(identify_cmd, [&c, o] { return modelIdentify(c.g, o->sources, o->fit); });

  c.on(model_cmd->add_subcommand("list", "list the stored models"), [&c] { return modelList(c.g); });

  auto* predict_cmd =
      model_cmd->add_subcommand("predict", "volumetric error at the tool point, at a grid or at points of the axes");
  predict_cmd->add_option("MODEL", o->model_id, "model id")->required();
  predict_cmd->add_option("--grid", o->grid, "axis positions X0:X1:N,Y0:Y1:N,Z0:Z1:N");
  predict_cmd->add_option("--points", o->points_csv, "CSV of axis positions x_mm,y_mm,z_mm (E is at the tool point)");
  predict_cmd->add_option("-o,--out", o->out_csv, "write the CSV here instead of stdout")
      ->check(notEmpty("a file name", "FILE"));
  c.on(predict_cmd, [&c, o] { return modelPredict(c.g, o->model_id, o->grid, o->points_csv, o->out_csv); });

  auto* keys_cmd = model_cmd->add_subcommand("key-errors", "share of each error term in the spatial error");
  keys_cmd->add_option("MODEL", o->model_id, "model id")->required();
  addXyzOption(keys_cmd, "--at", o->at, "x,y,z (default: the centre of the measured ranges)");
  keys_cmd->add_option("--sobol", o->sobol_samples, "also Monte Carlo Sobol indices with this many samples")
      ->transform(wholeBetween(10, 1000000));
  c.on(keys_cmd, [&c, o] { return modelKeyErrors(c.g, o->model_id, o->at, o->sobol_samples); });

  auto* bands_cmd = model_cmd->add_subcommand("bands", "error band of the plane random process on a plane");
  bands_cmd->add_option("MODEL", o->model_id, "model id")->required();
  bands_cmd->add_option("--plane", o->plane, "XY, YZ or ZX")->capture_default_str();
  addXyzOption(bands_cmd, "--at", o->at, "x,y,z fixing the third coordinate (default: the centre)");
  bands_cmd->add_option("--grid", o->band_grid, "points per side of the plane")->capture_default_str();
  c.on(bands_cmd, [&c, o] { return modelBands(c.g, o->model_id, o->plane, o->at, o->band_grid); });

  auto* validate_cmd =
      model_cmd->add_subcommand("validate", "compare a model with runs it was not built from (residual RMS and peak)");
  validate_cmd->add_option("MODEL", o->model_id, "model id")->required();
  validate_cmd->add_option("RUN", o->runs, "run ids, e.g. random points every ~3 mm")->required();
  c.on(validate_cmd, [&c, o] { return modelValidate(c.g, o->model_id, o->runs); });
}

}  // namespace mtcal::app
