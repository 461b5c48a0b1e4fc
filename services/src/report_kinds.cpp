// The reports of probe stepping (EST), gantry, thermal runs, of models and of diagnoses: each
// from the same service operation and result document as the CLI (docs/reports.md).

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cctype>
#include <cmath>

#include "mtcal/acquisition/error_models.h"
#include "mtcal/acquisition/est_run.h"
#include "mtcal/acquisition/thermal_data.h"
#include "mtcal/error.h"
#include "mtcal/services/diagnose.h"
#include "mtcal/services/est.h"
#include "mtcal/services/gantry.h"
#include "mtcal/services/model.h"
#include "mtcal/services/thermal.h"
#include "report_html.h"

namespace mtcal::services {

using namespace report_html;

namespace {

constexpr const char* kPalette[] = {"#1f5fa8", "#c0392b", "#1e8449", "#7d3c98", "#d68910",
                                    "#17a589", "#566573", "#a93226", "#2874a6", "#b7950b"};
const char* colour(std::size_t k) { return kPalette[k % std::size(kPalette)]; }

std::string um(double v) { return figureText(v, "µm"); }
std::vector<double> values(const Eigen::VectorXd& v) { return {v.data(), v.data() + v.size()}; }

// ---- EST --------------------------------------------------------------------------------

}  // namespace

Report estReport(Session& session, const RunDetail& detail, const ReportRequest& request) {
  const auto& run = detail.run;
  const auto plan = acquisition::EstPlan::fromJson(nlohmann::json::parse(run.plan_json), "the run's plan");
  EstMethod method;
  method.method = plan.probes == 3 ? "three-probe" : "two-probe";
  const auto a = analyzeEst(session, run.id, method);
  Report report;
  report.unit = "µm";
  report.warnings = a.warnings;
  report.title = fmt::format("{}: straightness of the {} guideway in {}, error separation", run.machine_name, plan.axis,
                             plan.measures);
  report.figures = {{"LSQ", "straightness, least-squares reference line", a.straightness.least_squares_um},
                    {"MZ", "straightness, minimum zone", a.straightness.min_zone_um},
                    {"EP", "straightness, end-point reference line", a.straightness.end_point_um}};
  applyTolerances(report, request.tolerance);
  std::string h =
      "<h2>Test conditions</h2>\n" +
      conditionsTable(
          detail,
          {fmt::format("guideway of axis {}, probes reading in {}", plan.axis, plan.measures),
           fmt::format("error separation, {} method with {} probes (docs/est.md){}", a.method.method, plan.probes,
                       a.zeroing
                           ? fmt::format("; probes zeroed on a reference flat{}: z3 - 2 z2 + z1 = {:.4f} µm taken "
                                         "off the three-probe combination",
                                         a.zeroing->method == "given" ? " (readings given with the file)" : "",
                                         a.zeroing->combinationUm())
                       : plan.probes == 3 ? std::string("; probes not zeroed")
                                          : std::string()),
           fmt::format("{} steps of {:g} mm from {:g} mm, probe spacing {:g} mm, {}", plan.points, plan.step_mm,
                       plan.start_mm, plan.spacing_mm,
                       run.source == "imported"
                           ? std::string("readings imported")
                           : fmt::format("{} readings per step after {:g} s", plan.readings_per_step, plan.settle_s))});
  h += "<h2>Results</h2>\n" + figuresTable(report.figures, report.unit);
  for (const auto& w : a.warnings) h += warning(w);
  const auto& r = a.result;
  // The least-squares line of the profile, drawn with it.
  const auto n = static_cast<double>(r.x_mm.size());
  double sx = 0, sy = 0, sxx = 0, sxy = 0;
  for (std::size_t k = 0; k < r.x_mm.size(); ++k) {
    sx += r.x_mm[k], sy += r.profile_um[k], sxx += r.x_mm[k] * r.x_mm[k], sxy += r.x_mm[k] * r.profile_um[k];
  }
  const double slope = (n * sxy - sx * sy) / (n * sxx - sx * sx), offset = (sy - slope * sx) / n;
  Plot profile{fmt::format("Guideway profile S (separated), {} method", a.method.method),
               fmt::format("{} (mm)", plan.axis),
               "straightness (µm)",
               {{"profile", kUpColour, r.x_mm, r.profile_um, PlotSeries::Style::kLine},
                {"least-squares line",
                 kGreyColour,
                 {r.x_mm.front(), r.x_mm.back()},
                 {offset + slope * r.x_mm.front(), offset + slope * r.x_mm.back()},
                 PlotSeries::Style::kDashed}}};
  if (a.noise_um.size() == r.x_mm.size()) {
    PlotSeries band{"±2σ of the readings' scatter", kDownColour, {}, {}, PlotSeries::Style::kDashed};
    for (const double side : {1.0, -1.0}) {
      for (std::size_t k = 0; k < r.x_mm.size(); ++k) {
        band.x.push_back(r.x_mm[k]);
        band.y.push_back(r.profile_um[k] + side * 2.0 * a.noise_um[k]);
      }
      band.x.push_back(NAN), band.y.push_back(NAN);
    }
    profile.series.push_back(std::move(band));
  }
  h += figure(plotSvg(profile));
  if (!r.carriage_um.empty()) {
    h += figure(plotSvg({"Carriage motion R (separated)",
                         fmt::format("{} (mm)", plan.axis),
                         fmt::format("carriage translation in {} (µm)", plan.measures),
                         {{"carriage", kAfterColour, r.x_mm, r.carriage_um, PlotSeries::Style::kLine}}}));
  }
  h += "<h2>Error budget</h2>\n<table>\n<tr><th>Contribution</th><th>Effect on the profile</th>"
       "<th class=\"num\">Size</th></tr>\n";
  if (!a.noise_um.empty()) {
    h += "<tr>" + cell("readings' scatter (this run, pooled s of the step means, propagated)") +
         cell("grows along the guideway") + numberCell(fmt::format("{} at the far end (1σ)", um(a.noise_um.back()))) +
         "</tr>\n";
  }
  h += "<tr>" + cell("probe zero offsets") + cell("a line: the straightness figures do not change") + numberCell("0") +
       "</tr>\n";
  if (a.method.method == "two-probe") {
    h += "<tr>" + cell("carriage yaw (not measured by two probes)") +
         cell(fmt::format("-spacing x sum of the yaw: {:.4f} µm per µrad per step", plan.spacing_mm * 1e-3)) +
         numberCell("not measured") + "</tr>\n";
  }
  h += "<tr>" + cell("probe spacing and step length errors") + cell("first order in the profile's slope") +
       numberCell("not measured") + "</tr>\n</table>\n";
  h += smallNote(
      "The contributions not measured in this run are bounded in docs/est.md (the paper's budget, combined linearly, "
      "as GUM root sum of squares and by Monte Carlo).");
  if (!r.lost_wavelengths_mm.empty()) {
    h += warning(
        fmt::format("the frequency method cannot see wavelengths {} mm", fmt::join(r.lost_wavelengths_mm, " mm, ")));
  }
  report.html = std::move(h);
  return report;
}

// ---- Gantry -------------------------------------------------------------------------------

Report gantryReport(Session& session, const RunDetail& detail, const ReportRequest& request) {
  const auto& run = detail.run;
  const auto a = analyzeGantry(session, run.id, {});
  const auto& e = a.evaluation;
  Report report;
  report.unit = "µm";
  report.title = fmt::format("{}: point accuracy with a laser tracker", run.machine_name);
  const auto& all = e.summaries.front();
  report.figures = {{"mean |dP|", "mean length of the holes' deviation vectors", all.mean_norm_um},
                    {"max |dP|", fmt::format("largest deviation vector (hole {})", all.worst_hole), all.max_norm_um},
                    {"max dP⊥", "largest deviation across the tool axis", all.max_perp_um},
                    {"gantry line", "straightness of the tracked gantry passes (rms)", e.gantry_line_rms_um},
                    {"A-C squareness", "angle between the A and C axes minus 90°", e.axes_squareness_urad, "µrad"}};
  if (a.uncertainty) {
    report.figures.push_back(
        {"U95 |dP|", fmt::format("largest 95 % uncertainty of |dP| ({} Monte Carlo trials)", a.uncertainty->trials),
         a.uncertainty->max_norm_u95_um});
  }
  applyTolerances(report, request.tolerance);
  std::string h =
      "<h2>Test conditions</h2>\n" +
      conditionsTable(detail, {fmt::format("{} holes, gantry positions {}", e.holes.size(), e.summaries.size() - 1),
                               fmt::format("gantry point accuracy (CN106017326, docs/gantry.md), target fit "
                                           "{}, TCP0 from {}",
                                           e.target_fit, a.options.tcp0),
                               a.title});
  h += "<h2>Results</h2>\n" + figuresTable(report.figures, report.unit);
  // The hole map: each hole with its dP vector (XY part) and its 95 % circle, magnified.
  double span = 1.0, largest = 0.0;
  double lo_x = INFINITY, hi_x = -INFINITY, lo_y = INFINITY, hi_y = -INFINITY;
  for (const auto& hole : e.holes) {
    lo_x = std::min(lo_x, hole.np_mm.x()), hi_x = std::max(hi_x, hole.np_mm.x());
    lo_y = std::min(lo_y, hole.np_mm.y()), hi_y = std::max(hi_y, hole.np_mm.y());
    largest = std::max(largest, hole.dp_um.head<2>().norm());
  }
  span = std::max({hi_x - lo_x, hi_y - lo_y, 1.0});
  const double magnification = largest > 0.0 ? 0.08 * span * 1000.0 / largest : 1.0;  // mm drawn per mm of dP
  PlotSeries holes{"hole (nominal)", "#111111", {}, {}},
      vectors{"dP (XY)", kDownColour, {}, {}, PlotSeries::Style::kLine},
      circles{"95 % uncertainty of dP", kUpColour, {}, {}, PlotSeries::Style::kDashed};
  for (std::size_t k = 0; k < e.holes.size(); ++k) {
    const auto& hole = e.holes[k];
    const double x = hole.np_mm.x(), y = hole.np_mm.y();
    holes.x.push_back(x), holes.y.push_back(y);
    const double tx = x + magnification * hole.dp_um.x() * 1e-3, ty = y + magnification * hole.dp_um.y() * 1e-3;
    vectors.x.insert(vectors.x.end(), {x, tx, NAN});
    vectors.y.insert(vectors.y.end(), {y, ty, NAN});
    if (a.uncertainty && k < a.uncertainty->holes.size()) {
      const double radius = magnification * a.uncertainty->holes[k].norm_u95_um * 1e-3;
      for (int s = 0; s <= 24; ++s) {
        circles.x.push_back(tx + radius * std::cos(2.0 * M_PI * s / 24));
        circles.y.push_back(ty + radius * std::sin(2.0 * M_PI * s / 24));
      }
      circles.x.push_back(NAN), circles.y.push_back(NAN);
    }
  }
  Plot map{
      fmt::format("Hole map: dP vectors (XY) magnified {:.0f} x, with the 95 % uncertainty of |dP|", magnification),
      "X (mm)",
      "Y (mm)",
      {holes, vectors}};
  map.equal_scale = true;
  if (!circles.x.empty()) map.series.push_back(std::move(circles));
  h += figure(plotSvg(map));
  h += "<h2>Per hole</h2>\n<table class=\"small\">\n<tr><th>Hole</th><th class=\"num\">Gantry</th><th "
       "class=\"num\">NP x, y, z (mm)</th><th class=\"num\">dP x, y, z (µm)</th><th class=\"num\">|dP| (µm)</th><th "
       "class=\"num\">dP⊥ (µm)</th><th class=\"num\">U95 |dP| (µm)</th></tr>\n";
  for (std::size_t k = 0; k < e.holes.size(); ++k) {
    const auto& hole = e.holes[k];
    h += "<tr>" + cell(hole.id) + numberCell(std::to_string(hole.gantry_position)) +
         numberCell(fmt::format("{:.3f}, {:.3f}, {:.3f}", hole.np_mm.x(), hole.np_mm.y(), hole.np_mm.z())) +
         numberCell(fmt::format("{:.1f}, {:.1f}, {:.1f}", hole.dp_um.x(), hole.dp_um.y(), hole.dp_um.z())) +
         numberCell(fmt::format("{:.1f}", hole.dp_norm_um)) + numberCell(fmt::format("{:.1f}", hole.dp_perp_um)) +
         numberCell(a.uncertainty && k < a.uncertainty->holes.size()
                        ? fmt::format("{:.1f}", a.uncertainty->holes[k].norm_u95_um)
                        : "-") +
         "</tr>\n";
  }
  h += "</table>\n<h2>Per gantry position</h2>\n<table>\n<tr><th>Gantry</th><th class=\"num\">Holes</th><th "
       "class=\"num\">mean |dP|</th><th class=\"num\">max |dP|</th><th class=\"num\">rms |dP|</th><th "
       "class=\"num\">max dP⊥</th><th>Worst hole</th></tr>\n";
  for (const auto& s : e.summaries) {
    h += "<tr>" + cell(s.gantry_position == 0 ? "all" : std::to_string(s.gantry_position)) +
         numberCell(std::to_string(s.holes)) + numberCell(um(s.mean_norm_um)) + numberCell(um(s.max_norm_um)) +
         numberCell(um(s.rms_norm_um)) + numberCell(um(s.max_perp_um)) + cell(s.worst_hole) + "</tr>\n";
  }
  h += "</table>\n";
  for (const auto& note : e.notes) h += smallNote(note);
  report.html = std::move(h);
  return report;
}

// ---- Thermal ------------------------------------------------------------------------------

namespace {

std::vector<double> hours(const Eigen::VectorXd& time_s) {
  std::vector<double> h(static_cast<std::size_t>(time_s.size()));
  for (Eigen::Index i = 0; i < time_s.size(); ++i) h[static_cast<std::size_t>(i)] = time_s(i) / 3600.0;
  return h;
}

std::string candidateRow(const std::string& label, const processing::ThermalCandidate& c) {
  const auto inputs = processing::thermalInputNames(c);
  return "<tr>" + cell(label) + cell(processing::thermalFamilyName(c.family)) +
         cell(inputs.empty() ? "-" : fmt::format("{}", fmt::join(inputs, ", "))) + numberCell(um(c.cv_rms_um)) +
         numberCell(um(c.validation_rms_um)) + numberCell(um(c.validation_rms_one_step_um)) +
         numberCell(um(c.rms_train_um)) + numberCell(um(c.rms_test_um)) + numberCell(um(c.rms_test_one_step_um)) +
         numberCell(um(c.peak_test_um)) + numberCell(fmt::format("{:.3f}", c.phi)) + "</tr>\n";
}

}  // namespace

Report thermalReport(Session& session, const RunDetail& detail, const ReportRequest& request) {
  const auto& run = detail.run;
  ThermalFitRequest fit_request;
  for (const auto& c : detail.thermal_channels) {
    if (c.kind == "displacement") {
      fit_request.target = c.name;
      break;
    }
  }
  if (fit_request.target.empty()) throw InputError(fmt::format("run {} has no displacement channel", run.id));
  const auto a = fitThermal(session, run.id, fit_request);
  const auto data = acquisition::thermalDataOfRun(session.store(), run.id, fit_request.target);
  const auto& fit = a.fit;
  Report report;
  report.unit = "µm";
  report.title = fmt::format("{}: thermal drift ({}) and its model", run.machine_name, fit_request.target);
  report.figures = {{"RMS test", "open-loop residual of the chosen model on the test part", fit.chosen.rms_test_um},
                    {"peak test", "largest open-loop residual on the test part", fit.chosen.peak_test_um},
                    {"RMS baseline", "the best single sensor (static) on the test part", fit.baseline.rms_test_um}};
  applyTolerances(report, request.tolerance);
  const double split_h = fit.split_time_s / 3600.0;
  std::string h =
      "<h2>Test conditions</h2>\n" +
      conditionsTable(detail,
                      {fmt::format("{} ({}) against {} temperature sensor(s)", fit_request.target, "displacement",
                                   data.sensors.size()),
                       fmt::format("grey relational sensor selection and stepwise forward selection, "
                                   "static, AR(1) and lagged families (docs/thermal.md); first {:.0f} % of "
                                   "the rows fit, the rest test",
                                   100.0 * fit_request.train_fraction),
                       fmt::format("{} samples over {:.2f} h, split at {:.2f} h", fit.n_rows,
                                   data.time_s.size() ? data.time_s(data.time_s.size() - 1) / 3600.0 : 0.0, split_h)});
  h += "<h2>Results</h2>\n" + figuresTable(report.figures, report.unit);
  h += smallNote(fmt::format(
      "Kept model: {} ({}) with {}; test RMS {} open loop against {} for the best single sensor (gain {:.0f} %).",
      fit.chosen.method, processing::thermalFamilyName(fit.chosen.family), fmt::join(fit.chosen.sensors, ", "),
      um(fit.chosen.rms_test_um), um(fit.baseline.rms_test_um), 100.0 * fit.gain));
  const auto t = hours(data.time_s);
  Plot temperatures{"Temperatures", "time (h)", "temperature (°C)", {}};
  double t_lo = INFINITY, t_hi = -INFINITY;
  for (std::size_t s = 0; s < data.sensors.size(); ++s) {
    const auto column = values(data.temperature_c.col(static_cast<Eigen::Index>(s)));
    for (const double v : column)
      if (std::isfinite(v)) t_lo = std::min(t_lo, v), t_hi = std::max(t_hi, v);
    // Past the palette's ten colours, dashed: every sensor told apart.
    temperatures.series.push_back({data.sensors[s], colour(s), t, column,
                                   s < std::size(kPalette) ? PlotSeries::Style::kLine : PlotSeries::Style::kDashed});
  }
  if (std::isfinite(t_lo))
    temperatures.series.push_back(
        {"train | test", kGreyColour, {split_h, split_h}, {t_lo, t_hi}, PlotSeries::Style::kDashed});
  h += figure(plotSvg(temperatures));
  const auto measured = values(data.target_um), predicted = values(fit.predicted_open_loop_um);
  std::vector<double> residual(measured.size());
  double d_lo = INFINITY, d_hi = -INFINITY;
  for (std::size_t i = 0; i < measured.size(); ++i) {
    residual[i] = measured[i] - predicted[i];
    if (std::isfinite(measured[i])) d_lo = std::min(d_lo, measured[i]), d_hi = std::max(d_hi, measured[i]);
  }
  Plot drift{"Drift: measured and the model's open-loop prediction",
             "time (h)",
             fmt::format("{} (µm)", fit_request.target),
             {{"measured", kGreyColour, t, measured},
              {"model (open loop)", kUpColour, t, predicted, PlotSeries::Style::kLine}}};
  if (std::isfinite(d_lo))
    drift.series.push_back({"train | test", "#555555", {split_h, split_h}, {d_lo, d_hi}, PlotSeries::Style::kDashed});
  h += figure(plotSvg(drift));
  // The residual on a scale of its own: on the drift's it is a flat line.
  Plot rest{"Residual: measured minus the model's open-loop prediction",
            "time (h)",
            "residual (µm)",
            {{"residual", kDownColour, t, residual, PlotSeries::Style::kLine}}};
  double r_lo = INFINITY, r_hi = -INFINITY;
  for (const double r : residual)
    if (std::isfinite(r)) r_lo = std::min(r_lo, r), r_hi = std::max(r_hi, r);
  if (std::isfinite(r_lo))
    rest.series.push_back({"train | test", "#555555", {split_h, split_h}, {r_lo, r_hi}, PlotSeries::Style::kDashed});
  h += figure(plotSvg(rest));
  h += "<h2>Models compared</h2>\n" +
       smallNote(
           "Open loop: the model from the temperatures alone, what a compensation on the controller "
           "predicts (the model is kept on it). One step: plus φ times the previous measured error, "
           "which only a measured drift can feed. CV: rolling-origin cross-validation on the "
           "search's rows (the forward selection's criterion); validation: the last quarter of the training "
           "part, which no search saw (the kept model's criterion).") +
       "<table class=\"small\">\n<tr><th>Model</th><th>Family</th><th>Inputs</th><th class=\"num\">CV open "
       "loop</th><th class=\"num\">Validation open loop</th><th class=\"num\">Validation one step</th><th "
       "class=\"num\">RMS train</th><th class=\"num\">RMS test "
       "open loop</th><th class=\"num\">RMS test one step</th><th class=\"num\">peak test</th><th "
       "class=\"num\">φ</th></tr>\n";
  h += candidateRow("kept (" + fit.chosen.method + ")", fit.chosen);
  h += candidateRow("best single sensor", fit.baseline);
  if (fit.all_sensors) h += candidateRow("every sensor", *fit.all_sensors);
  for (const auto& path : fit.paths) {
    for (const auto& c : path.models)
      h += candidateRow(fmt::format("{}, {} input(s)", path.method, c.sensors.size()), c);
  }
  h +=
      "</table>\n<h2>Sensors</h2>\n<table class=\"small\">\n<tr><th>Sensor</th><th class=\"num\">Grey grade</th>"
      "<th class=\"num\">Rank</th><th class=\"num\">Correlation</th><th class=\"num\">Missing</th><th>Note</th></tr>\n";
  for (const auto& s : fit.sensors) {
    h += "<tr>" + cell(s.name) + numberCell(fmt::format("{:.3f}", s.grade)) + numberCell(std::to_string(s.rank)) +
         numberCell(fmt::format("{:+.3f}", s.correlation)) + numberCell(std::to_string(s.missing)) +
         cell(s.usable ? s.note : "not used: " + s.note) + "</tr>\n";
  }
  h += "</table>\n";
  for (const auto& note : fit.notes) h += smallNote(note);
  report.html = std::move(h);
  return report;
}

// ---- Model --------------------------------------------------------------------------------

namespace {

/// The runs a model was identified from, for its report.
std::string identifiedFromText(const IdentifyingRuns& identified) {
  if (identified.runs.empty() && identified.not_held == 0) return "imported curves";
  std::string text = identified.runs.empty() ? "" : fmt::format("runs {}", fmt::join(identified.runs, ", "));
  if (identified.not_held > 0)
    text += fmt::format("{}{} run(s) this store does not hold (pulled from the plant archive)",
                        text.empty() ? "" : " and ", identified.not_held);
  return text;
}

}  // namespace

Report modelReport(Session& session, storage::Id model_id, const ReportRequest& request) {
  const auto record = session.store().model(model_id);
  const auto model = acquisition::modelOf(record);
  const auto& kin = model.kinematics();
  const auto identified_from = identifyingRuns(record);
  const bool own_runs = request.validate_runs.empty();
  const auto runs = own_runs ? identified_from.runs : request.validate_runs;
  Report report;
  report.unit = "µm";
  report.title = fmt::format("Geometric error model {} '{}' ({})", model_id, record.name, record.method);
  const auto keys = keyErrors(session, model_id, "", 0);
  for (int c = 0; c < 3; ++c) {
    report.figures.push_back(
        {fmt::format("σE{}", "xyz"[c]),
         fmt::format("standard deviation of the volumetric error in {} at the workspace centre", "XYZ"[c]),
         keys.sigma_um(c)});
  }
  std::optional<ModelValidation> validation;
  if (!runs.empty()) {
    validation = validateModel(session, model_id, runs);
    for (const auto& line : validation->runs) {
      report.figures.push_back(
          {fmt::format("run {} RMS", line.run_id), fmt::format("{} measured minus predicted (rms)", line.measures),
           line.comparison.rms,
           line.measures.size() > 1 && std::string("ABC").find(line.measures[1]) != std::string::npos ? "µrad" : "µm"});
    }
  }
  applyTolerances(report, request.tolerance);
  std::string h = "<h2>Model</h2>\n";
  std::string centre;
  for (Eigen::Index c = 0; c < keys.at.size(); ++c)
    centre += fmt::format("{}{} {:.1f}", c ? ", " : "", kin.coordinates()[static_cast<std::size_t>(c)], keys.at(c));
  h += definitionTable({{"Model", fmt::format("{} '{}', method {}", model_id, record.name, record.method)},
                        {"Created (UTC)", record.created_at + ", mtcal " + record.software_version},
                        {"Machine", fmt::format("{} coordinates ({}), {} error terms", kin.coordinates().size(),
                                                fmt::join(kin.coordinates(), ", "), kin.terms().size())},
                        {"Identified from", identifiedFromText(identified_from)},
                        {"Key errors at", centre}});
  h += "<h2>Results</h2>\n" + figuresTable(report.figures, report.unit);
  // The error curves, translations and rotations of each axis apart, with their +-3 sigma bands.
  std::vector<std::string> constants;
  for (std::size_t coordinate = 0; coordinate < kin.coordinates().size(); ++coordinate) {
    for (const bool rotation : {false, true}) {
      Plot plot{fmt::format("{} errors along {} with ±3σ bands", rotation ? "Angular" : "Translational",
                            kin.coordinates()[coordinate]),
                fmt::format("{} ({})", kin.coordinates()[coordinate], kin.coordinates()[coordinate] < "x" ? "°" : "mm"),
                rotation ? "error (µrad)" : "error (µm)",
                {}};
      for (const auto& f : model.functions()) {
        const auto& term = kin.terms()[static_cast<std::size_t>(kin.termIndex(f.name()))];
        const bool is_rotation = term.component >= processing::ErrorComponent::kRx;
        if (is_rotation != rotation) continue;
        if (f.constant()) {
          if (coordinate == 0)
            constants.push_back(fmt::format(
                "{} = {} {}{}", f.name(), processing::valueWithUncertainty(f.value(0.0), f.sigma(0.0), " ± "),
                is_rotation ? "µrad" : "µm", f.sigma(0.0) > 0.0 ? "" : " (no uncertainty known)"));
          continue;
        }
        if (kin.coordinateOfJoint(term.joint) != static_cast<int>(coordinate)) continue;
        const auto colour_of = colour(plot.series.size() / 2);
        PlotSeries curve{f.name(), colour_of, {}, {}, PlotSeries::Style::kLine};
        PlotSeries band{f.name() + " ±3σ", colour_of, {}, {}, PlotSeries::Style::kDashed};
        const double k = processing::coverageFactor(3.0, f.degreesOfFreedom());
        const double lo = f.nodes().front(), hi = f.nodes().back();
        for (const double side : {1.0, -1.0}) {
          for (int i = 0; i <= 100; ++i) {
            const double x = lo + (hi - lo) * i / 100.0;
            if (side > 0) curve.x.push_back(x), curve.y.push_back(f.value(x));
            band.x.push_back(x), band.y.push_back(f.value(x) + side * k * f.sigma(x));
          }
          band.x.push_back(NAN), band.y.push_back(NAN);
        }
        plot.series.push_back(std::move(curve));
        plot.series.push_back(std::move(band));
      }
      if (!plot.series.empty()) h += figure(plotSvg(plot));
    }
  }
  std::vector<std::string> unmeasured;
  for (const auto& term : kin.terms()) {
    if (std::none_of(model.functions().begin(), model.functions().end(),
                     [&](const processing::ErrorFunction& f) { return f.name() == term.name; }))
      unmeasured.push_back(term.name);
  }
  if (!unmeasured.empty()) {
    h += smallNote(fmt::format("Not measured, taken as zero with no uncertainty: {} of the {} error terms ({}).",
                               unmeasured.size(), kin.terms().size(), fmt::join(unmeasured, ", ")));
  }
  if (!constants.empty()) {
    h += "<h2>Constant errors (squareness, offsets)</h2>\n<p>" +
         xmlEscape(fmt::format("{}", fmt::join(constants, "; "))) + "</p>\n";
  }
  h += "<h2>Key errors at the workspace centre</h2>\n<table class=\"small\">\n<tr><th>Error</th><th "
       "class=\"num\">share of Var(Ex)</th><th class=\"num\">Var(Ey)</th><th class=\"num\">Var(Ez)</th></tr>\n";
  for (std::size_t k = 0; k < std::min<std::size_t>(keys.keys.size(), 10); ++k) {
    const auto& key = keys.keys[k];
    h += "<tr>" + cell(key.name) + numberCell(fmt::format("{:.1f} %", 100.0 * key.share[0])) +
         numberCell(fmt::format("{:.1f} %", 100.0 * key.share[1])) +
         numberCell(fmt::format("{:.1f} %", 100.0 * key.share[2])) + "</tr>\n";
  }
  h += "</table>\n";
  if (validation) {
    h += own_runs ? "<h2>Fit to the runs it was identified from</h2>\n" +
                        smallNote(
                            "These runs made the model: their residual shows how well it fits them, not how "
                            "well it predicts. Give other runs (--validate) for a validation.")
                  : std::string("<h2>Validation</h2>\n");
    h += "<table>\n<tr><th>Run</th><th>Reading</th><th class=\"num\">Points</th><th class=\"num\">RMS</th><th "
         "class=\"num\">Peak</th><th class=\"num\">Outside the measured range</th></tr>\n";
    for (const auto& line : validation->runs) {
      const char* unit =
          line.measures.size() > 1 && std::string("ABC").find(line.measures[1]) != std::string::npos ? "µrad" : "µm";
      h += "<tr>" + cell(std::to_string(line.run_id)) + cell(line.measures) +
           numberCell(std::to_string(line.comparison.position_mm.size())) +
           numberCell(figureText(line.comparison.rms, unit)) + numberCell(figureText(line.comparison.peak, unit)) +
           numberCell(std::to_string(line.comparison.outside)) + "</tr>\n";
    }
    h += "</table>\n";
  } else {
    h += "<h2>Validation</h2>\n" +
         smallNote(
             "None: the model was not identified from stored runs and no runs were given to check it "
             "against (mtcal report mN --validate RUN ...).");
  }
  report.html = std::move(h);
  return report;
}

// ---- Diagnosis ----------------------------------------------------------------------------

std::vector<std::pair<std::string, Plot>> diagnosisPlots(const processing::DiagnosisData& data,
                                                         const processing::Diagnosis& d) {
  const std::string unit = data.value_unit == "urad" ? "µrad" : data.value_unit == "um" ? "µm" : data.value_unit;
  std::vector<std::string> variables = data.plot_variables;
  if (variables.empty()) {
    variables.push_back(data.main_variable);
    if (data.main_variable != "time_s" && data.variable("time_s")) variables.push_back("time_s");
  }
  std::vector<std::pair<std::string, Plot>> plots;
  for (const auto& name : variables) {
    // The points where the variable is known (a run's own in a fit of several), every k-th of
    // them when there are many: a plot of a long run's 75 000 points was 17 MB of SVG.
    constexpr std::size_t kMostPoints = 4000;
    const Eigen::VectorXd& all_x = data.variable(name)->values;
    std::vector<Eigen::Index> known;
    for (Eigen::Index i = 0; i < all_x.size(); ++i) {
      if (std::isfinite(all_x(i))) known.push_back(i);
    }
    const std::size_t stride = std::max<std::size_t>(1, (known.size() + kMostPoints - 1) / kMostPoints);
    std::vector<Eigen::Index> shown;
    for (std::size_t k = 0; k < known.size(); k += stride) shown.push_back(known[k]);
    const auto at = [&](const Eigen::VectorXd& v) { return values(v(shown)); };
    const auto x = at(all_x);
    const std::string thinned =
        stride > 1 ? fmt::format(" (every {}th of {} points)", stride, known.size()) : std::string();
    // A file name of letters, digits, '_' and '-' ("run 3: time_s": run-3-time_s).
    std::string file;
    for (const char ch : name) {
      const bool plain = std::isalnum(static_cast<unsigned char>(ch)) || ch == '_' || ch == '-';
      if (plain) {
        file += ch;
      } else if (!file.empty() && file.back() != '-') {
        file += '-';
      }
    }
    // A variable's name as an axis label: position_mm -> position (mm).
    std::string label = name;
    for (const auto& [suffix, of] : {std::pair{"_mm", "mm"}, {"_s", "s"}, {"_deg", "°"}, {"_c", "°C"}}) {
      if (label.ends_with(suffix)) {
        label = label.substr(0, label.size() - std::string_view(suffix).size()) + " (" + of + ")";
        break;
      }
    }
    plots.push_back(
        {fmt::format("residual-vs-{}.svg", file),
         {fmt::format("Residual before and after the findings (fitted), against {}{}", label, thinned),
          label,
          fmt::format("residual ({})", unit),
          {{"before", kGreyColour, x, at(d.residual_before)}, {"after", kUpColour, x, at(d.residual_after)}}}});
    plots.push_back(
        {fmt::format("heldout-vs-{}.svg", file),
         {fmt::format("Held-out residual before and after ({}){}", data.fold_description, thinned),
          label,
          fmt::format("held-out residual ({})", unit),
          {{"before", kGreyColour, x, at(d.heldout_before)}, {"after", kDownColour, x, at(d.heldout_after)}}}});
  }
  return plots;
}

Report diagnosisBody(Session& session, const DiagnosisAnalysis& a) {
  const auto& data = a.data;
  const auto& d = a.diagnosis;
  const std::string unit = data.value_unit == "urad" ? "µrad" : data.value_unit == "um" ? "µm" : data.value_unit;
  Report report;
  report.unit = unit;
  report.title = fmt::format("Diagnosis of {}: what the model gets wrong", data.source);
  report.figures = {{"RMS before", "held-out residual of the model alone", d.heldout_rms_um},
                    {"RMS after", "held-out residual with every finding", d.final_heldout_rms_um},
                    {"gain", "1 - after / before, held out", 100.0 * d.gain, "%"}};
  std::string h;
  // The conditions of every run of the fit (several runs: each its own).
  std::vector<storage::Id> runs = a.pooled_runs;
  if (runs.empty() && a.run_id != 0) runs.push_back(a.run_id);
  for (const auto id : runs) {
    const auto detail = showRun(session, id);
    const std::string points = runs.size() == 1 ? fmt::format("{} data, {} points", data.kind, data.measured.size())
                                                : fmt::format("{} data, one of {} runs in one fit ({} points in all)",
                                                              detail.run.kind, runs.size(), data.measured.size());
    h += (runs.size() == 1 ? std::string("<h2>Test conditions</h2>\n")
                           : fmt::format("<h2>Test conditions of run {}</h2>\n", id)) +
         conditionsTable(detail, {points, "mtcal's diagnosis (docs/diagnosis.md)", detail.run.name});
  }
  h += definitionTable(
      {{"Model", data.model_description},
       {"Baseline", data.baseline_description},
       {"Validation", data.fold_description},
       {"Chance of a finding on effect-free data", fmt::format("{:g} (family-wise)", a.options.alpha)}});
  // The evidence in the baseline's residual: what makes "something is missing" a statistical
  // statement (the text's table).
  h += "<h2>Evidence in the baseline's residual</h2>\n<p>" + xmlEscape(evidenceLegend(unit)) +
       ".</p>\n<table class=\"small\">\n<tr><th>Variable</th><th "
       "class=\"num\">Slope/unit</th><th class=\"num\">Trend p</th><th class=\"num\">Period (false "
       "alarm)</th><th class=\"num\">Durbin-Watson</th><th class=\"num\">Ljung-Box p</th></tr>\n";
  for (const auto& row : evidenceRows(data, d)) {
    h += "<tr>" + cell(row.variable) + numberCell(row.slope) + numberCell(row.trend_p) + numberCell(row.period) +
         numberCell(row.durbin_watson) + numberCell(row.ljung_box_p) + "</tr>\n";
  }
  h += "</table>\n";
  if (const auto step = directionStepText(data, d, unit)) {
    std::string sentence = *step;
    sentence.front() = static_cast<char>(std::toupper(static_cast<unsigned char>(sentence.front())));
    h += "<p>" + xmlEscape(sentence) + ".</p>\n";
  }
  h += "<h2>Findings</h2>\n";
  if (d.findings.empty())
    h += "<p>None. " + xmlEscape(nothingNamedText(d, a.options.alpha, data.pooled_runs.size() > 1)) + "</p>\n";
  // A parameter as the report writes it: "drift_over_run = -4.28 ± 0.12 µm" (the text's digits).
  const auto parameterHtml = [](const processing::ParameterValue& p) {
    const std::string unit = p.unit == "um" ? "µm" : p.unit == "urad" ? "µrad" : p.unit;
    return fmt::format("{} = {} {}", p.name, processing::valueWithUncertainty(p.value, p.standard_error, " ± "), unit);
  };
  for (std::size_t k = 0; k < d.findings.size(); ++k) {
    const auto& f = d.findings[k];
    std::string parameters;
    for (const auto& p : f.parameters) parameters += (parameters.empty() ? "" : ", ") + parameterHtml(p);
    std::string forms;
    const auto addSentence = [&forms](std::string sentence) {
      sentence.front() = static_cast<char>(std::toupper(static_cast<unsigned char>(sentence.front())));
      forms += " " + xmlEscape(sentence) + ".";
    };
    if (f.replaced_form) addSentence(replacedFormText(*f.replaced_form));
    for (const auto& o : f.other_forms) addSentence(otherFormText(o, parameterHtml));
    h += fmt::format(
        "<p><b>{}. {}</b> ({} against {}): {}. Evidence: delta BIC {:.1f}, p {}. Held out{}: RMS {} → {} {} (gain "
        "{:.1f} %), peak {} → {} {}.{}{}</p>\n",
        k + 1, xmlEscape(f.candidate.cause), xmlEscape(f.candidate.effect), xmlEscape(f.candidate.variable),
        xmlEscape(parameters), f.delta_bic, pValueText(f.p_value), xmlEscape(heldOutScope(f)),
        sizeText(f.rms_before_um), sizeText(f.rms_after_um), unit, 100.0 * f.gain, sizeText(f.peak_before_um),
        sizeText(f.peak_after_um), unit,
        f.alternatives.empty()
            ? ""
            : " Cannot be told apart from: " + xmlEscape(fmt::format("{}", fmt::join(f.alternatives, ", "))) + ".",
        forms);
  }
  h += "<h2>Residual before and after</h2>\n" + figuresTable(report.figures, unit);
  for (const auto& [name, plot] : diagnosisPlots(data, d)) h += figure(plotSvg(plot));
  if (!a.validations.empty()) {
    h += "<h2>The findings on other runs (coefficients fixed)</h2>\n<table>\n<tr><th>Run</th><th "
         "class=\"num\">Points</th><th class=\"num\">RMS before</th><th class=\"num\">RMS after</th><th "
         "class=\"num\">Gain</th><th>Left out</th></tr>\n";
    for (const auto& [run_id, v] : a.validations) {
      h += "<tr>" + cell(v.source) + numberCell(std::to_string(v.points)) +
           numberCell(figureText(v.rms_before_um, unit));
      h += !anyFindingToApply(d)
               ? "<td colspan=\"2\">no finding to apply</td>"
               : numberCell(figureText(v.rms_after_um, unit)) + numberCell(figureText(100.0 * v.gain, "%"));
      h += cell(fmt::format("{}", fmt::join(v.left_out, ", "))) + "</tr>\n";
    }
    h += "</table>\n";
  }
  for (const auto& w : d.warnings) h += warning(w);
  for (const auto& n : d.notes) h += smallNote(n);
  report.html = std::move(h);
  return report;
}

}  // namespace mtcal::services
