#pragma once
// Calibration reports a customer can be handed: one self-contained HTML document (inline CSS
// and SVG, nothing fetched from anywhere), printable, from the same operations and result
// documents as the CLI. docs/reports.md.

#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "mtcal/services/session.h"

namespace mtcal::services {

struct ReportRequest {
  std::string standard = "iso230-2:2014";  ///< processing::standardNames()
  /// A figure's symbol (E, A, R, ...) -> the largest value that passes, um (urad for angles).
  std::map<std::string, double> tolerance;
  /// A second run of the same axis, measured after (e.g. with a compensation): the report
  /// sets both side by side and overlays their mean deviations.
  std::optional<storage::Id> after;
};

struct ReportFigure {
  std::string symbol, name;
  double value = 0.0;
  std::optional<double> tolerance;
  bool passed() const { return !tolerance || value <= *tolerance; }
};

struct Report {
  std::string title;
  std::string unit;  ///< of the figures: um, or urad for angular runs
  std::vector<ReportFigure> figures;
  std::string html;  ///< the whole document
  /// The title, the figures with their tolerance and verdict (not the HTML).
  nlohmann::json document() const;
};

/// The report of a linear run (and of its comparison with `request.after`). Stores the
/// analyses it makes, as `analyze linear` does.
/// @throws InputError for a run of a kind without a report yet, a tolerance for a figure the
///         standard does not have, or what `analyze linear` and `compare` refuse
Report reportRun(Session& session, storage::Id run_id, const ReportRequest& request);

/// Prints an HTML document to `pdf_path` (A4, no browser header or footer) with headless
/// Chromium (`chromium`, or the program MTCAL_CHROMIUM names), in a private temporary profile,
/// nothing fetched: the document is self-contained. Written whole or not at all.
/// @throws InputError when Chromium is missing or fails (with what it said)
void printPdf(const std::string& html, const std::string& pdf_path);

}  // namespace mtcal::services
