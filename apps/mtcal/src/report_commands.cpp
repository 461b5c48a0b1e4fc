// mtcal report: a calibration report of a run as one self-contained HTML file.

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <memory>

#include "cli_session.h"
#include "commands.h"
#include "mtcal/error.h"
#include "mtcal/services/archive.h"
#include "mtcal/services/linear.h"
#include "mtcal/services/report.h"
#include "mtcal/services/workshop.h"

namespace mtcal::app {
namespace {

struct ReportOptions {
  std::string subject;  ///< RUN, cN or mN
  std::string output_path;
  std::vector<std::string> tolerances;  ///< SYMBOL=VALUE
  services::ReportRequest request;
};

/// "A=10" -> {"A", 10}. @throws InputError naming the form
std::pair<std::string, double> tolerance(const std::string& text) {
  const auto eq = text.rfind('=');
  try {
    std::size_t used = 0;
    if (eq == std::string::npos || eq == 0) throw std::invalid_argument(text);
    const double value = std::stod(text.substr(eq + 1), &used);
    if (used != text.size() - eq - 1 || !(value >= 0.0) || !std::isfinite(value)) throw std::invalid_argument(text);
    return {text.substr(0, eq), value};
  } catch (const std::exception&) {
    throw InputError(
        fmt::format("--tolerance '{}': give a figure and its largest passing value, e.g. A=10 (um)", text));
  }
}

int report(const Globals& g, ReportOptions o) {
  for (const auto& t : o.tolerances) {
    if (!o.request.tolerance.insert(tolerance(t)).second)
      throw InputError(fmt::format("--tolerance '{}': a tolerance for this figure is given twice", t));
  }
  std::string extension = std::filesystem::path(o.output_path).extension().string();
  std::transform(extension.begin(), extension.end(), extension.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  const bool pdf = extension == ".pdf";
  if (!o.output_path.empty() && !pdf && extension != ".html" && extension != ".htm")
    throw InputError(fmt::format("-o {}: a report is written as .html or .pdf", o.output_path));
  CliSession cli(g);
  const auto r = services::makeReport(cli.session, services::ArchiveItem::parse(o.subject, "rcm"), o.request);
  if (o.output_path.empty()) {
    if (jsonPrinted(g, r.document())) return 0;
    *g.out << r.html;
    return 0;
  }
  if (pdf)
    services::printPdf(r.html, o.output_path);
  else
    services::writeTextFile(o.output_path, r.html);
  auto document = r.document();
  document["file"] = o.output_path;
  if (jsonPrinted(g, document)) return 0;
  *g.out << fmt::format("report written to {}: {}\n", o.output_path, r.title);
  for (const auto& f : r.figures) {
    if (f.tolerance)
      *g.out << fmt::format("  {} {:.2f} {} (tolerance {:.2f}): {}\n", f.symbol, f.value,
                            f.unit.empty() ? r.unit : f.unit, *f.tolerance, f.passed() ? "pass" : "FAIL");
  }
  return 0;
}

}  // namespace

void registerReportCommands(CliContext& c) {
  auto o = std::make_shared<ReportOptions>();
  auto* cmd = c.app->add_subcommand(
      "report", "a calibration report of a run, a campaign or a model: one self-contained HTML file, or PDF");
  cmd->add_option("SUBJECT", o->subject, "a run (12), a campaign (c3) or a model (m2)")->required();
  cmd->add_option("-o,--out", o->output_path,
                  "the report file, .html or .pdf (headless Chromium); default: HTML on stdout")
      ->check(notEmpty("a file name", "FILE"));
  cmd->add_option("--standard", o->request.standard,
                  fmt::format("the standard: {}", fmt::join(processing::positioningStandards(), ", ")))
      ->capture_default_str();
  cmd->add_option("--tolerance", o->tolerances, "a figure's tolerance in its unit, e.g. A=10 (repeat for several)");
  cmd->add_option("--after", o->request.after,
                  "linear runs: a run of the axis measured after (before/after comparison)");
  cmd->add_option("--validate", o->request.validate_runs,
                  "models: runs to check the model against (default: the runs it was identified from)");
  c.on(cmd, [&c, o] { return report(c.g, *o); });
}

}  // namespace mtcal::app
