// Calibration reports of every kind: what each states (the figures as its analysis gives them,
// to 0.01, the verdicts), what it draws (every measurement a point or a vertex), that it asks
// no other host for anything, the before/after comparison, campaigns, the refusals, and the
// PDF through headless Chromium read back with poppler's pdftotext.
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <regex>

#include "../support/command_output.h"
#include "../support/temp_dir.h"
#include "mtcal/services/circle.h"
#include "mtcal/services/est.h"
#include "mtcal/services/gantry.h"
#include "mtcal/services/linear.h"
#include "mtcal/services/model.h"
#include "mtcal/services/report.h"
#include "mtcal/services/thermal.h"
#include "mtcal/services/workshop.h"
#include "service_support.h"

namespace mtcal::services {
namespace {

/// The points of one series of the SVG plots ("up", "down").
std::size_t pointsOf(const std::string& html, const std::string& series) {
  const auto start = html.find("data-name=\"" + series + "\"");
  if (start == std::string::npos) return 0;
  const auto end = html.find("</g>", start);
  std::size_t n = 0;
  for (auto at = html.find("<circle", start); at < end; at = html.find("<circle", at + 1)) ++n;
  return n;
}

/// The vertices of one line series ("profile"): its path's M and L commands.
std::size_t verticesOf(const std::string& html, const std::string& series) {
  const auto start = html.find("data-name=\"" + series + "\" d=\"");
  if (start == std::string::npos) return 0;
  const auto end = html.find('"', html.find(" d=\"", start) + 4);
  return static_cast<std::size_t>(std::count_if(html.begin() + static_cast<std::ptrdiff_t>(start),
                                                html.begin() + static_cast<std::ptrdiff_t>(end),
                                                [](char c) { return c == 'M' || c == 'L'; }));
}

Report ofRun(Session& session, storage::Id run_id, const ReportRequest& request = {}) {
  return makeReport(session, ArchiveItem{run_id, {}, {}}, request);
}

/// What every report is: one HTML document, self-contained, numbers at a sensible precision.
void expectSelfContained(const Report& report) {
  const auto& html = report.html;
  EXPECT_TRUE(html.starts_with("<!DOCTYPE html>"));
  EXPECT_NE(html.find("<h1>" + xmlEscape(report.title) + "</h1>"), std::string::npos);
  EXPECT_NE(html.find("<h2>Approval</h2>"), std::string::npos);
  // No source, link or address but the SVG namespace.
  EXPECT_EQ(html.find(" src="), std::string::npos);
  EXPECT_EQ(html.find(" href="), std::string::npos);
  EXPECT_EQ(std::regex_replace(html, std::regex("xmlns=\"http://www.w3.org/2000/svg\""), "").find("http"),
            std::string::npos);
  // No number printed with more than the precision asked for (e.g. 4.9159999999972115).
  EXPECT_FALSE(std::regex_search(html, std::regex(">[-+]?[0-9]+\\.[0-9]{5,}")));
}

/// The figure `symbol` of a report, which must have it.
const ReportFigure& figureOf(const Report& report, const std::string& symbol) {
  const auto f = std::find_if(report.figures.begin(), report.figures.end(),
                              [&](const ReportFigure& f) { return f.symbol == symbol; });
  if (f == report.figures.end()) throw std::runtime_error("the report has no figure " + symbol);
  return *f;
}

TEST(ReportService, ALinearRunsReportStatesDrawsAndJudgesItsFigures) {
  const mtcal::testing::TempDir dir;
  Session session(mtcal::testing::onArchive(dir.file("r.sqlite")));
  const auto run = runLinear(session, mtcal::testing::smallLinearRun(3, 400.0)).runs.front();
  ASSERT_EQ(run.status, "completed");
  const auto analysis = analyzeLinear(session, run.run_id, "iso230-2:2014");
  ReportRequest request;
  request.tolerance = {{"E", 100.0}, {"R", 0.001}};
  const auto report = ofRun(session, run.run_id, request);
  const auto& html = report.html;
  expectSelfContained(report);
  // Every figure of the standard, to 0.01 um, as the analysis has it.
  ASSERT_EQ(report.figures.size(), analysis.evaluation.figures.size());
  for (const auto& f : analysis.evaluation.figures)
    EXPECT_NE(html.find(fmt::format(">{:.2f} µm<", f.value_um)), std::string::npos) << f.symbol;
  // E passes 100 um; R (a few tenths of a um) fails 0.001 um.
  EXPECT_TRUE(report.figures[0].passed());
  const auto r = std::find_if(report.figures.begin(), report.figures.end(), [](auto& f) { return f.symbol == "R"; });
  ASSERT_NE(r, report.figures.end());
  EXPECT_FALSE(r->passed());
  EXPECT_NE(html.find("<td class=\"fail\">fail</td>"), std::string::npos);
  // A signed figure is judged by its size: the mean reversal either way.
  ReportFigure reversal("B mean", "mean reversal error", -2.49);
  reversal.tolerance = 2.0;
  EXPECT_FALSE(reversal.passed());
  reversal.tolerance = 2.5;
  EXPECT_TRUE(reversal.passed());
  EXPECT_NE(html.find("<td class=\"pass\">pass</td>"), std::string::npos);
  // 3 targets x 2 cycles per direction: 6 points each; the test conditions name the instrument.
  EXPECT_EQ(pointsOf(html, "up"), 6u);
  EXPECT_EQ(pointsOf(html, "down"), 6u);
  // Each point's values on hover: its series, target and deviation with their units.
  EXPECT_NE(html.find("<title>up, target (mm) 50: deviation (µm) "), std::string::npos);
  EXPECT_NE(html.find("interferometer MTCAL-LI1 (emulated) serial EMU0001"), std::string::npos);
  EXPECT_NE(html.find("3 targets from 50.000 to 90.000 mm"), std::string::npos);

  // Before and after: both runs' figures side by side, the overlay of their means.
  const auto second = runLinear(session, mtcal::testing::smallLinearRun(4, 400.0)).runs.front();
  request.after = second.run_id;
  const auto compared = ofRun(session, run.run_id, request);
  EXPECT_NE(compared.html.find(fmt::format("Before and after: run {} and run {}", run.run_id, second.run_id)),
            std::string::npos);
  EXPECT_NE(compared.html.find("data-name=\"after mean up\""), std::string::npos);
  // Seeds 3 and 4 are two simulated machines: said.
  EXPECT_NE(
      compared.html.find("the runs measured different machines: 'virtual-vmc (seed 3)' and 'virtual-vmc (seed 4)'"),
      std::string::npos)
      << compared.html.substr(compared.html.find("Before and after"), 600);

  // Refusals.
  request.after.reset();
  request.tolerance = {{"Q", 1.0}};
  EXPECT_THROW(
      {
        try {
          ofRun(session, run.run_id, request);
        } catch (const InputError& e) {
          EXPECT_NE(std::string(e.what()).find("a tolerance for 'Q': the report '" + report.title +
                                               "' has no such figure (its figures: E, E up, E down, M,"),
                    std::string::npos)
              << e.what();
          throw;
        }
      },
      InputError);

  ReportRequest validate;
  validate.validate_runs = {run.run_id};  // for models only
  EXPECT_THROW(ofRun(session, run.run_id, validate), InputError);
  // The campaign: the run's report as a section, its figures named after it.
  const auto campaign = makeReport(session, ArchiveItem::parse(fmt::format("c{}", run.campaign_id), "rcm"), {});
  expectSelfContained(campaign);
  EXPECT_NE(campaign.title.find(fmt::format("campaign c{}", run.campaign_id)), std::string::npos);
  EXPECT_NE(campaign.html.find(fmt::format("<h1>Run {}: {}</h1>", run.run_id, xmlEscape(report.title))),
            std::string::npos);
  EXPECT_EQ(figureOf(campaign, fmt::format("run {} E", run.run_id)).value, report.figures[0].value);
  EXPECT_EQ(figureOf(campaign, fmt::format("run {} E", run.run_id)).unit, "µm");
  ReportRequest tolerance;
  tolerance.tolerance = {{"E", 1.0}};
  EXPECT_THROW(makeReport(session, ArchiveItem::parse(fmt::format("c{}", run.campaign_id), "rcm"), tolerance),
               InputError);
  EXPECT_THROW(makeReport(session, ArchiveItem::parse("c99", "rcm"), {}), InputError);
}

// A probe stepping run's report: the three straightness figures as the separation gives them,
// the profile with every step, the error budget.
TEST(ReportService, AProbeSteppingRunsReportHasItsProfileAndBudget) {
  const mtcal::testing::TempDir dir;
  Session session(mtcal::testing::onArchive(dir.file("r.sqlite")));
  const auto est = importEst(session, MTCAL_EXAMPLES_DIR "/est/guideway_400mm.csv", 20.0, "", "imported");
  const auto analysis = analyzeEst(session, est.run_id, {"three-probe", "carriage-at-rest", 0.0});
  ReportRequest request;
  request.tolerance = {{"MZ", 10.0}};
  const auto report = ofRun(session, est.run_id, request);
  expectSelfContained(report);
  EXPECT_NEAR(figureOf(report, "LSQ").value, analysis.straightness.least_squares_um, 1e-12);
  EXPECT_NEAR(figureOf(report, "MZ").value, analysis.straightness.min_zone_um, 1e-12);
  EXPECT_NEAR(figureOf(report, "EP").value, analysis.straightness.end_point_um, 1e-12);
  EXPECT_TRUE(figureOf(report, "MZ").passed());  // 5.04 um within 10 um
  EXPECT_NE(report.html.find(fmt::format(">{:.2f} µm<", analysis.straightness.min_zone_um)), std::string::npos);
  EXPECT_NE(report.html.find("three-probe method with 3 probes"), std::string::npos);
  EXPECT_NE(report.html.find("readings imported"), std::string::npos);
  EXPECT_EQ(verticesOf(report.html, "profile"), est.steps);
  EXPECT_EQ(verticesOf(report.html, "least-squares line"), 2u);
  EXPECT_NE(report.html.find("<h2>Error budget</h2>"), std::string::npos);
  // --after and --standard belong to linear runs.
  request.after = est.run_id;
  EXPECT_THROW(ofRun(session, est.run_id, request), InputError);
}

// A gantry run's report: the summary as the evaluation gives it, every hole in the map and the
// table.
TEST(ReportService, AGantryRunsReportMapsEveryHole) {
  const mtcal::testing::TempDir dir;
  Session session(mtcal::testing::onArchive(dir.file("r.sqlite")));
  const auto run = runGantry(session, mtcal::testing::quickGantryRequest());
  ASSERT_EQ(run.status, "completed");
  const auto analysis = analyzeGantry(session, run.run_id, {});
  const auto report = ofRun(session, run.run_id, {});
  expectSelfContained(report);
  const auto& all = analysis.evaluation.summaries.front();
  EXPECT_EQ(figureOf(report, "max |dP|").value, all.max_norm_um);
  EXPECT_EQ(figureOf(report, "mean |dP|").value, all.mean_norm_um);
  EXPECT_EQ(figureOf(report, "A-C squareness").unit, "µrad");
  ASSERT_TRUE(analysis.uncertainty);  // the plan's Monte Carlo
  EXPECT_EQ(figureOf(report, "U95 |dP|").value, analysis.uncertainty->max_norm_u95_um);
  const auto holes = analysis.evaluation.holes.size();
  EXPECT_EQ(holes, 12u);
  EXPECT_EQ(pointsOf(report.html, "hole (nominal)"), holes);
  EXPECT_EQ(verticesOf(report.html, "dP (XY)"), 2 * holes);
  for (const auto& hole : analysis.evaluation.holes) {
    EXPECT_NE(report.html.find(fmt::format("<td>{}</td>", hole.id)), std::string::npos) << hole.id;
    EXPECT_NE(report.html.find(fmt::format(">{:.1f}</td>", hole.dp_norm_um)), std::string::npos) << hole.id;
  }
}

// A thermal run's report: the chosen model's test RMS as the fit gives it, every sample drawn,
// each sensor a curve, the split marked.
TEST(ReportService, AThermalRunsReportDrawsTheDriftAndItsModel) {
  const mtcal::testing::TempDir dir;
  Session session(mtcal::testing::onArchive(dir.file("r.sqlite")));
  const auto imported = importThermal(session, MTCAL_EXAMPLES_DIR "/thermal/spindle-warmup-8h.csv", {});
  ThermalFitRequest fit_request;
  fit_request.target = "drift_z_um";
  const auto fit = fitThermal(session, imported.run_id, fit_request);
  const auto report = ofRun(session, imported.run_id, {});
  expectSelfContained(report);
  EXPECT_EQ(figureOf(report, "RMS test").value, fit.fit.chosen.rms_test_um);
  EXPECT_EQ(figureOf(report, "RMS baseline").value, fit.fit.baseline.rms_test_um);
  EXPECT_EQ(pointsOf(report.html, "measured"), imported.samples);
  EXPECT_EQ(verticesOf(report.html, "model (open loop)"), imported.samples);
  EXPECT_EQ(verticesOf(report.html, "train | test"), 2u);
  EXPECT_EQ(verticesOf(report.html, "residual"), imported.samples);
  for (const auto& c : imported.channels) {
    if (c.kind == "temperature") {
      EXPECT_NE(report.html.find("data-name=\"" + c.name + "\""), std::string::npos) << c.name;
    }
  }
  EXPECT_NE(report.html.find(fmt::format("split at {:.2f} h", fit.fit.split_time_s / 3600.0)), std::string::npos);
}

// A model's report: the curves with their bands over the measured range, the constants, the
// key errors, the standard deviations at the centre as the model gives them; validation runs
// refused when they do not fit the model's machine.
TEST(ReportService, AModelsReportDrawsItsCurvesWithBands) {
  const mtcal::testing::TempDir dir;
  Session session(mtcal::testing::onArchive(dir.file("r.sqlite")));
  std::string csv = "error,position_mm,value\n";
  for (int p = 50; p <= 600; p += 50) {
    for (int r = 0; r < 3; ++r) csv += fmt::format("EXX,{},{}\n", p, 0.01 * p + 0.1 * r);
  }
  csv += "EC0Y,,10\nEB0Z,,-6\nEB0Z,,-6.4\nEB0Z,,-5.6\n";
  const std::string csv_path = dir.file("curves.csv");
  writeTextFile(csv_path, csv);
  ModelFitRequest request;
  request.csv_path = csv_path;
  request.machine_path = MTCAL_EXAMPLES_DIR "/machines/vmc3-cn104200063.model.json";
  request.name = "hand-made";
  const auto stored = importModel(session, request);
  const auto keys = keyErrors(session, stored.model_id, "", 0);
  ReportRequest report_request;
  report_request.tolerance = {{"σEx", 100.0}};
  const auto report =
      makeReport(session, ArchiveItem::parse(fmt::format("m{}", stored.model_id), "rcm"), report_request);
  expectSelfContained(report);
  EXPECT_EQ(report.title, fmt::format("Geometric error model {} 'hand-made' (imported)", stored.model_id));
  EXPECT_EQ(figureOf(report, "σEx").value, keys.sigma_um(0));
  EXPECT_TRUE(figureOf(report, "σEx").passed());
  // EXX over 50..600 mm, 101 vertices, and its band (both sides); the squarenesses as constants,
  // one with the sigma of its three repeats (their standard deviation, 0.4 urad), one without.
  EXPECT_EQ(verticesOf(report.html, "EXX"), 101u);
  EXPECT_EQ(verticesOf(report.html, "EXX ±3σ"), 202u);
  EXPECT_NE(report.html.find("EC0Y = 10.00 µrad (no uncertainty known)"), std::string::npos);
  EXPECT_NE(report.html.find("EB0Z = -6.00 ± 0.40 µrad"), std::string::npos);
  EXPECT_NE(report.html.find("<td>EXX</td>"), std::string::npos);  // a key error
  // Imported: no runs to check it against, said; the terms not measured named.
  EXPECT_NE(report.html.find("<h2>Validation</h2>\n<p class=\"small\">None: "), std::string::npos);
  EXPECT_NE(report.html.find("Not measured, taken as zero with no uncertainty: 18 of the 21 error terms"),
            std::string::npos);
  EXPECT_THROW(makeReport(session, ArchiveItem::parse("m9", "rcm"), {}), InputError);
  ReportRequest wrong;
  wrong.standard = "vdi3441";  // for linear runs
  EXPECT_THROW(makeReport(session, ArchiveItem::parse(fmt::format("m{}", stored.model_id), "rcm"), wrong), InputError);
}

// A circular test's report: ISO 230-4's figures as its analysis gives them, the polar plot of
// both directions with every point, the ballbar's signatures.
TEST(ReportService, ACircularTestsReportHasItsPolarPlotAndSignatures) {
  const mtcal::testing::TempDir dir;
  Session session(mtcal::testing::onArchive(dir.file("r.sqlite")));
  const auto circle = runCircle(session, mtcal::testing::quickCircleRequest());
  ASSERT_EQ(circle.status, "completed");
  const auto iso = analyzeIso230_4(session, circle.run_id);
  const auto report = ofRun(session, circle.run_id, {});
  expectSelfContained(report);
  ASSERT_TRUE(iso.result.ccw && iso.result.cw);
  EXPECT_NE(report.html.find(fmt::format(">{:.2f} µm<", iso.result.ccw->g_um)), std::string::npos);
  EXPECT_NE(report.html.find(fmt::format(">{:.2f} µm<", *iso.result.h_um)), std::string::npos);
  EXPECT_EQ(report.figures.size(), 4u);  // G ccw, G cw, G(b), H
  EXPECT_NE(report.html.find(fmt::format("data-name=\"ccw\" data-points=\"{}\"", iso.result.ccw->points)),
            std::string::npos);
  EXPECT_NE(report.html.find(fmt::format("data-name=\"cw\" data-points=\"{}\"", iso.result.cw->points)),
            std::string::npos);
  EXPECT_NE(report.html.find("<h2>Ballbar diagnosis</h2>"), std::string::npos);
  EXPECT_NE(report.html.find("squareness"), std::string::npos);
  ReportRequest request;
  request.tolerance = {{"G", 0.01}};
  EXPECT_FALSE(figureOf(ofRun(session, circle.run_id, request), "G").passed());
  request.standard = "vdi3441";
  EXPECT_THROW(ofRun(session, circle.run_id, request), InputError);
}

TEST(ReportService, ThePdfHasTheReportsPages) {
  if (mtcal::testing::commandOutput("command -v chromium").empty() ||
      mtcal::testing::commandOutput("command -v pdftotext").empty())
    GTEST_SKIP() << "chromium or pdftotext is not installed (scripts/setup installs both)";
  const mtcal::testing::TempDir dir;
  Session session(mtcal::testing::onArchive(dir.file("r.sqlite")));
  const auto run = runLinear(session, mtcal::testing::smallLinearRun(3, 400.0)).runs.front();
  const auto report = ofRun(session, run.run_id, {});
  const std::string pdf = dir.file("report.pdf");
  printPdf(report.html, pdf);
  EXPECT_TRUE(readTextFile(pdf).starts_with("%PDF-"));
  const auto text = mtcal::testing::commandOutput("pdftotext -layout '" + pdf + "' -");
  EXPECT_NE(text.find("Test conditions"), std::string::npos) << text;
  EXPECT_NE(text.find("bidirectional systematic positioning error"), std::string::npos);
  EXPECT_NE(text.find(fmt::format("{:.2f} µm", report.figures[0].value)), std::string::npos);
  EXPECT_NE(text.find("Approval"), std::string::npos);
  const auto info = mtcal::testing::commandOutput("pdfinfo '" + pdf + "'");
  std::smatch pages;
  ASSERT_TRUE(std::regex_search(info, pages, std::regex("Pages:\\s+([0-9]+)")));
  EXPECT_GE(std::stoi(pages[1]), 2);  // A4: conditions and results, then the plot and the targets
  EXPECT_EQ(readTextFile(pdf).find("/URI"), std::string::npos);  // no link to anywhere

  // A program that is not there: said, and no file.
  setenv("MTCAL_CHROMIUM", "/nonexistent/chromium", 1);
  EXPECT_THROW(printPdf(report.html, dir.file("none.pdf")), InputError);
  unsetenv("MTCAL_CHROMIUM");
  EXPECT_FALSE(std::filesystem::exists(dir.file("none.pdf")));
  // One that never finishes: stopped at the timeout (with any helper it started), said, and no file.
  const std::string hangs = dir.file("hangs.sh");
  std::ofstream(hangs) << "#!/bin/sh\nsleep 1000 &\nsleep 1000\n";
  std::filesystem::permissions(hangs, std::filesystem::perms::owner_all);
  setenv("MTCAL_CHROMIUM", hangs.c_str(), 1);
  setenv("MTCAL_PDF_TIMEOUT_S", "0.5", 1);
  try {
    printPdf(report.html, dir.file("none.pdf"));
    ADD_FAILURE() << "a PDF from a program that never finished";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("made no PDF in 0.5 s and was stopped"), std::string::npos) << e.what();
  }
  unsetenv("MTCAL_CHROMIUM");
  unsetenv("MTCAL_PDF_TIMEOUT_S");
  EXPECT_FALSE(std::filesystem::exists(dir.file("none.pdf")));
}

}  // namespace
}  // namespace mtcal::services
