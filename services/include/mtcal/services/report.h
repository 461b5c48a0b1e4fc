#pragma once
// Calibration reports a customer can be handed: one self-contained HTML document (inline CSS
// and SVG, nothing fetched from anywhere), printable, from the same operations and result
// documents as the CLI. docs/reports.md.

#include <cmath>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "mtcal/services/archive.h"
#include "mtcal/services/diagnose.h"
#include "mtcal/services/session.h"
#include "mtcal/services/svg_plot.h"

namespace mtcal::services {

struct ReportRequest {
  std::string standard = "iso230-2:2014";  ///< linear runs: processing::standardNames()
  /// A figure's symbol (E, A, R, G, ...) -> the largest value that passes, in the figure's unit.
  std::map<std::string, double> tolerance;
  /// A second run of the same axis, measured after (e.g. with a compensation): the report
  /// sets both side by side and overlays their mean deviations.
  std::optional<storage::Id> after;
  /// Model reports: runs the model is checked against (none: the runs it was identified from,
  /// which shows how well it fits them, not how well it predicts).
  std::vector<storage::Id> validate_runs;
};

struct ReportFigure {
  ReportFigure(std::string symbol_, std::string name_, double value_, std::string unit_ = "")
      : symbol(std::move(symbol_)), name(std::move(name_)), value(value_), unit(std::move(unit_)) {}
  std::string symbol, name;
  double value = 0.0;
  std::string unit;  ///< empty: the report's
  std::optional<double> tolerance;
  /// Within the tolerance by its size (a signed figure such as the mean reversal either way).
  bool passed() const { return !tolerance || std::abs(value) <= *tolerance; }
};

struct Report {
  std::string title;
  std::string unit;  ///< of the figures without their own: µm, or µrad for angular runs
  std::vector<ReportFigure> figures;
  std::vector<std::string> warnings;  ///< what limits the figures (an unfinished run, too few cycles ...)
  std::string html;                   ///< the whole document
  /// The title, the figures with their unit, tolerance and verdict, the warnings (not the HTML).
  nlohmann::json document() const;
};

/// The report of a run (linear, circle, EST, gantry, thermal), a campaign (each run's report
/// in turn) or a model. Stores the analyses it makes, as `mtcal analyze` does (not in a
/// read-only session).
/// @throws InputError for a subject that does not exist or cannot be analysed, a tolerance for
///         a figure the report does not have, --after or --standard for other than a linear run
Report makeReport(Session& session, const ArchiveItem& what, const ReportRequest& request);

/// The report of a diagnosis (`mtcal diagnose --report`): the findings in words, the residual
/// before and after, the held-out gain and the checks on other runs.
Report diagnosisReport(Session& session, const DiagnosisAnalysis& analysis);
/// The diagnosis' plots, each with its file name: the residual before and after the findings
/// against the main variable (and time when the data have it), fitted and held out.
std::vector<std::pair<std::string, Plot>> diagnosisPlots(const processing::DiagnosisData& data,
                                                         const processing::Diagnosis& diagnosis);

/// Prints an HTML document to `pdf_path` (A4, no browser header or footer) with headless
/// Chromium (`chromium`, or the program MTCAL_CHROMIUM names), in a private temporary profile,
/// nothing fetched: the document is self-contained. Written whole or not at all.
/// @throws InputError when Chromium is missing or fails (with what it said)
void printPdf(const std::string& html, const std::string& pdf_path);
/// The same PDF as bytes (the dashboard's download).
std::string pdfOf(const std::string& html);
/// Stops the Chromium now printing, with its helpers (none: nothing). Async-signal-safe: for a
/// signal handler that ends the process at once.
void stopPdfRendering() noexcept;

}  // namespace mtcal::services
