// The loop closed on the simulated machine: an axis measured, its table written for a
// controller, the virtual CNC running that table, the axis measured again and the table
// iterated from the run that ran it.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <tuple>
#include <vector>

#include "../support/temp_dir.h"
#include "../support/time_scale.h"
#include "mtcal/services/archive.h"
#include "mtcal/services/compensate.h"
#include "mtcal/services/linear.h"
#include "mtcal/services/model.h"
#include "service_support.h"

namespace mtcal::services {
namespace {

/// The demo machine's X axis: the 20 mm grid of ISO 230-2, or random offsets from it (a
/// verification that does not measure at the table's own entries).
LinearRunRequest demoAxis(const std::string& plan = "x_axis_iso230-2.json") {
  LinearRunRequest r;
  r.plan_path = MTCAL_EXAMPLES_DIR "/plans/" + plan;
  r.plans = {acquisition::LinearPlan::fromJson(nlohmann::json::parse(readTextFile(r.plan_path)), r.plan_path)};
  r.simulation.seed = 1;
  r.simulation.time_scale = mtcal::testing::timeScale(400.0);
  return r;
}

TEST(CompensateService, TheVirtualCncRunsTheTableAndTheIterationConverges) {
  const mtcal::testing::TempDir dir;
  Session session(mtcal::testing::onArchive(dir.file("c.sqlite")));
  const auto grid = runLinear(session, demoAxis()).runs.front();
  ASSERT_EQ(grid.status, "completed");
  CompensateRequest request;
  request.controller = "linuxcnc";
  const auto first = compensateRun(session, grid.run_id, request);
  EXPECT_TRUE(first.existing_path.empty());
  const std::string table = dir.file("X.comp");
  writeTextFile(table, first.file.text);

  // Verified at random offsets from the grid, before and after: not at the table's entries.
  const auto bare = runLinear(session, demoAxis("x_axis_random_offsets.json")).runs.front();
  auto compensated = demoAxis("x_axis_random_offsets.json");
  compensated.simulation.compensation = {{"", table, "linuxcnc"}};
  const auto after = runLinear(session, compensated).runs.front();
  ASSERT_EQ(after.status, "completed");
  // The run keeps the table its controller ran.
  const auto ran = appliedTables(session.store().run(after.run_id).compensation_json);
  ASSERT_TRUE(ran[0].has_value());
  EXPECT_EQ(ran[0]->file, table);
  EXPECT_EQ(ran[0]->table.position, first.table.position);
  EXPECT_EQ(showRun(session, after.run_id).document()["compensation"]["X"]["controller"], "linuxcnc");
  // The virtual CNC applies what the truth says it does: the measured means agree with the
  // compensated machine's static error as they do on the bare machine.
  ASSERT_TRUE(after.simulation_check.has_value());
  EXPECT_LT(after.simulation_check->max_abs_um, 1.5);

  const auto c = compareRuns(session, bare.run_id, after.run_id, "iso230-2:2014");
  ASSERT_TRUE(c.before.truth_E_um && c.after.truth_E_um);
  const double e_before = c.before.evaluation.value("E"), e_after = c.after.evaluation.value("E");
  std::printf(
      "compensated on the demo machine: E %.3f -> %.3f um (truth %.3f -> %.3f), M %.3f -> %.3f um (truth "
      "%.3f -> %.3f)\n",
      e_before, e_after, *c.before.truth_E_um, *c.after.truth_E_um, c.before.evaluation.value("M"),
      c.after.evaluation.value("M"), *c.before.truth_M_um, *c.after.truth_M_um);
  // The truth: the table leaves a fifth of the error; measured, the means' scatter adds to it
  // (5 cycles: s / sqrt(5) at each of 58 means) but E and M still fall by more than half.
  EXPECT_LT(*c.after.truth_E_um, *c.before.truth_E_um / 5.0);
  EXPECT_LT(e_after, e_before / 2.0);
  EXPECT_LT(c.after.evaluation.value("M"), c.before.evaluation.value("M") / 2.0);
  const auto doc = c.document();
  EXPECT_EQ(doc["figures"][0]["symbol"], "E");
  EXPECT_DOUBLE_EQ(doc["figures"][0]["change_um"].get<double>(), e_after - e_before);
  EXPECT_EQ(doc["after"]["means"].size(), after.iso230_2->result.positions.size());  // the overlay's data

  // The second iteration, from the grid measured again with the table (no --existing needed:
  // the run keeps what it ran), changes the table by what was left, at most the repeatability's
  // level, and the machine's truth is no worse.
  auto grid_again = demoAxis();
  grid_again.simulation.compensation = {{"", table, "linuxcnc"}};
  const auto checked = runLinear(session, grid_again).runs.front();
  const auto second = compensateRun(session, checked.run_id, request);
  EXPECT_EQ(second.existing_path, table);
  ASSERT_EQ(second.table.position, first.table.position);
  double largest_change_um = 0.0;
  for (std::size_t i = 0; i < second.table.position.size(); ++i) {
    largest_change_um = std::max({largest_change_um, std::abs(second.table.up_um[i] - first.table.up_um[i]),
                                  std::abs(second.table.down_um[i] - first.table.down_um[i])});
  }
  EXPECT_TRUE(second.warnings.empty());
  const std::string table2 = dir.file("X2.comp");
  writeTextFile(table2, second.file.text);
  // --existing that is not the table the run ran: taken, and said.
  auto other = request;
  other.existing_path = table2;
  const auto iterated_elsewhere = compensateRun(session, checked.run_id, other);
  ASSERT_EQ(iterated_elsewhere.warnings.size(), 1u);
  EXPECT_NE(iterated_elsewhere.warnings[0].find("ran " + table + "'s table (stored with it), not " + table2 + "'s"),
            std::string::npos)
      << iterated_elsewhere.warnings[0];
  // A file of another controller: the error names the one that reads it.
  other.existing_path = table;
  other.controller = "csv";
  try {
    compensateRun(session, checked.run_id, other);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("(the file reads as a table of --controller linuxcnc)"), std::string::npos)
        << e.what();
  }
  // A LinuxCNC file of the other type reads as corrections of its positions: refused.
  other.controller = "linuxcnc-trim";
  try {
    compensateRun(session, checked.run_id, other);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("more than any axis' error (1000 um): a file of another format? (the file "
                                         "reads as a table of --controller linuxcnc)"),
              std::string::npos)
        << e.what();
  }
  compensated.simulation.compensation = {{"", table2, "linuxcnc"}};
  const auto after2 = runLinear(session, compensated).runs.front();
  const auto c2 = compareRuns(session, after.run_id, after2.run_id, "iso230-2:2014");
  std::printf("second iteration: the table changes by at most %.3f um; E %.3f -> %.3f um (truth %.3f -> %.3f)\n",
              largest_change_um, c2.before.evaluation.value("E"), c2.after.evaluation.value("E"), *c2.before.truth_E_um,
              *c2.after.truth_E_um);
  EXPECT_LT(largest_change_um, *checked.iso230_2->result.R_um / 2.0);
  EXPECT_LT(*c2.after.truth_E_um, *c2.before.truth_E_um + 0.1);
}

// A controller's file names its axis (SINUMERIK's AXn, FANUC's An: every format's reading of it,
// ControllerFormats.AFileNamesTheAxisItWasWrittenFor): another axis' table given as the one X ran
// would add that axis' corrections to X's. Refused; the axis' number given, taken.
TEST(CompensateService, AnExistingTableOfAnotherAxisIsRefused) {
  const mtcal::testing::TempDir dir;
  Session session(mtcal::testing::onArchive(dir.file("c.sqlite")));
  const auto grid = runLinear(session, demoAxis()).runs.front();
  ASSERT_EQ(grid.status, "completed");
  for (const auto& [controller, second_axis, first_axis] :
       std::vector<std::tuple<std::string, std::string, std::string>>{{"siemens-eec", "AX2", "AX1"},
                                                                      {"siemens-cec", "AX2", "AX1"}}) {
    SCOPED_TRACE(controller);
    CompensateRequest request;
    request.controller = controller;
    request.table.bidirectional = controller != "siemens-eec";  // one table for both directions
    request.table.interval = 10.0;                              // the grid formats: equal intervals
    request.axis_index = 1;                                     // written for the controller's second axis
    const std::string of_second = dir.file(controller + "_second_axis.txt");
    writeTextFile(of_second, compensateRun(session, grid.run_id, request).file.text);
    request.axis_index.reset();  // X: the first
    request.existing_path = of_second;
    try {
      compensateRun(session, grid.run_id, request);
      ADD_FAILURE() << "a table of " << second_axis << " taken as X's";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(fmt::format("--existing {} is a table of {}, and the table of X is written "
                                                       "for {} (--axis-index 0)",
                                                       of_second, second_axis, first_axis)),
                std::string::npos)
          << e.what();
    }
    request.axis_index = 1;  // X is the controller's second axis: the file is its own
    const auto iterated = compensateRun(session, grid.run_id, request);
    EXPECT_EQ(iterated.existing_path, of_second);
  }
}

TEST(CompensateService, AMachineFileNamesTheTablesItsControllerRuns) {
  const mtcal::testing::TempDir dir;
  Session session(mtcal::testing::onArchive(dir.file("c.sqlite")));
  const auto grid = runLinear(session, demoAxis()).runs.front();
  CompensateRequest request;
  request.controller = "linuxcnc-trim";
  writeTextFile(dir.file("X.comp"), compensateRun(session, grid.run_id, request).file.text);

  // The gantry example machine with the table beside its file, named relative to it.
  auto machine = readJsonFile(MTCAL_EXAMPLES_DIR "/machines/gantry-drilling.json");
  machine["kinematics"] = MTCAL_EXAMPLES_DIR "/machines/" + machine["kinematics"].get<std::string>();
  machine["compensation"] = {{{"axis", "X"}, {"file", "X.comp"}, {"controller", "linuxcnc-trim"}}};
  writeTextFile(dir.file("machine.json"), machine.dump());
  auto r = demoAxis();
  r.simulation.machine_file = dir.file("machine.json");
  const auto run = runLinear(session, r).runs.front();
  ASSERT_EQ(run.status, "completed");
  const auto ran = appliedTables(session.store().run(run.run_id).compensation_json);
  ASSERT_TRUE(ran[0].has_value());
  EXPECT_EQ(ran[0]->file, dir.file("X.comp"));
  EXPECT_EQ(ran[0]->controller, "linuxcnc-trim");
  // Stored with the run, not with the machine: the machine's description has no tables.
  EXPECT_EQ(session.store().machineDescriptionOfRun(run.run_id).find("compensation"), std::string::npos);

  // A table on the command line replaces the file's for its axis.
  writeTextFile(dir.file("Xb.comp"), compensateRun(session, grid.run_id, {}).file.text);
  r.simulation.compensation = {{"X", dir.file("Xb.comp"), "csv"}};
  const auto replaced = runLinear(session, r).runs.front();
  EXPECT_EQ(appliedTables(session.store().run(replaced.run_id).compensation_json)[0]->controller, "csv");

  // Run kinds that do not record tables refuse a machine that has them.
  SimulationOptions circle;
  circle.machine_file = dir.file("machine.json");
  try {
    simulatedMachine(circle);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("names compensation tables (key 'compensation'), which only linear runs run"),
              std::string::npos);
  }
  machine["compensation"] = {{{"axis", "X"}, {"file", "X.comp"}, {"contoller", "csv"}}};
  writeTextFile(dir.file("machine.json"), machine.dump());
  r.simulation.compensation.clear();
  try {
    runLinear(session, r);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("key 'compensation': entry 1: 'controller' is missing or not text"),
              std::string::npos);
  }
}

// The 21 errors of the demo machine identified from the direct method's 18 lines, written as
// ISG's volumetric compensation, and the virtual CNC running it at 200 random points of the
// measured volume: what remains is what the model misses (the machine minus the model),
// within the table's interpolation, and far less than the machine's error without it.
TEST(CompensateService, AVolumetricTableLeavesWhatTheModelMisses) {
  const mtcal::testing::TempDir dir;
  Session session(mtcal::testing::onArchive(dir.file("c.sqlite")));
  LinearRunRequest r;
  std::vector<std::string> paths;
  for (const auto& entry : std::filesystem::directory_iterator(MTCAL_EXAMPLES_DIR "/plans/direct-21"))
    if (entry.path().extension() == ".json") paths.push_back(entry.path().string());
  std::sort(paths.begin(), paths.end());
  ASSERT_EQ(paths.size(), 18u);
  for (const auto& p : paths)
    r.plans.push_back(acquisition::LinearPlan::fromJson(nlohmann::json::parse(readTextFile(p)), p));
  r.plan_path = paths.front();
  r.simulation.seed = 1;
  r.simulation.time_scale = mtcal::testing::timeScale(1000.0);
  const auto campaign = runLinear(session, r);
  ModelFitRequest fit;
  fit.machine_path = MTCAL_EXAMPLES_DIR "/machines/vmc3-cn104200063.model.json";
  const auto model = identifyModel(session, {"c" + std::to_string(campaign.campaign_id)}, fit);

  VolumetricRequest request;
  request.file_name = "vc.csv";
  const auto c = compensateVolumetric(session, model.model_id, request);
  // The file is what the controller reads: every axis 50..450 mm every 10 mm, the squarenesses.
  ASSERT_EQ(c.table.axes.size(), 3u);
  EXPECT_EQ(c.table.axes[0].position.size(), 41u);
  EXPECT_EQ(c.table.records(), 3u * 41u + 1u);
  EXPECT_EQ(c.table.constants.size(), 3u);
  EXPECT_NE(c.setup.find("file[0] vc.csv"), std::string::npos);
  ASSERT_TRUE(c.verification.has_value());
  const auto& v = *c.verification;
  EXPECT_EQ(v.points, 200u);
  // Measured (seed 1): without 1.83 um rms / 3.66 max, with 0.24 / 0.42, expected 0.24 / 0.43.
  EXPECT_GT(v.before_rms_um, 1.0);
  EXPECT_LT(v.after_rms_um, v.before_rms_um / 4.0);
  EXPECT_NEAR(v.after_rms_um, v.expected_rms_um, 0.02);
  EXPECT_NEAR(v.after_max_um, v.expected_max_um, 0.05);
  EXPECT_NEAR(c.document()["verification"]["after"]["rms_um"].get<double>(), v.after_rms_um, 0.0005);
}

// What a controller cannot take is refused by name, and what it takes but does not correct is
// said: an imported run of 0..100 mm (the error 0.05 um/mm, a reversal of 1 um), and one of the
// + direction alone.
TEST(CompensateService, WhatTheControllerCannotTakeIsRefusedOrSaid) {
  const mtcal::testing::TempDir dir;
  Session session(mtcal::testing::onArchive(dir.file("c.sqlite")));
  const auto imported = [&](bool both_directions) {
    std::string csv = "target_mm,direction,cycle,deviation_um\n";
    for (int cycle = 1; cycle <= 3; ++cycle) {
      for (const char* direction : {"+", "-"}) {
        if (!both_directions && std::string(direction) == "-") continue;
        for (int target = 0; target <= 100; target += 10)
          csv += fmt::format("{},{},{},{:.3f}\n", target, direction, cycle,
                             0.05 * target + (std::string(direction) == "-" ? 1.0 : 0.0));
      }
    }
    const std::string path = dir.file(both_directions ? "both.csv" : "up.csv");
    writeTextFile(path, csv);
    acquisition::LinearImportOptions options;
    options.axis = "X";
    return importLinear(session, path, options).run_ids.front();
  };
  const auto both = imported(true), up = imported(false);
  const auto refusal = [&](storage::Id run, CompensateRequest request) {
    try {
      compensateRun(session, run, request);
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("written");
  };
  CompensateRequest request;
  request.controller = "linuxcnc";
  auto fine = request;
  fine.table.interval = 1e-3;  // um taken for mm
  EXPECT_EQ(refusal(both, fine), "compensation: the interval 0.001 mm is finer than 0.1 mm (mm, not um?)");
  auto coarse = request;
  coarse.table.resolution_um = 1e3;
  EXPECT_EQ(refusal(both, coarse),
            "compensation: a resolution of 1000 um is not 0..10 um (a controller's is 0.1..1 um)");
  // Fanuc gives axis n the numbers 128 n to 128 n + 127 of 0..1023, and is zero at its reference position, 0 mm.
  auto fanuc = request;
  fanuc.controller = "fanuc";
  fanuc.axis_index = 8;
  EXPECT_NE(refusal(both, fanuc).find("so its axes are 0 to 7 (--axis-index)"), std::string::npos);
  fanuc.axis_index.reset();
  fanuc.table.reference = 50.0;
  EXPECT_EQ(refusal(both, fanuc),
            "--reference 50: the fanuc file's correction there is -3.000 um, not 0: the controller takes its own zero "
            "(leave --reference out)");
  auto linuxcnc = request;
  linuxcnc.table.reference = 50.0;  // LinuxCNC reads the table as written: zero there
  EXPECT_EQ(refusal(both, linuxcnc), "written");
  // A resolution that rounds every correction (at most 5.5 um) to 0: written, and said.
  auto rounded = request;
  rounded.table.resolution_um = 10.0;
  rounded.table.end = 10.0;  // corrections of 0.5 um at most there
  const auto nothing = compensateRun(session, both, rounded);
  ASSERT_EQ(nothing.warnings.size(), 1u);
  EXPECT_NE(nothing.warnings[0].find("every correction rounds to 0 at a resolution of 10 um"), std::string::npos)
      << nothing.warnings[0];
  // The + direction alone: its table serves both, and says so.
  const auto one_way = compensateRun(session, up, request);
  EXPECT_FALSE(one_way.table.bidirectional());
  ASSERT_EQ(one_way.warnings.size(), 1u);
  EXPECT_EQ(one_way.warnings[0],
            fmt::format("run {} measured no target in the - direction: the table's - direction takes the other's "
                        "correction, and a reversal (backlash) is not corrected",
                        up));
}

}  // namespace
}  // namespace mtcal::services
