// Files as people save them from spreadsheets and other programs (tests/data/dialects): each
// holds the same four readings, and each must import to the same values.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <numbers>
#include <sstream>

#include "../support/temp_dir.h"
#include "mtcal/acquisition/csv.h"
#include "mtcal/acquisition/error_models.h"
#include "mtcal/acquisition/import_linear.h"
#include "mtcal/acquisition/thermal_data.h"
#include "mtcal/error.h"

namespace mtcal::acquisition {
namespace {

const std::vector<double> kDeviations = {0.257, 0.301, -1.25, -1.2};

std::string dataFile(const std::string& name) { return std::string(MTCAL_TEST_DATA_DIR) + "/dialects/" + name; }

ParsedLinearCsv parsedFile(const std::string& name, LinearImportOptions options = {}) {
  std::ifstream in(dataFile(name), std::ios::binary);
  return parseLinearCsv(in, name, options);
}

std::string errorOf(const std::string& text, LinearImportOptions options = {}) {
  std::istringstream in(text);
  try {
    parseLinearCsv(in, "f.csv", options);
  } catch (const InputError& e) {
    return e.what();
  }
  return "no error";
}

void expectTheReadings(const ParsedLinearRun& run, double scale = 1.0, double tolerance = 1e-12) {
  ASSERT_EQ(run.targets.size(), kDeviations.size());
  for (std::size_t i = 0; i < kDeviations.size(); ++i) {
    EXPECT_NEAR(run.targets[i].deviation_um, scale * kDeviations[i], tolerance) << i;
    EXPECT_EQ(run.targets[i].cycle, static_cast<int>(i % 2 + 1));
    EXPECT_EQ(run.targets[i].direction, 1);
  }
  EXPECT_EQ(run.targets[2].target_mm, 100.0);
}

TEST(CsvDialects, EverySpreadsheetDialectImportsTheSameReadings) {
  for (const char* name : {"excel_utf8_bom.csv", "semicolon_decimal_comma.csv", "tab_separated.txt",
                           "tab_decimal_comma.txt", "header_case_spaces_units.csv", "excel_sep_quoted_trailing.csv"}) {
    SCOPED_TRACE(name);
    const auto parsed = parsedFile(name);
    ASSERT_EQ(parsed.runs.size(), 1u);
    EXPECT_EQ(parsed.runs[0].measures, "EXX");
    EXPECT_EQ(parsed.runs[0].value_unit, "um");
    EXPECT_TRUE(parsed.channel_names.empty());  // no column is left over as a channel
    expectTheReadings(parsed.runs[0]);
  }
}

TEST(CsvDialects, UnitsInHeadersAreConverted) {
  // mm -> um: 0.000257 mm is 0.257 um (the file keeps 6 decimals: 1e-9 mm rounding).
  expectTheReadings(parsedFile("deviation_in_mm.csv").runs[0], 1.0, 1e-6);
  // A pitch in arcsec: 1" = pi / 648000 rad = 4.84813681 urad.
  LinearImportOptions pitch;
  pitch.measures = "EBX";
  const auto p = parsedFile("pitch_arcsec.csv", pitch);
  EXPECT_EQ(p.runs[0].value_unit, "urad");
  expectTheReadings(p.runs[0], 4.84813681109536, 1e-9);
  // Without --measures the angle column is not read as a positioning error.
  EXPECT_NE(errorOf("target_mm,direction,cycle,deviation [arcsec]\n1,+,1,1\n1,+,2,1\n")
                .find("EXX is a length, but column 'deviation [arcsec]' is an angle"),
            std::string::npos);
  // A header without a unit, with the unit given.
  LinearImportOptions micro_radians;
  micro_radians.measures = "ECX";
  micro_radians.value_unit = "mm/m";
  std::istringstream in("target_mm,direction,cycle,deviation\n1,+,1,0.002\n1,+,2,0.004\n");
  const auto r = parseLinearCsv(in, "u.csv", micro_radians);
  EXPECT_NEAR(r.runs[0].targets[1].deviation_um, 4.0, 1e-12);  // 0.004 mm/m = 4 urad
}

TEST(CsvDialects, SixErrorsInOneFileAreSixRunsInTheirUnits) {
  const auto parsed = parsedFile("six_errors_x.csv");
  ASSERT_EQ(parsed.runs.size(), 6u);
  const std::vector<std::string> errors = {"EXX", "EYX", "EZX", "EAX", "EBX", "ECX"};
  // EXX um, EYX 2x um, EZX 3x in mm, EAX 1x arcsec, EBX 5x urad, ECX 6x in mm/m.
  const std::vector<double> scale = {1, 2, 3, 4.84813681109536, 5, 6};
  for (std::size_t e = 0; e < 6; ++e) {
    SCOPED_TRACE(errors[e]);
    EXPECT_EQ(parsed.runs[e].measures, errors[e]);
    EXPECT_EQ(parsed.runs[e].value_unit, e < 3 ? "um" : "urad");
    expectTheReadings(parsed.runs[e], scale[e], 1e-9);
  }
  // Positioning is a position; straightness and angles keep the target as the position.
  EXPECT_NEAR(parsed.runs[0].targets[0].measured_mm, 50.000257, 1e-12);
  EXPECT_EQ(parsed.runs[1].targets[0].measured_mm, 50.0);
}

TEST(CsvDialects, AColumnMappingNamesAnotherProgramsColumns) {
  EXPECT_NE(errorOf("Position,Dir,Run,Error\n50,+,1,1\n").find("the header has 'Position', 'Dir', 'Run', 'Error'"),
            std::string::npos);
  LinearImportOptions mapped;
  mapped.csv = CsvDialect::fromOptions("", "", {"target_mm=Position,direction=Dir", "cycle=Run,deviation_um=Error"});
  expectTheReadings(parsedFile("vendor_columns.csv", mapped).runs[0]);
  // A mapped header with a unit is converted.
  LinearImportOptions in_mm;
  in_mm.csv = CsvDialect::fromOptions("", "", {"deviation_um=Error [mm]"});
  std::istringstream in("target_mm,direction,cycle,Error [mm]\n1,+,1,0.001\n1,+,2,0.002\n");
  EXPECT_NEAR(parseLinearCsv(in, "m.csv", in_mm).runs[0].targets[1].deviation_um, 2.0, 1e-12);
  // The mapping may leave the header's unit out; the unit is still converted.
  LinearImportOptions unit_left_out;
  unit_left_out.csv = CsvDialect::fromOptions("", "", {"deviation_um=Error"});
  std::istringstream again("target_mm,direction,cycle,Error [mm]\n1,+,1,0.001\n1,+,2,0.002\n");
  EXPECT_NEAR(parseLinearCsv(again, "m.csv", unit_left_out).runs[0].targets[1].deviation_um, 2.0, 1e-12);
  // A mapping naming no column, and malformed mappings.
  LinearImportOptions wrong;
  wrong.csv = CsvDialect::fromOptions("", "", {"deviation_um=Fehler"});
  EXPECT_NE(errorOf("target_mm,direction,cycle,Error\n", wrong)
                .find("--columns deviation_um=Fehler: the header has no column 'Fehler'"),
            std::string::npos);
  // A mapping the import never reads (a typo) is refused, not silently unused; case aside.
  LinearImportOptions typo;
  typo.csv = CsvDialect::fromOptions("", "", {"deviaton_um=Error"});
  EXPECT_NE(errorOf("target_mm,direction,cycle,deviation_um,Error\n", typo)
                .find("--columns deviaton_um=Error: this file's format has no column 'deviaton_um'"),
            std::string::npos);
  LinearImportOptions upper;
  upper.csv = CsvDialect::fromOptions("", "", {"Target_MM=Position,direction=Dir,cycle=Run,deviation_um=Error"});
  expectTheReadings(parsedFile("vendor_columns.csv", upper).runs[0]);
  EXPECT_THROW(CsvDialect::fromOptions("", "", {"deviation_um"}), InputError);
  EXPECT_THROW(CsvDialect::fromOptions("", "", {"a=x,a=y"}), InputError);
  EXPECT_THROW(CsvDialect::fromOptions("::", "", {}), InputError);
  EXPECT_THROW(CsvDialect::fromOptions("", ";", {}), InputError);
  EXPECT_THROW(CsvDialect::fromOptions(",", ",", {}), InputError);
}

TEST(CsvDialects, WhatStaysAmbiguousIsSaidWithWhatWasRead) {
  const std::string semicolons = "target_mm;direction;cycle;deviation_um\n50;+;1;0.25\n50;+;2;0.5\n";
  LinearImportOptions comma;
  comma.csv.delimiter = ',';
  EXPECT_NE(errorOf(semicolons, comma)
                .find("the header has 1 column 'target_mm;direction;cycle;deviation_um': is ';' the separator? use "
                      "--delimiter ';'"),
            std::string::npos);
  // Both decimal marks in one file.
  EXPECT_NE(errorOf("target_mm;direction;cycle;deviation_um\n50;+;1;0,25\n50;+;2;0.5\n")
                .find("line 2 writes '0,25' with a decimal comma, line 3 '0.5' with a decimal point"),
            std::string::npos);
  // A decimal comma past the rows the detection read is named with the mark in use.
  std::string late = "target_mm;direction;cycle;deviation_um\n";
  for (int c = 1; c <= 25; ++c) late += "50;+;" + std::to_string(c) + (c < 25 ? ";1\n" : ";0,5\n");
  EXPECT_NE(errorOf(late).find("f.csv:26: column 'deviation_um': '0,5' is not a number (the decimal mark is '.'; "
                               "give --decimal , if the file writes decimal commas)"),
            std::string::npos);
  // A header without a unit where one is needed.
  EXPECT_NE(errorOf("target,direction,cycle,deviation_um\n").find("column 'target' has no unit"), std::string::npos);
  // A unit of the wrong quantity.
  EXPECT_NE(errorOf("target [s],direction,cycle,deviation_um\n").find("missing column 'target_mm'"), std::string::npos);
  // UTF-16 (Excel's "Unicode text").
  std::ifstream utf16(dataFile("utf16.csv"), std::ios::binary);
  try {
    parseLinearCsv(utf16, "utf16.csv", {});
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("UTF-16 text; save it as UTF-8"), std::string::npos) << e.what();
  }
  // A quoted cell not closed: said so, at the end of a line as in its middle (where it swallowed
  // the cells after it: "2 fields, the header has 4").
  for (const char* row : {"50,+,1,\"0.25\n", "50,\"+,1,0.25\n"}) {
    EXPECT_EQ(errorOf(std::string("target_mm,direction,cycle,deviation_um\n50,+,2,0.5\n") + row),
              "f.csv:3: a quoted cell is not closed: its '\"' has no closing '\"' on the line")
        << row;
  }
  // Two columns that read as the same name.
  EXPECT_NE(errorOf("target_mm,Target [mm],direction,cycle,deviation_um\n")
                .find("columns 'target_mm' and 'Target [mm]' both read as 'target_mm'"),
            std::string::npos);
}

TEST(CsvDialects, ARunWithOneCycleIsRefusedAtImportWithTheReason) {
  EXPECT_NE(errorOf("target_mm,direction,cycle,deviation_um\n50,+,1,0.2\n100,+,1,0.3\n100,-,1,0.1\n")
                .find("EXX has one cycle (1) only: analyze linear (ISO 230-2) and model identify estimate the "
                      "repeatability from at least 2 cycles"),
            std::string::npos);
}

TEST(CsvDialects, EveryImportReadsTheDialects) {
  // Circle points with ';', decimal commas and a BOM.
  {
    std::istringstream in(
        "\xEF\xBB\xBF"
        "Angle [deg];Direction;Deviation [µm]\n0;ccw;1,5\n90;ccw;-0,5\n");
    const auto t = readColumnTable(in, "c.csv", {"angle_deg", "deviation_um"}, {}, {"direction"});
    EXPECT_EQ(t.numbers.at("deviation_um"), (std::vector<double>{1.5, -0.5}));
    EXPECT_EQ(t.texts.at("direction")[1], "ccw");
  }
  // Probe readings, tab-separated, with the probes in mm.
  {
    std::istringstream in("x [mm]\tv1 [mm]\tv2 [mm]\n0\t0.001\t0.002\n5\t0.003\t0.004\n");
    const auto c = readColumnsCsv(in, "e.txt", {"x_mm", "v1_um", "v2_um"});
    EXPECT_NEAR(c.at("v2_um")[1], 4.0, 1e-12);
  }
  // Thermal: decimal commas, time in minutes, the drift in mm, a temperature in degC.
  {
    std::istringstream in(
        "Time [min];T spindle [°C];Drift Z [mm];T1 (front bearing)\n0;20,5;0,001;21\n1;20,7;0,002;21,5\n");
    const auto t = parseThermalCsv(in, "t.csv", {});
    ASSERT_EQ(t.channels.size(), 3u);
    EXPECT_EQ(t.channels[2].name, "T1 (front bearing)");  // a bracket that is no unit is part of the name
    EXPECT_EQ(t.channels[2].kind, "temperature");
    EXPECT_EQ(t.channels[0].name, "t_spindle");
    EXPECT_EQ(t.channels[0].kind, "temperature");
    EXPECT_EQ(t.channels[1].name, "drift_z_um");
    EXPECT_EQ(t.channels[1].kind, "displacement");
    EXPECT_DOUBLE_EQ(t.samples[1].time_s, 60.0);
    EXPECT_NEAR(*t.samples[1].values[1], 2.0, 1e-12);
    EXPECT_DOUBLE_EQ(*t.samples[1].values[0], 20.7);
  }
  // Error curves with ';' and decimal commas.
  {
    std::istringstream in("Error;Position mm;Value\nEXX;0;0,5\nEXX;100;1,5\n");
    const auto curves = parseErrorCurvesCsv(in, "m.csv");
    ASSERT_EQ(curves.size(), 1u);
    EXPECT_DOUBLE_EQ(curves[0].mean[1], 1.5);
  }
}

TEST(CsvDialects, ACampaignManifestInCsvNamesEachFilesSetup) {
  const mtcal::testing::TempDir dir;
  {
    std::ofstream(dir.file("exx.csv")) << "target_mm;direction;cycle;deviation [um]\n50;+;1;0,5\n50;+;2;0,7\n"
                                          "100;+;1;1,5\n100;+;2;1,7\n";
    std::ofstream(dir.file("ebx.csv")) << "target_mm;direction;cycle;deviation\n50;+;1;1\n50;+;2;1\n100;+;1;2\n"
                                          "100;+;2;2\n";
    std::ofstream(dir.file("campaign.csv"))
        << "file;axis;measures;units;line_y_mm;line_z_mm;reflector_x_mm;reflector_y_mm;reflector_z_mm\n"
           "exx.csv;X;EXX;;200;50;0;25;45\n"
           "ebx.csv;X;EBX;arcsec;200;50;;;\n";
  }
  storage::Store store(dir.file("db.sqlite"));
  const auto imported = importLinearCampaign(store, dir.file("campaign.csv"), {});
  ASSERT_EQ(imported.run_ids.size(), 2u);
  const auto exx = store.run(imported.run_ids[0]);
  const auto ebx = store.run(imported.run_ids[1]);
  EXPECT_EQ(exx.campaign_id, ebx.campaign_id);
  const auto plan = nlohmann::json::parse(exx.plan_json);
  EXPECT_EQ(plan["measures"], "EXX");
  EXPECT_EQ(plan["line_position_mm"]["Y"], 200.0);
  EXPECT_EQ(plan["reflector_offset_mm"], nlohmann::json::array({0.0, 25.0, 45.0}));
  EXPECT_EQ(ebx.value_unit, "urad");
  EXPECT_FALSE(nlohmann::json::parse(ebx.plan_json).contains("reflector_offset_mm"));
  EXPECT_NEAR(store.targets(ebx.id)[2].deviation_um, 2 * 4.84813681109536, 1e-9);
  EXPECT_TRUE(imported.warnings.empty());
  // One file named for two axes: stored for both, and said.
  std::ofstream(dir.file("twice.csv")) << "file;axis;measures\nexx.csv;X;EXX\nexx.csv;Z;EZZ\n";
  const auto twice = importLinearCampaign(store, dir.file("twice.csv"), {});
  EXPECT_EQ(twice.run_ids.size(), 2u);
  ASSERT_EQ(twice.warnings.size(), 1u);
  EXPECT_EQ(twice.warnings[0], dir.file("twice.csv") + ":2 and " + dir.file("twice.csv") +
                                   ":3 name the same file 'exx.csv': its readings are stored for both");

  // A bad run file stores nothing of the campaign.
  std::ofstream(dir.file("bad.csv")) << "file,axis,measures\nexx.csv,X,EXX\nmissing.csv,X,EYX\n";
  const auto before = store.listRuns().size();
  try {
    importLinearCampaign(store, dir.file("bad.csv"), {});
    FAIL();
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), dir.file("bad.csv") + ":3: run file 'missing.csv': " + dir.file("missing.csv") +
                                         ": cannot open file: No such file or directory");
  }
  EXPECT_EQ(store.listRuns().size(), before);
  // A measures that is not an error of the axis, named with the manifest's line.
  std::ofstream(dir.file("wrong.csv")) << "file,axis,measures\nexx.csv,X,EXY\n";
  try {
    importLinearCampaign(store, dir.file("wrong.csv"), {});
    FAIL();
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), dir.file("wrong.csv") +
                                         ":2: column 'measures': 'EXY' is not one of the errors of axis X (EXX, EYX, "
                                         "EZX, EAX, EBX, ECX)");
  }
  // Its refusals name the manifest's columns, not a plan's keys.
  const auto refusal = [&](const std::string& manifest) {
    std::ofstream(dir.file("m.csv")) << manifest;
    try {
      importLinearCampaign(store, dir.file("m.csv"), {});
    } catch (const InputError& e) {
      return std::string(e.what()).substr(dir.file("m.csv").size());
    }
    return std::string("accepted");
  };
  EXPECT_EQ(refusal("file,axis,line_x_mm\nexx.csv,X,5\n"), ":2: column 'line_x_mm': is the measured axis");
  EXPECT_EQ(refusal("file,axis\nexx.csv,W\n"), ":2: column 'axis': 'W' is not an axis: must be X, Y or Z");
  EXPECT_EQ(refusal("file,axis,reflector_x_mm,reflector_y_mm,reflector_z_mm\nexx.csv,X,,5,\n"),
            ":2: columns reflector_x_mm, reflector_y_mm, reflector_z_mm: 1 of the three given: give all three, or "
            "none (no offset)");
  EXPECT_EQ(refusal("file,axis,units\nexx.csv,X,furlong\n"),
            ":2: column 'units': 'furlong' is not a unit mtcal knows (um, mm, urad, arcsec, mm/m ...)");
  EXPECT_EQ(refusal("file,axis,reflector_x_mm,reflector_y_mm,reflector_z_mm\nexx.csv,X,0,0,2e5\n"),
            ":2: columns reflector_x_mm, reflector_y_mm, reflector_z_mm: its z is 200000 mm: beyond 10 m of the tool "
            "point (mm, not um)");
  EXPECT_EQ(store.listRuns().size(), before);
}

}  // namespace
}  // namespace mtcal::acquisition
