// The archive's housekeeping through the command line: runs filtered and sorted, a run renamed
// and annotated, runs and campaigns deleted with everything they hold (asked first), a
// consistent backup and a check that finds what is wrong.

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "../support/cli_run.h"
#include "../support/temp_dir.h"
#include "mtcal/storage/store.h"

namespace mtcal::app {
namespace {

using mtcal::testing::cli;

class ArchiveCli : public ::testing::Test {
 protected:
  void SetUp() override {
    const std::string linear = std::string(MTCAL_TEST_DATA_DIR) + "/linear_deviation.csv";
    ASSERT_EQ(run({"import", "linear", linear, "--name", "X before repair"}).code, 0);
    ASSERT_EQ(run({"import", "linear", linear, "--axis", "Y", "--name", "Y"}).code, 0);
    ASSERT_EQ(run({"import", "circle", MTCAL_EXAMPLES_DIR "/circle/xy_r100_export.csv", "--radius-mm", "100"}).code, 0);
    ASSERT_EQ(run({"analyze", "iso230-2", "1"}).code, 0);
  }
  mtcal::testing::CliRun run(std::vector<std::string> args, const std::string& input = "") {
    args.insert(args.begin(), {"--db", db_});
    return cli(args, input);
  }
  std::vector<int> ids(std::vector<std::string> args) {
    args.insert(args.begin(), {"--json", "runs"});
    const auto r = run(args);
    EXPECT_EQ(r.code, 0) << r.err;
    std::vector<int> out;
    const auto listed = nlohmann::json::parse(r.out);
    for (const auto& j : listed["runs"]) out.push_back(j["id"].get<int>());
    return out;
  }
  mtcal::testing::TempDir dir_;
  std::string db_ = dir_.file("archive.sqlite");
};

TEST_F(ArchiveCli, RunsAreFilteredAndSorted) {
  mtcal::testing::CliRun r;
  EXPECT_EQ(ids({}), (std::vector<int>{1, 2, 3}));
  EXPECT_EQ(ids({"--kind", "circle"}), std::vector<int>{3});
  EXPECT_EQ(ids({"--axis", "y"}), std::vector<int>{2});
  EXPECT_EQ(ids({"--status", "imported", "--kind", "linear"}), (std::vector<int>{1, 2}));
  EXPECT_EQ(ids({"--sort", "kind", "--descending"}), (std::vector<int>{2, 1, 3}));  // linear before circle
  EXPECT_EQ(ids({"--sort", "name"}), (std::vector<int>{1, 2, 3}));  // "X before repair", "Y", "xy_r100_export.csv"
  EXPECT_EQ(ids({"--descending"}), (std::vector<int>{3, 2, 1}));
  EXPECT_EQ(ids({"--since", "2000-01-01"}).size(), 3u);
  EXPECT_TRUE(ids({"--until", "2000-01-01"}).empty());
  EXPECT_EQ(ids({"--since", "2000-01-01 08:00"}).size(), 3u);  // a space for the T, as people type it
  EXPECT_TRUE(ids({"--until", "2000-02-29T23:59:59"}).empty());
  for (const char* bad : {"yesterday", "2026-13-01", "2026-02-30", "2026-11-24T25:00", "24/11/2026"}) {
    r = run({"runs", "--since", bad});
    EXPECT_EQ(r.code, 2) << bad;
    EXPECT_NE(r.err.find(std::string("since '") + bad + "': not a date or time; give 2026-11-24"), std::string::npos)
        << r.err;
  }
  // A filter that nothing could match is a mistake, said so rather than an empty list.
  r = run({"runs", "--since", "2027-01-01", "--until", "2026-01-01"});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("since 2027-01-01 is after until 2026-01-01"), std::string::npos) << r.err;
  r = run({"runs", "--axis", "Q"});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("axis 'Q': a run's axes are of X, Y, Z, A, B, C"), std::string::npos) << r.err;
  EXPECT_EQ(ids({"--since", "2000-01-01", "--until", "2000-01-01"}).size(), 0u);  // one day: before and after agree
  r = run({"show", "abc"});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("RUN 'abc' is not an id (a whole number"), std::string::npos) << r.err;
  // An empty number is no number (CLI11 would read it as 0: run 0, seed 0).
  for (const std::vector<std::string>& empty :
       {std::vector<std::string>{"show", ""}, {"resume", ""}, {"thermal", "fit", "", "--target", "a"}}) {
    r = run(empty);
    EXPECT_EQ(r.code, 2) << empty[0];
    EXPECT_NE(r.err.find("RUN: a number is needed, got ''"), std::string::npos) << r.err;
  }
  r = run({"run", "linear", MTCAL_EXAMPLES_DIR "/plans/x_axis_iso230-2.json", "--seed", ""});
  EXPECT_NE(r.err.find("--seed: must be a number, got ''"), std::string::npos) << r.err;
  // An option without its value is named in words; with --json the failure is the one document
  // on stdout, although the parser stopped before it stored the flag.
  r = run({"--json", "runs", "--kind"});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("--kind needs a value (one of linear, circle, est, gantry, thermal)"), std::string::npos)
      << r.err;
  EXPECT_EQ(nlohmann::json::parse(r.out)["exit_code"], 2) << r.out;
  r = run({"diagnose", "1", "--against"});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("--against needs a value (MODEL)"), std::string::npos) << r.err;
  r = run({"diagnose", "1", "--max-findings"});
  EXPECT_NE(r.err.find("--max-findings needs a value (a whole number from 1 to 30)"), std::string::npos) << r.err;
  r = run({"import", "circle", "x.csv", "--radius-mm", "100", "--centre-mm", "1,2"});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("--centre-mm takes x,y,z in mm (three numbers), got 2 in '1,2'"), std::string::npos) << r.err;
  // Given with spaces, the values after the first are not expected: said in the order given
  // (CLI11 listed them last first), with the commas an x,y,z option needs; after another
  // command, without.
  r = run({"import", "circle", "x.csv", "--radius-mm", "100", "--centre-mm", "1", "2", "3"});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("these arguments were not expected: 2 3 (--centre-mm takes x,y,z with commas: --centre-mm "
                       "1,2,3; mtcal help COMMAND lists its options)"),
            std::string::npos)
      << r.err;
  // A value given twice, the option given with '=', and a radius's value that equals an extra.
  r = run({"import", "circle", "x.csv", "--radius-mm", "2", "--centre-mm", "0", "0", "10"});
  EXPECT_NE(r.err.find("not expected: 0 10 (--centre-mm takes x,y,z with commas: --centre-mm 0,0,10;"),
            std::string::npos)
      << r.err;
  r = run({"import", "circle", "x.csv", "--radius-mm", "2", "--centre-mm=1", "2", "3"});
  EXPECT_NE(r.err.find("not expected: 2 3 (--centre-mm takes x,y,z with commas: --centre-mm 1,2,3;"), std::string::npos)
      << r.err;
  // No hint where commas would not do: a value with its commas and one more, or a word.
  for (const auto& given : std::vector<std::vector<std::string>>{{"1,2,3", "4"}, {"1", "foo"}}) {
    std::vector<std::string> args = {"import", "circle", "x.csv", "--radius-mm", "100", "--centre-mm"};
    args.insert(args.end(), given.begin(), given.end());
    r = run(args);
    EXPECT_EQ(r.code, 2);
    EXPECT_EQ(r.err.find("takes x,y,z with commas"), std::string::npos) << r.err;
  }
  r = run({"show", "1", "2", "3"});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("these arguments were not expected: 2 3 (mtcal help COMMAND lists its options)"),
            std::string::npos)
      << r.err;
  const auto campaign = nlohmann::json::parse(run({"--json", "show", "2"}).out)["campaign_id"].get<int>();
  EXPECT_EQ(ids({"--campaign", "c" + std::to_string(campaign)}), std::vector<int>{2});
  r = run({"runs", "--sort", "colour"});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("sort by one of id, started"), std::string::npos) << r.err;
}

TEST_F(ArchiveCli, ARunIsRenamedAndAnnotated) {
  ASSERT_EQ(run({"rename", "1", "X after repair"}).code, 0);
  ASSERT_EQ(run({"--operator", "Q. Engineer", "note", "1", "beam clipped near 600 mm"}).code, 0);
  const auto shown = run({"show", "1"});
  EXPECT_NE(shown.out.find("run 1: X after repair"), std::string::npos) << shown.out;
  EXPECT_NE(shown.out.find("Q. Engineer: beam clipped near 600 mm"), std::string::npos) << shown.out;
  EXPECT_NE(shown.out.find("iso230-2"), std::string::npos) << shown.out;  // its stored result
  const auto j = nlohmann::json::parse(run({"--json", "show", "1"}).out);
  EXPECT_EQ(j["notes"][0]["author"], "Q. Engineer");
  EXPECT_EQ(run({"rename", "9", "x"}).code, 2);
  // A name heads tables and reports: one line, not blank.
  auto refused = run({"rename", "1", "a\nb"});
  EXPECT_EQ(refused.code, 2);
  EXPECT_NE(refused.err.find("a run's name is one line of text: character 2 is 0x0A, a control character"),
            std::string::npos)
      << refused.err;
  EXPECT_EQ(run({"rename", "1", "  "}).code, 2);
  EXPECT_EQ(run({"note", "1", ""}).code, 2);
}

TEST_F(ArchiveCli, DeletingAsksAndTakesEverythingOfTheRunOrCampaign) {
  auto r = run({"delete", "1"}, "no\n");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("run 1 X before repair (linear"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("nothing deleted"), std::string::npos) << r.err;
  EXPECT_EQ(ids({}).size(), 3u);
  r = run({"--json", "delete", "1"});
  EXPECT_EQ(r.code, 2);  // nobody to ask under --json
  EXPECT_NE(r.err.find("confirm with --yes"), std::string::npos) << r.err;
  r = run({"delete", "1"}, "yes\n");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(ids({}), (std::vector<int>{2, 3}));
  const auto campaign = nlohmann::json::parse(run({"--json", "show", "3"}).out)["campaign_id"].get<int>();
  r = run({"--json", "delete", "c" + std::to_string(campaign), "--yes"});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(nlohmann::json::parse(r.out)["deleted_runs"], nlohmann::json::array({3}));
  EXPECT_EQ(ids({}), std::vector<int>{2});
  // Nothing of the deleted runs is left behind.
  r = run({"--json", "check"});
  EXPECT_EQ(r.code, 0) << r.out;
  EXPECT_TRUE(nlohmann::json::parse(r.out)["sound"].get<bool>());
  storage::Store store(db_);
  storage::Statement left(
      store.database(),
      "SELECT (SELECT COUNT(*) FROM targets WHERE run_id = 1) + (SELECT COUNT(*) FROM results WHERE "
      "run_id = 1) + (SELECT COUNT(*) FROM circle_points WHERE run_id = 3) + (SELECT COUNT(*) FROM "
      "channel_values WHERE channel_id NOT IN (SELECT id FROM channels))");
  left.step();
  EXPECT_EQ(left.getInt(0), 0);
  EXPECT_EQ(run({"delete", "c999", "--yes"}).code, 2);
  EXPECT_EQ(run({"delete", "x1", "--yes"}).code, 2);
}

TEST_F(ArchiveCli, ABackupIsAWholeArchiveAndTheCheckNamesWhatIsWrong) {
  const std::string copy = dir_.file("copy.sqlite");
  auto r = run({"backup", copy});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(run({"backup", copy}).code, 2);  // never over an existing file
  const auto nowhere = run({"backup", dir_.file("nowhere/copy.sqlite")});
  EXPECT_EQ(nowhere.code, 2);
  EXPECT_NE(nowhere.err.find("there is no folder"), std::string::npos) << nowhere.err;
  r = cli({"--db", copy, "--json", "runs"});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(nlohmann::json::parse(r.out)["runs"].size(), 3u);
  EXPECT_EQ(cli({"--db", copy, "check"}).code, 0);
  {
    // Rows that belong to no run, as a plain SQL delete with foreign keys off leaves them.
    storage::Store store(copy);
    store.database().exec("PRAGMA foreign_keys = OFF; DELETE FROM runs WHERE id = 3");
  }
  r = cli({"--db", copy, "check"});
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("row(s) of circle_points belong to no run"), std::string::npos) << r.out;
  // A file no command can open as a store: the check says what SQLite finds, where the others
  // send the engineer.
  const std::string garbage = dir_.file("garbage.sqlite");
  std::ofstream(garbage) << std::string(8192, 'x');
  r = cli({"--db", garbage, "runs"});
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("is damaged or not an mtcal store (file is not a database): mtcal check lists"),
            std::string::npos)
      << r.err;
  r = cli({"--db", garbage, "demo"});  // refused before the demo says what it will do
  EXPECT_EQ(r.code, 1);
  EXPECT_EQ(r.out, "");
  EXPECT_NE(r.err.find("is damaged or not an mtcal store"), std::string::npos) << r.err;
  r = cli({"--db", garbage, "check"});
  EXPECT_EQ(r.code, 1) << r.err;
  EXPECT_NE(r.out.find("file is not a database"), std::string::npos) << r.out << r.err;
  EXPECT_EQ(cli({"--db", dir_.file("none.sqlite"), "check"}).code, 1);  // a missing store: not made
  EXPECT_FALSE(std::filesystem::exists(dir_.file("none.sqlite")));
  // A folder given for the store, or a store in a folder that does not exist: said so, as bad
  // input.
  r = cli({"--db", dir_.file(""), "runs"});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("is a folder, not a store file"), std::string::npos) << r.err;
  r = cli({"--db", dir_.file("no/such/folder/s.sqlite"), "import", "est", MTCAL_EXAMPLES_DIR "/est/guideway_400mm.csv",
           "--spacing-mm", "20"});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("/no/such/folder' does not exist"), std::string::npos) << r.err;
  r = cli({"--db", copy, "serve", "--port", "70000"});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("--port: must be from 0 to 65535, got 70000"), std::string::npos) << r.err;
}

}  // namespace
}  // namespace mtcal::app
