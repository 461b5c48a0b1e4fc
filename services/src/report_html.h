#pragma once
// The pieces every report is made of (report.cpp, report_kinds.cpp): cells and rows, the test
// conditions, the document's frame. Inside the services library only.

#include <fmt/format.h>

#include <optional>
#include <string>

#include "mtcal/services/archive.h"
#include "mtcal/services/report.h"
#include "mtcal/services/svg_plot.h"

namespace mtcal::services::report_html {

inline constexpr const char *kUpColour = "#1f5fa8", *kDownColour = "#c0392b", *kAfterColour = "#1e8449",
                            *kGreyColour = "#888888";

std::string cell(const std::string& text);
std::string numberCell(const std::string& text);
/// A figure and its unit as reports show it: to the hundredth, a percentage to the tenth, and
/// below 0.1 to two significant digits (an EST run's residual of 0.0135 um is not 0.01).
std::string figureText(double value, const std::string& unit);
/// A header cell and a value cell.
std::string row(const std::string& label, const std::string& value);
/// A table of label / value rows.
std::string definitionTable(const std::vector<std::pair<std::string, std::string>>& rows);
std::string optionalValue(const std::optional<double>& v, const char* format = "{:.2f}");
std::string figure(const std::string& svg);
std::string warning(const std::string& text);
std::string smallNote(const std::string& text);

/// What a report's test conditions say besides what every run records.
struct Conditions {
  std::string measured;  ///< "X, measuring EXX", "XY plane, radius 100 mm, F1000"
  std::string standard;  ///< with its edition, or the method
  std::string plan;
};
std::string conditionsTable(const RunDetail& d, const Conditions& c);

/// The figures with their tolerances and verdicts when any has one; `where` the place of each.
std::string figuresTable(const std::vector<ReportFigure>& figures, const std::string& unit,
                         const std::vector<std::string>& where = {});

/// The run's events and notes (empty when it has none).
std::string eventsSection(const RunDetail& d);
/// The whole document: title, who made it when, the body, the approval block.
std::string document(const std::string& title, const std::string& subject, const std::string& body);

/// Takes the requested tolerances onto the report's figures.
/// @throws InputError for a figure the report lacks, naming those it has
void applyTolerances(Report& report, const std::map<std::string, double>& tolerance);

/// A figure of a JSON document in words: "backlash_X_um" -> ("backlash X", "µm").
std::pair<std::string, std::string> nameAndUnit(std::string key);

}  // namespace mtcal::services::report_html

namespace mtcal::services {
/// The body of each kind's report (report.html is the title, the figures and the body):
/// report.cpp and report_kinds.cpp.
Report linearReport(Session& session, const RunDetail& detail, const ReportRequest& request);
Report circleReport(Session& session, const RunDetail& detail, const ReportRequest& request);
Report estReport(Session& session, const RunDetail& detail, const ReportRequest& request);
Report gantryReport(Session& session, const RunDetail& detail, const ReportRequest& request);
Report thermalReport(Session& session, const RunDetail& detail, const ReportRequest& request);
Report modelReport(Session& session, storage::Id model_id, const ReportRequest& request);
Report diagnosisBody(Session& session, const DiagnosisAnalysis& analysis);
}  // namespace mtcal::services
