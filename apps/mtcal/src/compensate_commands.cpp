// mtcal compensate: the compensation table a controller loads, from a linear positioning run
// or an identified model, written in the controller's format with the lines that activate it.

#include <fmt/format.h>

#include <filesystem>
#include <memory>

#include "cli_session.h"
#include "commands.h"
#include "mtcal/error.h"
#include "mtcal/services/archive.h"
#include "mtcal/services/compensate.h"

namespace mtcal::app {
namespace {

struct CompensateOptions {
  std::string source;  ///< a run id, or mN for model N
  std::string output_path;
  bool mean = false;
  services::CompensateRequest request;
  int verify_points = static_cast<int>(services::VolumetricRequest{}.points);
  bool verify_points_given = false;
};

int compensateVolumetric(const Globals& g, const CompensateOptions& o, storage::Id model_id) {
  if (!o.request.axis.empty() || o.request.axis_index || o.request.table.start || o.request.table.end ||
      o.request.table.reference || o.mean || o.request.table.resolution_um || !o.request.existing_path.empty() ||
      !o.request.at.empty()) {
    throw InputError(
        fmt::format("{} compensates every axis of the model at once: it takes --interval, "
                    "--verify-points and -o, not the options of one axis' table",
                    services::kIsgVolumetric));
  }
  CliSession cli(g);
  services::VolumetricRequest request;
  request.interval = o.request.table.interval.value_or(request.interval);
  request.points = static_cast<std::size_t>(o.verify_points);
  if (!o.output_path.empty()) request.file_name = std::filesystem::path(o.output_path).filename().string();
  const auto c = services::compensateVolumetric(cli.session, model_id, request);
  if (!o.output_path.empty()) services::writeTextFile(o.output_path, c.text);
  if (jsonPrinted(g, c.document())) return 0;
  std::string axes;
  for (const auto& a : c.table.axes)
    axes += fmt::format("{}{} {} rows from {:g} to {:g}", axes.empty() ? "" : ", ", a.coordinate, a.position.size(),
                        a.position.front(), a.position.back());
  const std::string what =
      fmt::format("{} records ({}; {} position errors)", c.table.records(), axes, c.table.constants.size());
  if (o.output_path.empty()) {
    *g.out << c.text;
    *g.err << fmt::format("{} of {}: {}\nthe controller's configuration:\n{}", services::kIsgVolumetric, c.source, what,
                          c.setup);
  } else {
    *g.out << fmt::format("{} of {} written to {}: {}\nthe controller's configuration:\n{}", services::kIsgVolumetric,
                          c.source, o.output_path, what, c.setup);
  }
  if (!c.extensions_left_out.empty()) {
    *g.err << fmt::format("model extensions left out (a volumetric table has no direction, time or temperature): {}\n",
                          fmt::join(c.extensions_left_out, ", "));
  }
  if (const auto& v = c.verification) {
    (o.output_path.empty() ? *g.err : *g.out) << fmt::format(
        "on the simulated machine, {} random points (seed {}), error after a best-fit rigid motion:\n"
        "  without the table  rms {:.2f} um, max {:.2f} um\n"
        "  with the table     rms {:.2f} um, max {:.2f} um\n"
        "  expected (the machine minus the model)  rms {:.2f} um, max {:.2f} um\n",
        v->points, v->seed, v->before_rms_um, v->before_max_um, v->after_rms_um, v->after_max_um, v->expected_rms_um,
        v->expected_max_um);
  }
  return 0;
}

int compensate(const Globals& g, const CompensateOptions& o) {
  CliSession cli(g);
  auto request = o.request;
  request.table.bidirectional = !o.mean;
  if (!o.output_path.empty()) request.file_name = std::filesystem::path(o.output_path).filename().string();
  const auto source = services::ArchiveItem::parse(o.source, "rm");
  if (o.verify_points_given && o.request.controller != services::kIsgVolumetric)
    throw InputError(fmt::format("--verify-points is for --controller {} (a model's volumetric compensation)",
                                 services::kIsgVolumetric));
  if (source.run && !o.request.at.empty())
    throw InputError("--at places a model's other axes: a run's table is of the line it measured");
  if (o.request.controller == services::kIsgVolumetric) {
    if (!source.model)
      throw InputError(fmt::format("{} needs a model (mN): a run measures one axis", services::kIsgVolumetric));
    return compensateVolumetric(g, o, *source.model);
  }
  const auto c = source.model ? services::compensateModel(cli.session, *source.model, request)
                              : services::compensateRun(cli.session, *source.run, request);
  if (!o.output_path.empty()) services::writeTextFile(o.output_path, c.file.text);
  if (jsonPrinted(g, c.document())) return 0;
  const auto& t = c.table;
  const std::string what = fmt::format("{} entries from {:g} to {:g}{}, {}", t.position.size(), t.position.front(),
                                       t.position.back(), t.modulo ? " deg (modulo)" : " mm",
                                       t.bidirectional() ? "bidirectional" : "one table for both directions");
  if (o.output_path.empty()) {
    *g.out << c.file.text;
    *g.err << fmt::format("{} table of axis {} from {}: {}\n", c.controller, c.axis, c.source, what);
  } else {
    *g.out << fmt::format("{} table of axis {} from {} written to {}: {}\n", c.controller, c.axis, c.source,
                          o.output_path, what);
  }
  for (const auto& w : c.warnings) *g.err << "warning: " << w << "\n";
  if (!c.existing_path.empty()) {
    *g.err << fmt::format("the table is {}'s plus the correction of what {} measured with it\n", c.existing_path,
                          c.source);
  }
  if (!c.file.setup.empty()) {
    (o.output_path.empty() ? *g.err : *g.out) << fmt::format("the controller's configuration:\n{}", c.file.setup);
  }
  if (!c.extensions_applied.empty())
    *g.err << fmt::format("model extensions included: {}\n", fmt::join(c.extensions_applied, ", "));
  if (!c.extensions_left_out.empty()) {
    *g.err << fmt::format("model extensions left out (they depend on time or temperatures): {}\n",
                          fmt::join(c.extensions_left_out, ", "));
  }
  if (c.outside > 0)
    *g.err << fmt::format("note: {} position(s) outside the model's measured range were left out\n", c.outside);
  return 0;
}

}  // namespace

void registerCompensateCommands(CliContext& c) {
  auto o = std::make_shared<CompensateOptions>();
  auto& t = o->request.table;
  auto* cmd = c.app->add_subcommand(
      "compensate", "the compensation table a controller loads, from a linear positioning run or a model (mN)");
  cmd->add_option("SOURCE", o->source, "a completed positioning run's id, or mN for model N")->required();
  cmd->add_option("--controller", o->request.controller,
                  fmt::format("the file format: {}, or {} (a model's volumetric compensation)",
                              fmt::join(processing::controllerNames(), ", "), services::kIsgVolumetric))
      ->capture_default_str();
  cmd->add_option("--axis", o->request.axis, "the axis (a run's own by default; a model needs it)");
  cmd->add_option("--axis-index", o->request.axis_index,
                  "the controller's number of the axis (LinuxCNC's joint; default X 0, Y 1, Z 2)");
  cmd->add_option("--start", t.start, "first position, mm (default: the measured range's)");
  cmd->add_option("--end", t.end, "last position, mm (default: the measured range's)");
  cmd->add_option("--interval", t.interval, "spacing of the entries, mm (default: a run's targets; a model: 10)")
      ->check(positive());
  cmd->add_option("--reference", t.reference, "the correction is zero at this position (mm)");
  cmd->add_flag("--mean", o->mean, "one table for both directions (the mean), not bidirectional");
  cmd->add_option("--resolution-um", t.resolution_um, "round the corrections to this (default: the controller's)")
      ->check(positive());
  cmd->add_option("--existing", o->request.existing_path,
                  "the table the machine ran while measured (the controller's format): the new one adds to it")
      ->check(notEmpty("a file name", "FILE"));
  addXyzOption(cmd, "--at", o->request.at, "a model's other coordinates x,y,z (default: the centre)");
  cmd->add_option_function<int>(
         "--verify-points",
         [o](int n) {
           o->verify_points = n;
           o->verify_points_given = true;
         },
         fmt::format("isg-volumetric: random points of the check on the simulated machine, 0 (none) to 100000 "
                     "(default {})",
                     o->verify_points))
      ->transform(wholeBetween(0, 100000));
  cmd->add_option("-o,--out", o->output_path, "write the table file here (default: stdout)")
      ->check(notEmpty("a file name", "FILE"));
  c.on(cmd, [&c, o] { return compensate(c.g, *o); });
}

}  // namespace mtcal::app
