#include "mtcal/acquisition/import_linear.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>
#include <tuple>

#include "../support/temp_dir.h"
#include "mtcal/error.h"

namespace mtcal::acquisition {
namespace {

std::string errorOf(const std::string& csv, LinearImportOptions options = {}) {
  std::istringstream in(csv);
  try {
    parseLinearCsv(in, "f.csv", options);
  } catch (const InputError& e) {
    return e.what();
  }
  return "no error";
}

TEST(ImportLinear, ReadsDeviationsAllDirectionSpellingsAndChannels) {
  std::ifstream in(std::string(MTCAL_TEST_DATA_DIR) + "/linear_deviation.csv");
  const auto parsed = parseLinearCsv(in, "linear_deviation.csv", {});
  ASSERT_EQ(parsed.runs[0].targets.size(), 8u);
  EXPECT_EQ(parsed.channel_names, std::vector<std::string>{"spindle_temp_c"});
  const std::vector<int> directions = {1, 1, -1, -1, 1, 1, -1, -1};
  for (std::size_t i = 0; i < 8; ++i) EXPECT_EQ(parsed.runs[0].targets[i].direction, directions[i]) << i;
  EXPECT_DOUBLE_EQ(parsed.runs[0].targets[1].measured_mm, 100.005);
  EXPECT_DOUBLE_EQ(parsed.runs[0].targets[1].deviation_um, 5.0);
  EXPECT_DOUBLE_EQ(*parsed.runs[0].targets[3].air_temp_c, 20.2);
  EXPECT_FALSE(parsed.runs[0].channel_rows[3][0].has_value());  // empty cell: missing, not zero
  EXPECT_DOUBLE_EQ(*parsed.runs[0].channel_rows[7][0], 25.7);
  EXPECT_EQ(parsed.runs[0].targets[7].cycle, 2);
}

TEST(ImportLinear, MeasuredPositionsGiveDeviations) {
  std::istringstream in("target_mm,direction,cycle,measured_mm\n50,+,1,50.0012\n50,+,2,49.9990\n");
  const auto parsed = parseLinearCsv(in, "m.csv", {});
  EXPECT_NEAR(parsed.runs[0].targets[0].deviation_um, 1.2, 1e-9);
  EXPECT_NEAR(parsed.runs[0].targets[1].deviation_um, -1.0, 1e-9);
  EXPECT_FALSE(parsed.runs[0].targets[0].air_index.has_value());
}

// --raw: L = datum + NTC(L_raw / n), hand-worked with a published index. NIST's Edlen
// calculator at its defaults (20 degC, 101 325 Pa, 50 % RH, 450 umol/mol CO2, 633 nm) gives
// n = 1.000271374 (NIST Engineering Metrology Toolbox, "Refractive Index of Air Calculator",
// Stone & Zimmerman). A steel part (11.5e-6 /K) 280 mm from the 20 mm datum at 20 degC is
// 280 x (1 + 11.5e-6 x 2) = 280.00644 mm at 22 degC, and the laser, counting with the vacuum
// wavelength, reads 280.00644 x 1.000271374 = 280.0824264676 mm. Imported, it must come
// back at 300 mm: within 0.2 nm (the calculator's last digit, 5e-10 of 280 mm, 0.14 nm).
TEST(ImportLinear, RawReadingsAreCompensatedFromTheEnvironmentColumns) {
  std::istringstream in(
      "target_mm,direction,cycle,measured_mm,air_temp_c,air_pressure_pa,humidity_pct,material_temp_c\n"
      "300,+,1,280.0824264676,20,101325,50,22\n"
      "300,+,2,280.0824264676,20,101325,50,22\n");
  LinearImportOptions options;
  options.raw = true;
  options.datum_mm = 20.0;
  options.wavelength_nm = 633.0;
  const auto parsed = parseLinearCsv(in, "raw.csv", options);
  EXPECT_NEAR(parsed.runs[0].targets[0].measured_mm, 300.0, 2e-7);
  EXPECT_NEAR(parsed.runs[0].targets[0].deviation_um, 0.0, 2e-4);
  ASSERT_TRUE(parsed.runs[0].targets[0].air_index.has_value());
  EXPECT_NEAR(*parsed.runs[0].targets[0].air_index, 1.000271374, 1e-9);
}

TEST(ImportLinear, MalformedInputNamesTheLineAndTheColumn) {
  std::ifstream bad(std::string(MTCAL_TEST_DATA_DIR) + "/linear_bad_row.csv");
  try {
    parseLinearCsv(bad, "linear_bad_row.csv", {});
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("linear_bad_row.csv:4: column 'direction'"), std::string::npos) << e.what();
  }
  const std::string h = "target_mm,direction,cycle,deviation_um\n";
  EXPECT_NE(errorOf(h + "10,+,1,abc\n").find("f.csv:2: column 'deviation_um': 'abc' is not a number"),
            std::string::npos);
  // A number beyond a double's range is a number, too large; one below it is nearly 0.
  EXPECT_NE(errorOf(h + "10,+,1,1e400\n").find("f.csv:2: column 'deviation_um': '1e400' is beyond +-1e+12"),
            std::string::npos);
  EXPECT_NE(errorOf(h + "10,+,1,-inf\n").find("'-inf' is beyond +-1e+12"), std::string::npos);
  EXPECT_NE(errorOf(h + "10,+,1,nan\n").find("'nan' is not a number"), std::string::npos);
  // A position reached far from its target is a mistyped cell, not an error of the machine.
  EXPECT_EQ(errorOf("target_mm,direction,cycle,measured_mm\n50,+,1,50.0003\n50,+,2,5000\n"),
            "f.csv:3: column 'measured_mm': the position reached, 5000 mm, is 4950 mm from its target 50 mm: beyond "
            "+-100 mm, not a machine's error (a mistyped or shifted cell?)");
  {
    std::istringstream tiny(h + "10,+,1,1e-400\n20,+,1,1\n10,+,2,0\n20,+,2,1\n");
    EXPECT_EQ(parseLinearCsv(tiny, "f.csv", {}).runs.at(0).targets.at(0).deviation_um, 0.0);
  }
  // A binary file's bytes are not quoted back: its first control character is named, with what
  // a carriage return alone or a zero byte says of the file; lines ended CR CR LF are read.
  EXPECT_EQ(errorOf(std::string("target_mm,dir\x01"
                                "ection\x7F\n")),
            "f.csv:1: byte 14 of the line is 0x01, a control character: not a text file (a CSV file is text)");
  EXPECT_NE(errorOf(h + "10,+,1,1\r20,+,1,1\r")
                .find("f.csv:2: byte 9 of the line is 0x0D, a control character: "
                      "lines ended by a carriage return alone"),
            std::string::npos);
  EXPECT_NE(errorOf(std::string("t\0a", 3)).find("0x00, a control character: UTF-16 text without a byte-order mark"),
            std::string::npos);
  {
    std::istringstream crcrlf(
        "target_mm,direction,cycle,deviation_um\r\r\n10,+,1,1.5\r\r\n20,+,1,1\r\r\n"
        "10,+,2,0\r\r\n20,+,2,1\r\r\n");
    EXPECT_EQ(parseLinearCsv(crcrlf, "f.csv", {}).runs.at(0).targets.at(0).deviation_um, 1.5);
  }
  EXPECT_NE(errorOf(h + "10,+,0,1\n").find("column 'cycle'"), std::string::npos);
  EXPECT_NE(errorOf(h + "10,+,1.5,1\n").find("column 'cycle'"), std::string::npos);
  EXPECT_NE(errorOf(h + "10,+,1\n").find("f.csv:2: 3 fields, the header has 4"), std::string::npos);
  EXPECT_NE(errorOf(h + "10,+,1,1\n10,up,1,2\n").find("already given on line 2"), std::string::npos);
  EXPECT_NE(errorOf(h + ",+,1,1\n").find("column 'target_mm': value missing"), std::string::npos);
  EXPECT_NE(errorOf("target_mm,cycle,deviation_um\n").find("missing column 'direction'"), std::string::npos);
  EXPECT_NE(errorOf("target_mm,direction,cycle,deviation_um,measured_mm\n").find("exactly one"), std::string::npos);
  EXPECT_NE(errorOf(h).find("no data rows"), std::string::npos);
  EXPECT_NE(errorOf("").find("empty file"), std::string::npos);
  EXPECT_NE(errorOf("target_mm,direction,cycle,deviation_um,extra\n1,+,1,2,x\n").find("column 'extra'"),
            std::string::npos);
  LinearImportOptions raw;
  raw.raw = true;
  EXPECT_NE(errorOf("target_mm,direction,cycle,measured_mm\n1,+,1,1.0\n1,+,2,1.0\n", raw).find("--raw needs"),
            std::string::npos);
  // The environment is read where the air's index is taken, with --raw or without: 5 Pa is in kPa.
  for (const auto& options : {raw, LinearImportOptions{}}) {
    EXPECT_NE(
        errorOf("target_mm,direction,cycle,measured_mm,air_temp_c,air_pressure_pa,humidity_pct\n1,+,1,1,20,5,50\n",
                options)
            .find(":2: column 'air_pressure_pa': 5 Pa is outside 10000..140000 Pa (a sensor fault? leave the cell "
                  "empty)"),
        std::string::npos);
  }
  EXPECT_NE(
      errorOf("target_mm,direction,cycle,deviation_um,humidity_pct\n1,+,1,1,150\n").find("150 % is outside 0..100 %"),
      std::string::npos);
  EXPECT_NE(errorOf("target_mm,direction,cycle,deviation_um,material_temp_c\n1,+,1,1,-500\n")
                .find("column 'material_temp_c': -500 degC is outside -40..100 degC"),
            std::string::npos);
  // What mtcal compensates raw readings with is refused by its option's name.
  const std::string positions = "target_mm,direction,cycle,measured_mm\n1,+,1,1.0\n";
  raw.expansion_per_k = 5.0;
  EXPECT_NE(errorOf(positions, raw).find("--expansion-per-k: must be in [0, 1e-4) 1/K"), std::string::npos)
      << errorOf(positions, raw);
  raw.expansion_per_k = 11.5e-6;
  raw.datum_mm = std::nan("");
  EXPECT_NE(errorOf(positions, raw).find("--datum-mm: must be a machine coordinate within 100 m of the origin"),
            std::string::npos)
      << errorOf(positions, raw);
}

/// One row of a unidirectional or bidirectional run: target, direction, cycle, time.
struct Reading {
  double target_mm;
  int direction, cycle;
  double time_s;
};

std::vector<std::string> warningsOf(const std::vector<Reading>& rows) {
  std::string csv = "target_mm,direction,cycle,deviation_um,time [min]\n";
  for (const auto& r : rows)
    csv += fmt::format("{},{},{},0.5,{}\n", r.target_mm, r.direction > 0 ? "+" : "-", r.cycle, r.time_s / 60.0);
  std::istringstream in(csv);
  return parseLinearCsv(in, "t.csv", {}).warnings;
}

/// Three bidirectional cycles over 0, 100, 200 mm in the order measured, 10 s apart.
std::vector<Reading> measuredInOrder() {
  std::vector<Reading> rows;
  for (int cycle = 1; cycle <= 3; ++cycle) {
    for (const int direction : {1, -1}) {
      for (int k = 0; k < 3; ++k) {
        rows.push_back({direction > 0 ? 100.0 * k : 200.0 - 100.0 * k, direction, cycle, 10.0 * rows.size()});
      }
    }
  }
  return rows;
}

// Times that go back are imported as given, with a warning naming the row, where they cannot be
// one clock's; an export listed in another order (by target, or a pilgrim-step plan listed by
// cycle) goes back in time legitimately and gets none.
TEST(ImportLinear, TimesThatCannotBeOneClocksAreWarnedAbout) {
  const auto in_order = measuredInOrder();
  EXPECT_TRUE(warningsOf(in_order).empty());

  auto by_target = in_order;
  std::stable_sort(by_target.begin(), by_target.end(), [](const Reading& a, const Reading& b) {
    return std::tie(a.target_mm, a.direction, a.cycle) < std::tie(b.target_mm, b.direction, b.cycle);
  });
  EXPECT_TRUE(warningsOf(by_target).empty());

  // A pilgrim step: each target approached three times before the next, listed by cycle.
  std::vector<Reading> pilgrim;
  for (int cycle = 1; cycle <= 3; ++cycle)
    for (int k = 0; k < 3; ++k) pilgrim.push_back({100.0 * k, 1, cycle, 10.0 * (3 * k + cycle - 1)});
  EXPECT_TRUE(warningsOf(pilgrim).empty());

  // A clock of whole minutes: the short passes of a cycle begin in one minute, one after another.
  auto coarse = in_order;
  for (auto& r : coarse) r.time_s = 60.0 * std::floor(r.time_s / 60.0);
  EXPECT_TRUE(warningsOf(coarse).empty());
  // One time on every row: said so, not taken for a reset.
  auto constant = in_order;
  for (auto& r : constant) r.time_s = 7.0;
  auto w = warningsOf(constant);
  ASSERT_EQ(w.size(), 1u);
  EXPECT_EQ(w[0],
            "t.csv: column 'time [min]' holds the same time, 0.116667 (7.000 s), on every row: nothing is read in time "
            "from it");

  // Each pass's clock started at zero: the pass of cycle 1, direction - (line 5) begins the
  // instant the first pass does.
  auto per_pass = in_order;
  for (std::size_t i = 0; i < per_pass.size(); ++i) per_pass[i].time_s = 10.0 * static_cast<double>(i % 3);
  w = warningsOf(per_pass);
  ASSERT_EQ(w.size(), 1u);
  EXPECT_NE(w[0].find("t.csv:5: column 'time [min]': the pass of cycle 1, direction - begins at 0 (0.000 s), the "
                      "instant the pass of cycle 1, direction + begins (line 2)"),
            std::string::npos)
      << w[0];
  EXPECT_NE(w[0].find("imported as given"), std::string::npos);

  // Each cycle's clock from its own start, cycle 2 (line 8) beginning 3 s into cycle 1's clock.
  auto per_cycle = in_order;
  for (std::size_t i = 0; i < per_cycle.size(); ++i)
    per_cycle[i].time_s = 10.0 * static_cast<double>(i % 6) + 3.0 * (3 - per_cycle[i].cycle);
  w = warningsOf(per_cycle);
  ASSERT_EQ(w.size(), 1u);
  EXPECT_NE(w[0].find("t.csv:8: column 'time [min]': cycle 2 begins at 0.05 (3.000 s), no later than cycle 1 (line "
                      "2, 0.1 (6.000 s))"),
            std::string::npos)
      << w[0];

  // The clock reset in the middle of cycle 2's forward pass (after its first reading, line 8):
  // said once at line 9 (where the pass also begins the instant the first pass does).
  auto reset = in_order;
  for (std::size_t i = 7; i < reset.size(); ++i) reset[i].time_s -= 70.0;
  w = warningsOf(reset);
  ASSERT_EQ(w.size(), 1u);
  EXPECT_NE(w[0].find("t.csv:9: column 'time [min]': 0 (0.000 s) is earlier than the reading before it in the same "
                      "pass (line 8, 1 (60.000 s); cycle 2, direction +)"),
            std::string::npos)
      << w[0];
}

TEST(ImportLinear, ABadFileImportsNothing) {
  const mtcal::testing::TempDir dir;
  storage::Store store(dir.file("db.sqlite"));
  EXPECT_THROW(importLinearCsv(store, std::string(MTCAL_TEST_DATA_DIR) + "/linear_bad_row.csv", {}), InputError);
  EXPECT_TRUE(store.listRuns().empty());
  // Nor does one of a single target, which no analysis of an axis could read.
  std::istringstream one_target("target_mm,direction,cycle,deviation_um\n50,+,1,0.2\n50,+,2,0.3\n");
  try {
    importLinearCsv(store, one_target, "one.csv", {});
    ADD_FAILURE() << "imported";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()),
              "one.csv: EXX has one target (50 mm) only: an axis' error is read along it, from at least 2 targets "
              "(ISO 230-2)");
  }
  EXPECT_TRUE(store.listRuns().empty());
  const auto id =
      importLinearCsv(store, std::string(MTCAL_TEST_DATA_DIR) + "/linear_deviation.csv", {}).run_ids.front();
  const auto run = store.run(id);
  EXPECT_EQ(run.status, "imported");
  EXPECT_EQ(run.target_count, 8);
  EXPECT_EQ(run.name, "linear_deviation.csv");
}

}  // namespace
}  // namespace mtcal::acquisition
