#include <fmt/format.h>
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <limits>
#include <numbers>
#include <random>

#include "../support/temp_dir.h"
#include "mtcal/error.h"
#include "mtcal/services/circle.h"
#include "mtcal/services/diagnose.h"
#include "mtcal/services/thermal.h"
#include "service_support.h"

// The diagnosis through services: a circle 30 urad out of square (R 100 mm) from a file, its
// finding stored as printed; a run of another kind cannot validate it, and nothing is stored.
namespace mtcal::services {
namespace {

std::string writeCircle(const mtcal::testing::TempDir& dir) {
  const std::string csv = dir.file("circle.csv");
  std::mt19937_64 rng(3);
  std::normal_distribution<double> noise(0.0, 0.1);
  std::ofstream out(csv);
  out.precision(12);
  out << "angle_deg,direction,deviation_um\n";
  for (const char* direction : {"ccw", "cw"}) {
    for (int k = 0; k < 360; ++k) {
      // Out of square by g: the radial deviation is R g / 2 sin(2a).
      out << k << "," << direction << ","
          << 100.0e3 * 30e-6 / 2.0 * std::sin(2 * k * std::numbers::pi / 180.0) + noise(rng) << "\n";
    }
  }
  return csv;
}

// A parameter's standard error to two significant digits and the parameter to the same digit
// (GUM 7.2.6), trailing zeros kept and no exponent from 1e-6 to a million; beyond, in one power
// of ten.
TEST(DiagnoseService, AParametersTextHasItsSignificantDigits) {
  const auto text = [](double value, double standard_error) {
    return parameterText({"p", "um", value, standard_error});
  };
  EXPECT_EQ(text(1042.0, 187.0), "p = 1040 +- 190 um");   // not 1.9e+02, nor 1042
  EXPECT_EQ(text(0.3484, 0.398), "p = 0.35 +- 0.40 um");  // as a run's drift rate was said: 0.3484 +- 0.4
  EXPECT_EQ(text(5.24, 4.7), "p = 5.2 +- 4.7 um");
  EXPECT_EQ(text(-0.03, 2.5), "p = 0.0 +- 2.5 um");                 // below the error's last digit: 0.0, not -0.0
  EXPECT_EQ(text(2.5051, 0.0065), "p = 2.5051 +- 0.0065 um");       // to the error's digit (it was 2.505)
  EXPECT_EQ(text(5.000012, 0.00082), "p = 5.00001 +- 0.00082 um");  // a period found to 1 um in 5 mm
  EXPECT_EQ(text(-3.0, 0.028), "p = -3.000 +- 0.028 um");           // as 4.001 beside it, not -3
  EXPECT_EQ(text(4.0012, 0.0281), "p = 4.001 +- 0.028 um");
  EXPECT_EQ(text(9.9996, 0.5), "p = 10.00 +- 0.50 um");  // rounded up to the next power of ten
  EXPECT_EQ(text(0.74936, 0.00342), "p = 0.7494 +- 0.0034 um");
  EXPECT_EQ(text(2.5, 0.0), "p = 2.500 um");                        // no standard error: none shown
  EXPECT_EQ(text(0.0, 0.5), "p = 0.00 +- 0.50 um");                 // as 1e-9 beside it would be
  EXPECT_EQ(text(0.00237, 1.6e-5), "p = 0.002370 +- 0.000016 um");  // an EST run's zeros (it was +- 1.6e-05)
  EXPECT_EQ(text(-4.2e-6, 3.14e-5), "p = -0.000004 +- 0.000031 um");
  // Below 1e-6 or from a million, in one power of ten.
  EXPECT_EQ(text(0.0, 1e-17), "p = (0.0 +- 1.0)e-17 um");
  EXPECT_EQ(text(3.2e7, 4.56e5), "p = (3.200 +- 0.046)e7 um");
  EXPECT_EQ(text(3.2e7, 9.7e-17), "p = 3.2e+07 +- 9.7e-17 um");  // 1e23 apart: each to its own digits
  // A value that is not a number (a fit gone wrong) beside a standard error: each as it is.
  EXPECT_EQ(text(std::numeric_limits<double>::quiet_NaN(), 0.5), "p = nan +- 0.50 um");
  EXPECT_EQ(text(std::numeric_limits<double>::infinity(), 0.5), "p = inf +- 0.50 um");
}

// A diagnosis that names nothing says the model explains the run to within its scatter only where
// the residual's evidence shows neither a trend nor a correlation along any variable (p below the
// diagnosis' alpha); else it says along which.
TEST(DiagnoseService, NothingNamedSaysWhetherTheResidualStillHasStructure) {
  processing::Diagnosis d;
  d.candidates_tried = 12;
  d.evidence["position_mm"].trend_p = 0.3;
  d.evidence["position_mm"].ljung_box_p = 0.5;
  d.evidence["time_s"].trend_p = 0.02;  // above 0.01
  d.evidence["time_s"].ljung_box_p = 0.2;
  EXPECT_EQ(nothingNamedText(d, 0.01),
            "No named cause or dependence on a variable passes the test (12 tried): the model explains this run to "
            "within its scatter.");
  // But for readings far off the fit: it does not say the run is explained within its scatter.
  d.readings_off_fit.push_back({"run 3", {17, 18}, false});
  EXPECT_EQ(nothingNamedText(d, 0.01),
            "No named cause or dependence on a variable passes the test (12 tried), with 2 readings far off the fit, "
            "which the tests include and which may hide a cause (see the warnings).");
  d.readings_off_fit.clear();
  d.evidence["time_s"].ljung_box_p = 1e-9;
  d.evidence["air_temp_c"].trend_p = 0.004;
  EXPECT_EQ(nothingNamedText(d, 0.01),
            "No named cause or dependence on a variable passes the test (12 tried); the residual still has a trend or "
            "a correlation along time_s, air_temp_c (p below 0.01): what is left is none of the named causes, or too "
            "weak to be told from the model's own error.");
  // Readings far off the fit and a residual with structure: both said.
  d.readings_off_fit.push_back({"run 3", {5}, false});
  EXPECT_EQ(nothingNamedText(d, 0.01),
            "No named cause or dependence on a variable passes the test (12 tried), with one reading far off the fit, "
            "which the tests include and which may hide a cause (see the warnings); the residual still has a trend or "
            "a correlation along time_s, air_temp_c (p below 0.01): what is left is none of the named causes, or too "
            "weak to be told from the model's own error.");
  d.readings_off_fit.clear();
  // The four strongest named (the smaller of each variable's two p values), the others counted.
  for (const char* name : {"a", "b", "c", "d"}) d.evidence[name].ljung_box_p = 1e-3;
  EXPECT_NE(nothingNamedText(d, 0.01).find("along time_s, a, b, c and 2 more (p below 0.01)"), std::string::npos)
      << nothingNamedText(d, 0.01);
}

TEST(DiagnoseService, NamesTheSquarenessOfACircleAndStoresIt) {
  const mtcal::testing::TempDir dir;
  mtcal::testing::RecordingObserver observer;
  Session session({dir.file("d.sqlite"), "", &observer, nullptr, nullptr});
  acquisition::CircleImportOptions circle;
  circle.radius_mm = 100.0;
  const auto imported = importCircle(session, writeCircle(dir), circle);
  DiagnoseRequest request;
  request.run_id = imported.run_id;
  const auto a = diagnose(session, request);
  ASSERT_EQ(a.diagnosis.findings.size(), 1u) << a.document().dump(1);
  const auto& f = a.diagnosis.findings.front();
  EXPECT_EQ(f.candidate.effect, "squareness");
  ASSERT_FALSE(f.parameters.empty());
  EXPECT_NEAR(f.parameters.front().value, -30.0, 1.0);  // +(a R / 2) sin 2a: the axes closer than square
  EXPECT_EQ(f.parameters.front().unit, "urad");
  // Stored as printed, less its own id.
  const auto results = session.store().results(imported.run_id);
  ASSERT_EQ(results.size(), 1u);
  EXPECT_EQ(results.front().id, a.result_id);
  auto printed = a.document();
  printed.erase("result_id");
  EXPECT_EQ(nlohmann::json::parse(results.front().output_json), printed);
  EXPECT_EQ(printed["schema_version"], 1);
  // Progress: the search's steps, the last complete.
  ASSERT_FALSE(observer.progress.empty());
  EXPECT_EQ(observer.progress.back().done, observer.progress.back().total);
  // Counted as the search's rounds of every candidate, the number the result says was tried.
  EXPECT_EQ(observer.progress.back().what, fmt::format("tests of candidate causes (up to {} rounds of {})",
                                                       services::kDefaultMaxFindings, a.diagnosis.candidates_tried));
  EXPECT_EQ(observer.progress.back().total, static_cast<std::size_t>(services::kDefaultMaxFindings) *
                                                static_cast<std::size_t>(a.diagnosis.candidates_tried));

  // A thermal run cannot validate a circle's findings: refused before anything is stored.
  const std::string series = dir.file("series.csv");
  {
    std::ofstream out(series);
    out << "time_s,T1,drift_um\n";
    for (int i = 0; i < 20; ++i) out << 60 * i << "," << 20 + 0.1 * i << "," << 0.5 * i << "\n";
  }
  const auto thermal = importThermal(session, series, {});
  request.validate_runs = {thermal.run_id};
  try {
    diagnose(session, request);
    FAIL() << "validated a circle's findings on thermal data";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("cannot validate"), std::string::npos) << e.what();
  }
  EXPECT_EQ(session.store().results(imported.run_id).size(), 1u);
}

}  // namespace
}  // namespace mtcal::services
