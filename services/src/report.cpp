#include "mtcal/services/report.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <ctime>
#include <limits>

#include "mtcal/acquisition/linear_plan.h"
#include "mtcal/error.h"
#include "mtcal/processing/number_text.h"
#include "mtcal/services/archive.h"
#include "mtcal/services/circle.h"
#include "mtcal/services/compensate.h"
#include "mtcal/services/linear.h"
#include "mtcal/services/svg_plot.h"
#include "mtcal/services/version.h"
#include "report_html.h"

namespace mtcal::services {
namespace report_html {
namespace {

/// Print and screen styles: A4 portrait, tables that do not break inside a row.
constexpr const char* kStyle = R"(
body { font-family: "DejaVu Sans", Arial, sans-serif; font-size: 10pt; color: #111; max-width: 190mm; margin: 10mm auto; }
h1 { font-size: 16pt; margin: 0 0 2mm; } h2 { font-size: 12pt; margin: 6mm 0 2mm; border-bottom: 1px solid #999; }
table { border-collapse: collapse; margin: 2mm 0; } td, th { border: 1px solid #bbb; padding: 1mm 2mm; text-align: left; }
td.num, th.num { text-align: right; font-variant-numeric: tabular-nums; white-space: nowrap; } tr { page-break-inside: avoid; }
.pass { color: #1e8449; font-weight: bold; } .fail { color: #c0392b; font-weight: bold; }
.warning { color: #a04000; } .small { font-size: 8.5pt; color: #444; }
svg { width: 100%; height: auto; } figure { margin: 2mm 0; page-break-inside: avoid; }
.signature td { height: 12mm; width: 60mm; vertical-align: bottom; }
section.run { page-break-before: always; } section.run h1 { font-size: 14pt; }
@page { size: A4; margin: 12mm; } @media print { body { margin: 0; } }
)";

/// min - max (mean) of a recorded environment quantity over the run's targets; empty: none.
std::string environmentRange(const std::vector<storage::TargetRecord>& targets,
                             std::optional<double> storage::TargetRecord::*field, const char* unit, int decimals) {
  double lo = std::numeric_limits<double>::infinity(), hi = -lo, sum = 0.0;
  int n = 0;
  for (const auto& t : targets) {
    if (!(t.*field)) continue;
    lo = std::min(lo, *(t.*field)), hi = std::max(hi, *(t.*field)), sum += *(t.*field), ++n;
  }
  if (n == 0) return "";
  return fmt::format("{0:.{1}f} to {2:.{1}f} {3} (mean {4:.{1}f})", lo, decimals, hi, unit, sum / n);
}

std::string compensationText(const std::string& compensation_json) {
  std::string out;
  const auto tables = appliedTables(compensation_json);
  for (std::size_t a = 0; a < tables.size(); ++a) {
    if (!tables[a]) continue;
    out += fmt::format("{}{}: {} table {} ({} entries)", out.empty() ? "" : "; ", "XYZ"[a], tables[a] -> controller,
                       tables[a] -> file, tables[a] -> table.position.size());
  }
  return out.empty() ? "none recorded with the run" : out;
}

std::string nowUtc() {
  const std::time_t now = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&now, &tm);
  char text[32];
  std::strftime(text, sizeof text, "%Y-%m-%d %H:%M:%S", &tm);
  return text;
}

}  // namespace

std::string cell(const std::string& text) { return "<td>" + xmlEscape(text) + "</td>"; }
std::string numberCell(const std::string& text) { return "<td class=\"num\">" + xmlEscape(text) + "</td>"; }
std::string row(const std::string& label, const std::string& value) {
  return "<tr><th>" + xmlEscape(label) + "</th>" + cell(value) + "</tr>\n";
}
std::string definitionTable(const std::vector<std::pair<std::string, std::string>>& rows) {
  std::string t = "<table>\n";
  for (const auto& [label, value] : rows) t += row(label, value);
  return t + "</table>\n";
}
std::string optionalValue(const std::optional<double>& v, const char* format) {
  if (!v) return "-";
  std::string text = fmt::format(fmt::runtime(format), *v);
  // A value that rounds to zero is shown as 0.00, not -0.00.
  if (text.starts_with('-') && text.find_first_of("123456789") == std::string::npos) text.erase(0, 1);
  return text;
}
std::string figure(const std::string& svg) { return "<figure>" + svg + "</figure>\n"; }
std::string warning(const std::string& text) { return "<p class=\"warning\">Warning: " + xmlEscape(text) + "</p>\n"; }
std::string smallNote(const std::string& text) { return "<p class=\"small\">" + xmlEscape(text) + "</p>\n"; }

std::string conditionsTable(const RunDetail& d, const Conditions& c) {
  const auto& run = d.run;
  std::string t = "<table>\n";
  t += row("Machine", run.machine_name);
  t += row("Run", fmt::format("{} '{}' (campaign c{}), {}", run.id, run.name, run.campaign_id, run.status));
  t += row("Measured", c.measured);
  std::string instruments;
  for (const auto& i : d.instruments) {
    instruments += fmt::format("{}{} {} serial {}{} ({})", instruments.empty() ? "" : "; ", i.info.kind, i.info.model,
                               i.info.serial, i.info.firmware.empty() ? "" : ", firmware " + i.info.firmware, i.role);
  }
  t += row("Instrument", instruments.empty() ? "not recorded" : instruments);
  t += row("Standard", c.standard);
  std::string environment;
  for (const auto& [label, field, unit, decimals] :
       std::initializer_list<std::tuple<const char*, std::optional<double> storage::TargetRecord::*, const char*, int>>{
           {"air", &storage::TargetRecord::air_temp_c, "°C", 2},
           {"machine", &storage::TargetRecord::material_temp_c, "°C", 2},
           {"pressure", &storage::TargetRecord::air_pressure_pa, "Pa", 0},
           {"humidity", &storage::TargetRecord::humidity_pct, "%", 1}}) {
    const auto range = environmentRange(d.targets, field, unit, decimals);
    if (!range.empty()) environment += fmt::format("{}{} {}", environment.empty() ? "" : "; ", label, range);
  }
  t += row("Environment", environment.empty() ? "not recorded" : environment);
  t += row("Compensation", compensationText(run.compensation_json));
  t += row("Date (UTC)", run.started_at + (run.finished_at ? " to " + *run.finished_at : ""));
  t += row("Operator", run.operator_name.empty() ? "not recorded" : run.operator_name);
  t += row("Software", fmt::format("recorded by {}; evaluated by mtcal {}", run.software_version, kVersion));
  t += row("Plan", c.plan);
  return t + "</table>\n";
}

std::string figureText(double value, const std::string& unit) {
  // Below a thousandth of the unit (a nanometre of um): the arithmetic's zero, e.g. a model's
  // residual on the very runs it was solved from, not a figure to two digits (1.9e-11 um).
  const std::string number = unit == "%"                              ? fmt::format("{:.1f}", value)
                             : std::abs(value) >= 0.1 || value == 0.0 ? fmt::format("{:.2f}", value)
                             : std::abs(value) < 5e-4                 ? std::string("0.000")
                                                                      : processing::significant(value, 2);
  return unit.empty() ? number : number + " " + unit;
}

std::string figuresTable(const std::vector<ReportFigure>& figures, const std::string& unit,
                         const std::vector<std::string>& where) {
  const bool judged = std::any_of(figures.begin(), figures.end(), [](const auto& f) { return f.tolerance; });
  std::string t = "<table>\n<tr><th>Figure</th><th>Definition</th><th class=\"num\">Value</th>";
  t += judged ? "<th class=\"num\">Tolerance</th><th>Verdict</th>" : "";
  t += where.empty() ? "</tr>\n" : "<th>Where</th></tr>\n";
  for (std::size_t k = 0; k < figures.size(); ++k) {
    const auto& f = figures[k];
    const std::string& u = f.unit.empty() ? unit : f.unit;
    t += "<tr>" + cell(f.symbol) + cell(f.name) + numberCell(figureText(f.value, u));
    if (judged) {
      t += f.tolerance ? numberCell(figureText(*f.tolerance, u)) : cell("");
      t += !f.tolerance ? cell("") : f.passed() ? "<td class=\"pass\">pass</td>" : "<td class=\"fail\">fail</td>";
    }
    if (!where.empty()) t += cell(k < where.size() ? where[k] : "");
    t += "</tr>\n";
  }
  return t + "</table>\n";
}

std::string eventsSection(const RunDetail& d) {
  if (d.events.empty() && d.notes.empty()) return "";
  std::string h = "<h2>Events and notes</h2>\n<table class=\"small\">\n";
  for (const auto& e : d.events) h += "<tr>" + cell(e.created_at) + cell(e.level) + cell(e.message) + "</tr>\n";
  for (const auto& n : d.notes) h += "<tr>" + cell(n.created_at) + cell("note, " + n.author) + cell(n.text) + "</tr>\n";
  return h + "</table>\n";
}

std::string document(const std::string& title, const std::string& subject, const std::string& body) {
  return "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>" + xmlEscape(title) +
         "</title>\n<style>" + kStyle + "</style>\n</head>\n<body>\n<h1>" + xmlEscape(title) + "</h1>\n" +
         fmt::format("<p class=\"small\">Report of {}, made {} UTC by mtcal {}.</p>\n", xmlEscape(subject), nowUtc(),
                     kVersion) +
         body +
         "<h2>Approval</h2>\n<table class=\"signature\">\n<tr><th>Calibrated by</th><td></td><th>Date</th>"
         "<td></td></tr>\n<tr><th>Checked by</th><td></td><th>Signature</th><td></td></tr>\n</table>\n</body>\n"
         "</html>\n";
}

/// A figure of a JSON document in words: "backlash_X_um" -> ("backlash X", "µm").
std::pair<std::string, std::string> nameAndUnit(std::string key) {
  std::string unit;
  for (const auto& [suffix, u] :
       {std::pair{"_um", "µm"}, {"_urad", "µrad"}, {"_ppm", "ppm"}, {"_ms", "ms"}, {"_mm", "mm"}, {"_deg", "°"}}) {
    if (key.ends_with(suffix)) {
      key.erase(key.size() - std::string_view(suffix).size());
      unit = u;
      break;
    }
  }
  std::replace(key.begin(), key.end(), '_', ' ');
  return {key, unit};
}

void applyTolerances(Report& report, const std::map<std::string, double>& tolerance) {
  for (const auto& [symbol, value] : tolerance) {
    const auto f = std::find_if(report.figures.begin(), report.figures.end(),
                                [&](const ReportFigure& f) { return f.symbol == symbol; });
    if (f == report.figures.end()) {
      std::string symbols;
      for (const auto& g : report.figures) symbols += (symbols.empty() ? "" : ", ") + g.symbol;
      throw InputError(fmt::format("a tolerance for '{}': the report '{}' has no such figure (its figures: {})", symbol,
                                   report.title, symbols.empty() ? "none" : symbols));
    }
    f->tolerance = value;
  }
}

}  // namespace report_html

using namespace report_html;

namespace {

std::string planText(const storage::RunInfo& run, const processing::Iso230Result& result) {
  const auto& p = result.positions;
  std::string text = fmt::format("{} targets from {:.3f} to {:.3f} mm, {} cycle(s) at the fewest", p.size(),
                                 p.front().target_mm, p.back().target_mm, result.min_cycles);
  const auto j = nlohmann::json::parse(run.plan_json, nullptr, false);
  if (run.source != "imported" && j.is_object() && j.contains("start_mm")) {
    const auto plan = acquisition::LinearPlan::fromJson(j, "stored plan");
    text += fmt::format("; plan '{}': step {:g} mm, {} cycles, {}, overrun {:g} mm, dwell {:g} s, window {:g} s",
                        plan.name, plan.step_mm, plan.repeats, plan.bidirectional ? "bidirectional" : "unidirectional",
                        plan.overrun_mm, plan.dwell_s, plan.window_s);
    if (plan.random_offset_mm > 0.0) text += fmt::format(", random offsets up to {:g} mm", plan.random_offset_mm);
    for (const auto& [axis, at] : plan.line_position_mm) text += fmt::format(", {} at {:g} mm", axis, at);
  }
  return text;
}

/// Where a per-target figure is largest: " at 320.000 mm".
std::string whereLargest(const processing::Iso230Result& r, std::optional<double> processing::Iso230Position::*field,
                         bool absolute) {
  const processing::Iso230Position* best = nullptr;
  for (const auto& p : r.positions) {
    if (!(p.*field)) continue;
    const double v = absolute ? std::abs(*(p.*field)) : *(p.*field);
    if (!best || v > (absolute ? std::abs(*(best->*field)) : *(best->*field))) best = &p;
  }
  return best ? fmt::format("at {:.3f} mm", best->target_mm) : "";
}

std::string positionsTable(const processing::Iso230Result& r, const std::string& unit) {
  std::string t = fmt::format(
      "<table class=\"small\">\n<tr><th class=\"num\">Target (mm)</th><th class=\"num\">x&#772; up ({0})</th>"
      "<th class=\"num\">x&#772; down ({0})</th><th class=\"num\">s up ({0})</th><th class=\"num\">s down ({0})</th>"
      "<th class=\"num\">B ({0})</th><th class=\"num\">R ({0})</th><th class=\"num\">cycles</th></tr>\n",
      unit);
  for (const auto& p : r.positions) {
    t += "<tr>" + numberCell(fmt::format("{:.3f}", p.target_mm)) + numberCell(optionalValue(p.mean_up_um)) +
         numberCell(optionalValue(p.mean_down_um)) + numberCell(optionalValue(p.s_up_um)) +
         numberCell(optionalValue(p.s_down_um)) + numberCell(optionalValue(p.reversal_um)) +
         numberCell(optionalValue(p.repeatability_um)) +
         numberCell(fmt::format("{} / {}", p.cycles_up, p.cycles_down)) + "</tr>\n";
  }
  return t + "</table>\n";
}

/// One direction's mean and its +-2s band (the band as one series: upper, a break, lower).
void addDirection(Plot& plot, const processing::Iso230Result& r, bool up, const std::string& colour,
                  const std::string& prefix) {
  PlotSeries mean{prefix + (up ? "mean up" : "mean down"), colour, {}, {}, PlotSeries::Style::kLine};
  PlotSeries band{prefix + (up ? "±2s up" : "±2s down"), colour, {}, {}, PlotSeries::Style::kDashed};
  for (const double side : {1.0, -1.0}) {
    for (const auto& p : r.positions) {
      const auto& m = up ? p.mean_up_um : p.mean_down_um;
      const auto& s = up ? p.s_up_um : p.s_down_um;
      if (side > 0) mean.x.push_back(p.target_mm), mean.y.push_back(m ? *m : NAN);
      band.x.push_back(p.target_mm);
      band.y.push_back(m && s ? *m + side * 2.0 * *s : NAN);
    }
    band.x.push_back(NAN), band.y.push_back(NAN);
  }
  plot.series.push_back(std::move(mean));
  plot.series.push_back(std::move(band));
}

std::string deviationPlot(const RunDetail& d, const PositioningAnalysis& a, const std::string& unit) {
  const auto& r = a.iso230_2.result;
  Plot plot{fmt::format("Axis {}: deviation against target, {}", d.run.axis, a.evaluation.title),
            "target (mm)",
            fmt::format("deviation ({})", unit),
            {},
            {}};
  PlotSeries up{"up", kUpColour, {}, {}}, down{"down", kDownColour, {}, {}};
  for (const auto& t : d.targets) {
    auto& s = t.direction > 0 ? up : down;
    s.x.push_back(t.target_mm), s.y.push_back(t.deviation_um);
  }
  plot.series = {up, down};
  addDirection(plot, r, true, kUpColour, "");
  addDirection(plot, r, false, kDownColour, "");
  // E spans the means, A the means +- 2s: their extremes marked.
  double mean_lo = INFINITY, mean_hi = -INFINITY, band_lo = INFINITY, band_hi = -INFINITY;
  for (const auto& p : r.positions) {
    for (const auto& [m, s] : {std::pair{p.mean_up_um, p.s_up_um}, std::pair{p.mean_down_um, p.s_down_um}}) {
      if (!m) continue;
      mean_lo = std::min(mean_lo, *m), mean_hi = std::max(mean_hi, *m);
      if (s) band_lo = std::min(band_lo, *m - 2.0 * *s), band_hi = std::max(band_hi, *m + 2.0 * *s);
    }
  }
  if (r.E_um) {
    plot.marks.push_back({mean_hi, "E = " + figureText(*r.E_um, unit), "#555"});
    plot.marks.push_back({mean_lo, "", "#555"});
  }
  if (r.A_um) {
    plot.marks.push_back({band_hi, "A = " + figureText(*r.A_um, unit), "#8e44ad"});
    plot.marks.push_back({band_lo, "", "#8e44ad"});
  }
  return "<figure>" + plotSvg(plot) + "</figure>\n";
}

std::string comparisonSection(const RunComparison& c, const std::string& unit) {
  std::string s =
      fmt::format("<h2>Before and after: run {} and run {}</h2>\n", c.before.iso230_2.run_id, c.after.iso230_2.run_id);
  for (const auto& w : c.warnings) s += "<p class=\"warning\">Warning: " + xmlEscape(w) + "</p>\n";
  s += "<table>\n<tr><th>Figure</th><th class=\"num\">Before</th><th class=\"num\">After</th>"
       "<th class=\"num\">Change</th></tr>\n";
  for (const auto& f : c.before.evaluation.figures) {
    const double after = c.after.evaluation.value(f.symbol);
    const std::string pct =
        f.value_um > 0.0 && after >= 0.0 ? fmt::format(" ({:+.0f} %)", 100.0 * (after - f.value_um) / f.value_um) : "";
    s += "<tr>" + cell(f.symbol) + numberCell(figureText(f.value_um, unit)) + numberCell(figureText(after, unit)) +
         numberCell((after >= f.value_um ? "+" : "") + figureText(after - f.value_um, unit) + pct) + "</tr>\n";
  }
  s += "</table>\n";
  Plot plot{
      "Mean deviation per direction, before and after", "target (mm)", fmt::format("deviation ({})", unit), {}, {}};
  addDirection(plot, c.before.iso230_2.result, true, kUpColour, "before ");
  addDirection(plot, c.before.iso230_2.result, false, kDownColour, "before ");
  addDirection(plot, c.after.iso230_2.result, true, kAfterColour, "after ");
  addDirection(plot, c.after.iso230_2.result, false, "#7d3c98", "after ");
  // The bands of both runs would hide the curves: the overlay keeps the means.
  std::erase_if(plot.series, [](const PlotSeries& p) { return p.style == PlotSeries::Style::kDashed; });
  return s + "<figure>" + plotSvg(plot) + "</figure>\n";
}

/// Where B and R are largest, for the figures table.
std::vector<std::string> whereOf(const std::vector<ReportFigure>& figures, const processing::Iso230Result& r) {
  std::vector<std::string> where;
  for (const auto& f : figures) {
    if (f.symbol == "B" || f.symbol == "Ps max")
      where.push_back(whereLargest(r, &processing::Iso230Position::reversal_um, true));
    else if (f.symbol == "R")
      where.push_back(whereLargest(r, &processing::Iso230Position::repeatability_um, false));
    else
      where.emplace_back();
  }
  return where;
}

}  // namespace

Report linearReport(Session& session, const RunDetail& detail, const ReportRequest& request) {
  const auto& run = detail.run;
  std::optional<RunComparison> comparison;
  if (request.after && *request.after == run.id)
    throw InputError(fmt::format("run {} compared with itself: the run after the correction is another run", run.id));
  if (request.after) comparison = compareRuns(session, run.id, *request.after, request.standard);
  const auto analysis = comparison ? comparison->before : analyzeLinear(session, run.id, request.standard);
  Report report;
  report.unit = run.value_unit == "urad" ? "µrad" : "µm";
  report.title = fmt::format("{}: axis {} calibration, {}", run.machine_name, run.axis, analysis.evaluation.title);
  for (const auto& f : analysis.evaluation.figures) report.figures.push_back({f.symbol, f.name, f.value_um});
  applyTolerances(report, request.tolerance);
  const auto plan = nlohmann::json::parse(run.plan_json, nullptr, false);
  const std::string measures = plan.is_object() && plan.value("measures", std::string()) != ""
                                   ? plan["measures"].get<std::string>()
                                   : fmt::format("E{0}{0}", run.axis);
  const Conditions conditions{
      fmt::format("axis {}, {}", run.axis, measures),
      analysis.evaluation.title + (analysis.evaluation.note.empty() ? "" : " (" + analysis.evaluation.note + ")"),
      planText(run, analysis.iso230_2.result)};
  std::string& h = report.html;
  h = "<h2>Test conditions</h2>\n" + conditionsTable(detail, conditions);
  h += "<h2>Results</h2>\n" +
       figuresTable(report.figures, report.unit, whereOf(report.figures, analysis.iso230_2.result));
  if (!analysis.evaluation.definitions_verified)
    h += "<p class=\"small\">The definitions of this standard were taken from secondary descriptions; see "
         "mtcal's docs/linear-calibration.md.</p>\n";
  for (const auto& w : analysis.iso230_2.warnings) h += warning(w);
  report.warnings = analysis.iso230_2.warnings;
  if (analysis.truth_E_um) {
    h += fmt::format(
        "<p class=\"small\">Simulated machine: its own static error at these targets gives E = {} and M = {} "
        "(without the per-approach scatter).</p>\n",
        figureText(*analysis.truth_E_um, report.unit), figureText(*analysis.truth_M_um, report.unit));
  }
  if (comparison) h += comparisonSection(*comparison, report.unit);
  h += deviationPlot(detail, analysis, report.unit);
  h += "<h2>Per target</h2>\n" + positionsTable(analysis.iso230_2.result, report.unit);
  return report;
}

Report circleReport(Session& session, const RunDetail& detail, const ReportRequest& request) {
  const auto& run = detail.run;
  const auto iso = analyzeIso230_4(session, run.id);
  const auto ballbar = analyzeBallbar(session, run.id);
  const auto iso_doc = iso.document(), ballbar_doc = ballbar.document();
  Report report;
  report.unit = "µm";
  const std::string plane = iso_doc.value("plane", std::string("XY"));
  report.title = fmt::format("{}: circular test in {}, ISO 230-4", run.machine_name, plane);
  for (const auto& [symbol, key, name] : {std::tuple{"G ccw", "G_ccw_um", "circular deviation, counter-clockwise"},
                                          {"G cw", "G_cw_um", "circular deviation, clockwise"},
                                          {"G", "G_um", "circular deviation (bidirectional G(b) when both directions)"},
                                          {"H", "H_um", "circular hysteresis"}}) {
    if (iso_doc.contains(key) && iso_doc[key].is_number())
      report.figures.push_back({symbol, name, iso_doc[key].get<double>()});
  }
  applyTolerances(report, request.tolerance);
  std::string h;
  std::string points;
  for (const auto& [path, name] : {std::pair{&iso.result.ccw, "ccw"}, std::pair{&iso.result.cw, "cw"}}) {
    if (*path)
      points += fmt::format("{}{} {} points over {:.0f}°", points.empty() ? "" : ", ", name, (*path)->points,
                            (*path)->angle_span_deg);
  }
  const Conditions conditions{
      fmt::format("{} plane, radius {:.3f} mm, feed {:g} mm/min", plane, iso.setting.radius_mm,
                  iso.setting.feed_mm_per_min),
      "ISO 230-4 (circular tests; the edition is not checked by mtcal); the ballbar diagnosis by mtcal's "
      "signature fit (docs/ballbar.md)",
      points};
  h += "<h2>Test conditions</h2>\n" + conditionsTable(detail, conditions);
  h += "<h2>Results (ISO 230-4)</h2>\n" + figuresTable(report.figures, report.unit);
  std::vector<std::pair<std::string, std::string>> centre;
  for (const auto& [key, value] : iso_doc.items()) {
    if (!key.starts_with("centre_") || !value.is_number()) continue;
    const auto [name, unit] = nameAndUnit(key);
    centre.emplace_back(name + " (least-squares, both paths)", figureText(value.get<double>(), unit));
  }
  if (!centre.empty()) h += definitionTable(centre);
  PolarPlot polar{
      fmt::format("Radial deviation, {} plane (magnified)", plane), "µm", plane.substr(0, 1), plane.substr(1, 1), {}};
  for (const auto direction : {processing::CircleDirection::kCcw, processing::CircleDirection::kCw}) {
    PolarSeries series{processing::directionName(direction),
                       direction == processing::CircleDirection::kCcw ? kUpColour : kDownColour,
                       {},
                       {}};
    for (const auto& p : iso.points) {
      if (p.direction != direction) continue;
      series.angle_rad.push_back(p.angle_rad);
      series.deviation.push_back(p.deviation_um);
    }
    if (!series.angle_rad.empty()) polar.series.push_back(std::move(series));
  }
  h += figure(polarPlotSvg(polar));
  h += "<h2>Ballbar diagnosis</h2>\n<table>\n<tr><th>Signature</th><th class=\"num\">Value</th></tr>\n";
  for (const auto& [key, value] : ballbar_doc["diagnosis"].items()) {
    const auto [name, unit] = nameAndUnit(key);
    const std::string shown = value.is_number()   ? figureText(value.get<double>(), unit)
                              : value.is_string() ? value.get<std::string>()
                                                  : "not detected";
    h += "<tr>" + cell(name) + numberCell(shown) + "</tr>\n";
  }
  h += fmt::format(
      "</table>\n<p class=\"small\">Radial deviation about each path's least-squares circle: {} rms before the "
      "signatures, {} after.</p>\n",
      figureText(ballbar.diagnosis.rms_before_um, "µm"), figureText(ballbar.diagnosis.rms_after_um, "µm"));
  for (const auto& n : ballbar.diagnosis.notes) h += smallNote(n);
  report.html = std::move(h);
  return report;
}

nlohmann::json Report::document() const {
  nlohmann::json list = nlohmann::json::array();
  for (const auto& f : figures) {
    nlohmann::json j{
        {"symbol", f.symbol}, {"name", f.name}, {"value", f.value}, {"unit", f.unit.empty() ? unit : f.unit}};
    if (f.tolerance) j["tolerance"] = *f.tolerance, j["passed"] = f.passed();
    list.push_back(j);
  }
  return {{"schema_version", 1}, {"title", title}, {"unit", unit}, {"figures", list}, {"warnings", warnings}};
}

namespace {

/// The document of a run's report: its body and its events.
Report runReport(Session& session, storage::Id run_id, const ReportRequest& request) {
  const auto detail = showRun(session, run_id);
  const auto& kind = detail.run.kind;
  if (kind != storage::run_kind::kLinear && (request.after || request.standard != ReportRequest{}.standard)) {
    throw InputError(fmt::format("run {} is {}: --after and --standard are for linear runs", run_id,
                                 storage::run_kind::aRunOf(kind)));
  }
  Report report = kind == storage::run_kind::kLinear   ? linearReport(session, detail, request)
                  : kind == storage::run_kind::kCircle ? circleReport(session, detail, request)
                  : kind == storage::run_kind::kEst    ? estReport(session, detail, request)
                  : kind == storage::run_kind::kGantry ? gantryReport(session, detail, request)
                                                       : thermalReport(session, detail, request);
  const auto& status = detail.run.status;
  // (A linear run's analysis says so itself, with the targets measured.)
  if (kind != storage::run_kind::kLinear && status != storage::run_status::kCompleted &&
      status != storage::run_status::kImported) {
    report.warnings.insert(report.warnings.begin(),
                           fmt::format("run {} is {}: the report holds what it recorded so far", run_id,
                                       detail.run.stale ? "interrupted" : status));
    report.html = warning(report.warnings.front()) + report.html;
  }
  report.html += eventsSection(detail);
  return report;
}

}  // namespace

Report makeReport(Session& session, const ArchiveItem& what, const ReportRequest& request) {
  if (what.model && (request.after || request.standard != ReportRequest{}.standard))
    throw InputError("a model's report takes no --after or --standard (they are for linear runs)");
  if (!what.model && !request.validate_runs.empty())
    throw InputError("--validate is for a model's report (mN): runs are checked against a model");
  Report report;
  std::string subject;
  if (what.model) {
    report = modelReport(session, *what.model, request);
    subject = fmt::format("model {}", *what.model);
  } else if (what.run) {
    report = runReport(session, *what.run, request);
    subject = fmt::format("run {}", *what.run);
  } else {
    // A campaign: each run's report in turn, its figures named after the run.
    const auto runs = runsOf(session, what);
    if (runs.empty()) throw InputError(fmt::format("campaign c{} has no runs to report", *what.campaign));
    if (request.after || !request.tolerance.empty())
      throw InputError("a campaign's report takes no --after or --tolerance (give them for one run)");
    report.title = fmt::format("{}: campaign c{} '{}', {} run(s)", runs.front().machine_name, *what.campaign,
                               runs.front().campaign_name, runs.size());
    subject = fmt::format("campaign c{}", *what.campaign);
    std::string contents = "<h2>Runs</h2>\n<table>\n<tr><th>Run</th><th>Kind</th><th>Name</th><th>Report</th></tr>\n";
    std::string sections;
    for (const auto& run : runs) {
      std::string made = "included below";
      try {
        auto part = runReport(session, run.id, request);
        for (const auto& w : part.warnings) report.warnings.push_back(fmt::format("run {}: {}", run.id, w));
        for (auto f : part.figures) {
          f.symbol = fmt::format("run {} {}", run.id, f.symbol);
          if (f.unit.empty()) f.unit = part.unit;
          report.figures.push_back(std::move(f));
        }
        sections += "<section class=\"run\">\n<h1>" + xmlEscape(fmt::format("Run {}: {}", run.id, part.title)) +
                    "</h1>\n" + part.html + "</section>\n";
      } catch (const InputError& e) {
        made = std::string("none: ") + e.what();
      }
      contents += "<tr>" + cell(std::to_string(run.id)) + cell(run.kind + (run.axis.empty() ? "" : " " + run.axis)) +
                  cell(run.name) + cell(made) + "</tr>\n";
    }
    report.html = contents + "</table>\n" + sections;
  }
  report.html = document(report.title, subject, report.html);
  return report;
}

Report diagnosisReport(Session& session, const DiagnosisAnalysis& analysis) {
  Report report = diagnosisBody(session, analysis);
  report.html = document(report.title, analysis.data.source, report.html);
  return report;
}

}  // namespace mtcal::services
