// The calibration report of a linear run: what it states (the figures as the analysis gives
// them, to 0.01 um, the verdicts), what it draws (every deviation a point), that it asks no
// other host for anything, the before/after comparison, the refusals, and its PDF through
// headless Chromium read back with poppler's pdftotext.
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
#include "mtcal/services/linear.h"
#include "mtcal/services/report.h"
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

TEST(ReportService, ALinearRunsReportStatesDrawsAndJudgesItsFigures) {
  const mtcal::testing::TempDir dir;
  Session session(mtcal::testing::onArchive(dir.file("r.sqlite")));
  const auto run = runLinear(session, mtcal::testing::smallLinearRun(3, 400.0)).runs.front();
  ASSERT_EQ(run.status, "completed");
  const auto analysis = analyzeLinear(session, run.run_id, "iso230-2:2014");
  ReportRequest request;
  request.tolerance = {{"E", 100.0}, {"R", 0.001}};
  const auto report = reportRun(session, run.run_id, request);
  const auto& html = report.html;

  EXPECT_TRUE(html.starts_with("<!DOCTYPE html>"));
  EXPECT_NE(html.find("<h1>" + report.title + "</h1>"), std::string::npos);
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
  EXPECT_NE(html.find("<td class=\"pass\">pass</td>"), std::string::npos);
  // 3 targets x 2 cycles per direction: 6 points each; the test conditions name the instrument.
  EXPECT_EQ(pointsOf(html, "up"), 6u);
  EXPECT_EQ(pointsOf(html, "down"), 6u);
  // Each point's values on hover: its target and deviation.
  EXPECT_NE(html.find("<title>target (mm) 50: "), std::string::npos);
  EXPECT_NE(html.find("interferometer MTCAL-LI1 (emulated) serial EMU0001"), std::string::npos);
  EXPECT_NE(html.find("3 targets from 50.000 to 90.000 mm"), std::string::npos);
  // Self-contained: no source, link or address but the SVG namespace.
  EXPECT_EQ(html.find(" src="), std::string::npos);
  EXPECT_EQ(html.find(" href="), std::string::npos);
  EXPECT_EQ(std::regex_replace(html, std::regex("xmlns=\"http://www.w3.org/2000/svg\""), "").find("http"),
            std::string::npos);
  // No number printed with more than the precision asked for (e.g. 4.9159999999972115).
  EXPECT_FALSE(std::regex_search(html, std::regex(">[-+]?[0-9]+\\.[0-9]{5,}")));

  // Before and after: both runs' figures side by side, the overlay of their means.
  const auto second = runLinear(session, mtcal::testing::smallLinearRun(4, 400.0)).runs.front();
  request.after = second.run_id;
  const auto compared = reportRun(session, run.run_id, request);
  EXPECT_NE(compared.html.find(fmt::format("Before and after: run {} and run {}", run.run_id, second.run_id)),
            std::string::npos);
  EXPECT_NE(compared.html.find("data-name=\"after mean up\""), std::string::npos);

  // Refusals.
  request.after.reset();
  request.tolerance = {{"Q", 1.0}};
  EXPECT_THROW(
      {
        try {
          reportRun(session, run.run_id, request);
        } catch (const InputError& e) {
          EXPECT_NE(std::string(e.what()).find("a tolerance for 'Q': ISO 230-2:2014 has no such figure"),
                    std::string::npos);
          throw;
        }
      },
      InputError);
  const auto est = importEst(session, MTCAL_EXAMPLES_DIR "/est/guideway_400mm.csv", 20.0, "", "imported");
  try {
    reportRun(session, est.run_id, {});
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("is a est run: reports are made of linear and circle runs so far"),
              std::string::npos)
        << e.what();
  }
}

// A circular test's report: ISO 230-4's figures as its analysis gives them, the polar plot of
// both directions with every point, the ballbar's signatures.
TEST(ReportService, ACircularTestsReportHasItsPolarPlotAndSignatures) {
  const mtcal::testing::TempDir dir;
  Session session(mtcal::testing::onArchive(dir.file("r.sqlite")));
  const auto circle = runCircle(session, mtcal::testing::quickCircleRequest());
  ASSERT_EQ(circle.status, "completed");
  const auto iso = analyzeIso230_4(session, circle.run_id);
  const auto report = reportRun(session, circle.run_id, {});
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
  EXPECT_FALSE(std::regex_search(report.html, std::regex(">[-+]?[0-9]+\\.[0-9]{5,}")));
  ReportRequest wrong;
  wrong.tolerance = {{"G", 10.0}};
  EXPECT_THROW(reportRun(session, circle.run_id, wrong), InputError);
}

TEST(ReportService, ThePdfHasTheReportsPages) {
  if (mtcal::testing::commandOutput("command -v chromium").empty() ||
      mtcal::testing::commandOutput("command -v pdftotext").empty())
    GTEST_SKIP() << "chromium or pdftotext is not installed (scripts/setup installs both)";
  const mtcal::testing::TempDir dir;
  Session session(mtcal::testing::onArchive(dir.file("r.sqlite")));
  const auto run = runLinear(session, mtcal::testing::smallLinearRun(3, 400.0)).runs.front();
  const auto report = reportRun(session, run.run_id, {});
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
}

}  // namespace
}  // namespace mtcal::services
