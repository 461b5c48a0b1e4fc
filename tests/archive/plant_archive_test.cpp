// The plant archive against a real PostgreSQL 15 server (tests/archive/postgres-server,
// started once for the suite on a Unix socket): runs of every kind pushed and pulled back
// unchanged, pushes repeated, changed, deleted, cut off and run side by side.

#include "mtcal/archive/plant_archive.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "../support/cli_run.h"
#include "../support/http_client.h"
#include "../support/temp_dir.h"
#include "../support/time_scale.h"
#include "mtcal/archive/plant_schema.h"
#include "mtcal/archive/postgres.h"
#include "mtcal/error.h"
#include "mtcal/storage/store.h"

namespace mtcal::archive {
namespace {

using mtcal::testing::cli;

/// The suite's server, and a database of its own for each test.
class PlantArchive : public ::testing::Test {
 public:
  void SetUp() override {
    const char* info = std::getenv("MTCAL_TEST_POSTGRES_INFO");
    ASSERT_NE(info, nullptr) << "the tests run under ctest, which starts the server (postgres_start)";
    std::ifstream in(info);
    ASSERT_TRUE(std::getline(in, socket_dir_) && std::getline(in, port_)) << "no server: " << info;
    database_ = "t_" + std::string(::testing::UnitTest::GetInstance()->current_test_info()->name());
    for (auto& ch : database_) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
    Connection admin(address("postgres"));
    admin.exec("DROP DATABASE IF EXISTS " + database_ + " WITH (FORCE)");
    admin.exec("CREATE DATABASE " + database_);
  }
  void TearDown() override {
    if (database_.empty()) return;
    Connection admin(address("postgres"));
    admin.exec("DROP DATABASE IF EXISTS " + database_ + " WITH (FORCE)");
  }
  /// On the server's Unix socket, as `user` (trusted there).
  std::string address(const std::string& database, const std::string& user = "mtcal") const {
    return "postgresql:///" + database + "?host=" + socket_dir_ + "&port=" + port_ + "&user=" + user;
  }
  std::string archive(const std::string& user = "mtcal") const { return address(database_, user); }
  /// Creates a login role (roles belong to the whole server: made once) in `group`.
  void role(const std::string& name, const std::string& group) {
    Connection admin(address("postgres"));
    admin.exec("DO $$ BEGIN IF NOT EXISTS (SELECT FROM pg_roles WHERE rolname = '" + name + "') THEN CREATE ROLE " +
               name + " LOGIN; END IF; END $$");
    admin.exec("GRANT " + group + " TO " + name);
  }

  /// A store with runs of the kinds that import in an instant: a linear run with an
  /// auxiliary channel and an analysis, a circle, probe steps, a thermal run, and a note.
  std::string quickStore(const std::string& name) {
    const std::string db = dir_.file(name);
    const auto ok = [&](std::vector<std::string> args) {
      args.insert(args.begin(), {"--db", db});
      const auto r = cli(args);
      ASSERT_EQ(r.code, 0) << r.err;
    };
    ok({"import", "linear", std::string(MTCAL_TEST_DATA_DIR) + "/linear_deviation.csv", "--name", "X " + name});
    ok({"import", "circle", MTCAL_EXAMPLES_DIR "/circle/xy_r100_export.csv", "--radius-mm", "100"});
    ok({"import", "est", MTCAL_EXAMPLES_DIR "/est/guideway_400mm.csv", "--spacing-mm", "20"});
    ok({"import", "thermal", MTCAL_EXAMPLES_DIR "/thermal/spindle-warmup-8h.csv"});
    ok({"analyze", "iso230-2", "1"});
    ok({"note", "2", "reflector cleaned"});
    return db;
  }
  nlohmann::json json(std::vector<std::string> args) {
    args.insert(args.begin(), "--json");
    const auto r = cli(args);
    EXPECT_EQ(r.code, 0) << r.err;
    return r.code == 0 ? nlohmann::json::parse(r.out) : nlohmann::json();
  }
  std::int64_t rows(const std::string& sql) {
    Connection c(archive());
    return std::stoll(c.scalar(sql).value_or("-1"));
  }

  mtcal::testing::TempDir dir_;
  std::string socket_dir_, port_, database_;
};

std::map<std::string, int> outcomes(const nlohmann::json& pushed) {
  std::map<std::string, int> out;
  for (const auto& r : pushed["runs"]) ++out[r["outcome"].get<std::string>()];
  return out;
}

TEST_F(PlantArchive, EveryKindPushedAndPulledBackAnalysesTheSame) {
  const std::string db = dir_.file("station.sqlite");
  const auto ok = [&](std::vector<std::string> args) {
    args.insert(args.begin(), {"--db", db});
    const auto r = cli(args);
    ASSERT_EQ(r.code, 0) << r.err;
  };
  // Acquired runs with raw samples, environment and events, and imported ones of every kind.
  ok({"demo", "--time-scale", mtcal::testing::timeScaleArg(400)});
  ok({"import", "linear", std::string(MTCAL_TEST_DATA_DIR) + "/linear_deviation.csv"});
  ok({"import", "circle", MTCAL_EXAMPLES_DIR "/circle/xy_r100_export.csv", "--radius-mm", "100"});
  ok({"import", "est", MTCAL_EXAMPLES_DIR "/est/guideway_400mm.csv", "--spacing-mm", "20"});
  ok({"gantry", "run", MTCAL_EXAMPLES_DIR "/plans/gantry/quick-6x2.json", "--machine-config",
      MTCAL_EXAMPLES_DIR "/machines/gantry-drilling.json", "--time-scale", mtcal::testing::timeScaleArg(400.0),
      "--trials", "20"});
  ok({"run", "thermal", MTCAL_EXAMPLES_DIR "/plans/thermal/quick-2h.json", "--time-scale",
      mtcal::testing::timeScaleArg(3000), "--seed", "5"});
  const auto local = json({"--db", db, "runs"})["runs"];
  ASSERT_EQ(local.size(), 6u);

  const auto pushed = json({"--db", db, "archive", "push", "--to", archive(), "--station", "bay-1"});
  EXPECT_EQ(outcomes(pushed), (std::map<std::string, int>{{"new", 6}}));
  storage::Store store(db);
  EXPECT_EQ(rows("SELECT count(*) FROM samples"), store.sampleCount(1));
  EXPECT_GT(store.sampleCount(1), 1000);
  EXPECT_EQ(pushed["rows_sent"].get<std::int64_t>(),
            rows("SELECT (SELECT count(*) FROM samples) + (SELECT count(*) FROM targets) + (SELECT count(*) FROM "
                 "environment) + (SELECT count(*) FROM channels) + (SELECT count(*) FROM channel_values) + (SELECT "
                 "count(*) FROM results) + (SELECT count(*) FROM events) + (SELECT count(*) FROM run_notes) + (SELECT "
                 "count(*) FROM run_instruments) + (SELECT count(*) FROM probe_steps) + (SELECT count(*) FROM "
                 "circle_points) + (SELECT count(*) FROM tracker_points) + (SELECT count(*) FROM thermal_channels) + "
                 "(SELECT count(*) FROM thermal_samples) + (SELECT count(*) FROM thermal_values)"));

  const auto listed = json({"archive", "runs", "--from", archive()})["runs"];
  ASSERT_EQ(listed.size(), 6u);
  const std::string copy = dir_.file("office.sqlite");
  const auto pulled = json({"--db", copy, "archive", "pull", "c" + std::to_string(listed[0]["campaign_id"].get<int>()),
                            "--from", archive()});
  // The demo's campaign: the other runs are each in a campaign of their own.
  for (const auto& run : listed) {
    if (run["campaign_id"] != listed[0]["campaign_id"])
      json({"--db", copy, "archive", "pull", std::to_string(run["id"].get<int>()), "--from", archive()});
  }
  const auto copied = json({"--db", copy, "runs"})["runs"];
  ASSERT_EQ(copied.size(), 6u);
  for (std::size_t i = 0; i < 6; ++i) {
    SCOPED_TRACE(local[i]["kind"].get<std::string>());
    EXPECT_EQ(copied[i]["uuid"], local[i]["uuid"]);
    for (const char* key :
         {"kind", "axis", "name", "status", "started_at", "finished_at", "measured", "machine", "campaign"})
      EXPECT_EQ(copied[i][key], local[i][key]) << key;
  }
  // Analyses of the copies: the same numbers as of the originals.
  const auto same = [&](std::vector<std::string> analysis) {
    SCOPED_TRACE(analysis[0] + " " + analysis[1]);
    auto there = analysis;
    there.insert(there.begin(), {"--db", copy});
    analysis.insert(analysis.begin(), {"--db", db});
    EXPECT_EQ(json(there), json(analysis));
  };
  same({"analyze", "iso230-2", "1"});
  same({"analyze", "iso230-2", "2"});
  same({"analyze", "iso230-4", "3"});
  same({"analyze", "est", "4"});
  same({"analyze", "gantry", "5", "--trials", "20"});
  same({"thermal", "fit", "6", "--target", "drift_z_um"});
  EXPECT_EQ(storage::Store(copy).sampleCount(1), store.sampleCount(1));
  // Each target still points at its own raw samples.
  storage::Store copied_store(copy);
  const auto targets = store.targets(1);
  ASSERT_GT(targets.size(), 2u);
  for (const auto seq : {targets.front().seq, targets[targets.size() / 2].seq, targets.back().seq}) {
    const auto here = store.samplesOfTarget(1, seq), there = copied_store.samplesOfTarget(1, seq);
    ASSERT_FALSE(here.empty());
    ASSERT_EQ(there.size(), here.size()) << seq;
    EXPECT_EQ(there.front().device_seq, here.front().device_seq);
    EXPECT_EQ(there.back().value, here.back().value);
  }
  EXPECT_EQ(storage::Store(copy).environment(1).size(), store.environment(1).size());

  // Pulled again: already there, nothing written.
  const auto again = json({"--db", copy, "archive", "pull", "1", "--from", archive()});
  EXPECT_TRUE(again["runs"][0]["already_here"].get<bool>());
  EXPECT_EQ(json({"--db", copy, "runs"})["runs"].size(), 6u);
}

TEST_F(PlantArchive, PushingTwiceChangesNothingAndAChangeIsANewVersion) {
  const std::string db = quickStore("station.sqlite");
  auto pushed = json({"--db", db, "archive", "push", "--to", archive(), "--station", "bay-1"});
  EXPECT_EQ(outcomes(pushed), (std::map<std::string, int>{{"new", 4}}));
  const auto versions = rows("SELECT count(*) FROM run_versions");
  const auto values = rows("SELECT count(*) FROM thermal_values");
  EXPECT_EQ(versions, 4);

  pushed = json({"--db", db, "archive", "push", "--to", archive(), "--station", "bay-1"});
  EXPECT_EQ(outcomes(pushed), (std::map<std::string, int>{{"unchanged", 4}}));
  EXPECT_EQ(pushed["rows_sent"], 0);
  EXPECT_EQ(rows("SELECT count(*) FROM run_versions"), versions);

  // Renamed and noted after the push: a second version that sends the changed part only
  // (one note), and keeps the first as it was.
  ASSERT_EQ(cli({"--db", db, "rename", "4", "warm-up, 8 h"}).code, 0);
  ASSERT_EQ(cli({"--db", db, "note", "4", "sensor T3 loose"}).code, 0);
  pushed = json({"--db", db, "archive", "push", "--to", archive(), "--station", "bay-1"});
  EXPECT_EQ(outcomes(pushed), (std::map<std::string, int>{{"changed", 1}, {"unchanged", 3}}));
  EXPECT_EQ(pushed["rows_sent"], 1);
  EXPECT_EQ(rows("SELECT count(*) FROM thermal_values"), values);
  EXPECT_EQ(rows("SELECT max(version) FROM run_versions"), 2);
  Connection c(archive());
  EXPECT_EQ(c.scalar("SELECT name FROM run_versions WHERE version = 1 AND kind = 'thermal'"), "spindle-warmup-8h.csv");
  EXPECT_EQ(c.scalar("SELECT name FROM run_versions WHERE version = 2"), "warm-up, 8 h");
  EXPECT_EQ(c.scalar("SELECT (parts->'thermal_values'->>'version') FROM run_versions WHERE version = 2"), "1");

  // The newest version is what a pull brings.
  const std::string copy = dir_.file("copy.sqlite");
  const auto pulled = json({"--db", copy, "archive", "pull", "4", "--from", archive()});
  EXPECT_EQ(pulled["runs"][0]["version"], 2);
  const auto run = json({"--db", copy, "show", "1"});
  EXPECT_EQ(run["name"], "warm-up, 8 h");
  EXPECT_EQ(run["notes"].size(), 1u);

  // The run's history: both versions, who pushed them and what each sent; the first one
  // still pulls as it was.
  const auto history = json({"archive", "history", "4", "--from", archive()})["runs"];
  ASSERT_EQ(history.size(), 2u);
  EXPECT_EQ(history[0]["version"], 1);
  EXPECT_EQ(history[0]["name"], "spindle-warmup-8h.csv");
  EXPECT_EQ(history[0]["pushed_by"], "mtcal");
  EXPECT_EQ(history[1]["parts_sent"], nlohmann::json::array({"run_notes"}));
  EXPECT_NE(history[0]["sha256"], history[1]["sha256"]);
  const std::string first = dir_.file("first.sqlite");
  const auto old = json({"--db", first, "archive", "pull", "4@1", "--from", archive()});
  EXPECT_EQ(old["runs"][0]["version"], 1);
  EXPECT_EQ(json({"--db", first, "show", "1"})["name"], "spindle-warmup-8h.csv");
  EXPECT_TRUE(json({"--db", first, "show", "1"})["notes"].empty());
  const auto r = cli({"archive", "pull", "4@3", "--from", archive()});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("has no run 4 with a version 3"), std::string::npos) << r.err;
}

TEST_F(PlantArchive, AModelIsPushedOnceAndPredictsTheSameWherePulled) {
  const std::string db = quickStore("station.sqlite");
  const std::string machine = MTCAL_EXAMPLES_DIR "/machines/vmc3-cn104200063.model.json";
  ASSERT_EQ(
      cli({"--db", db, "model", "import", MTCAL_EXAMPLES_DIR "/models/vmc3-error-curves.csv", "--machine", machine})
          .code,
      0);
  auto pushed = json({"--db", db, "archive", "push", "--to", archive(), "--station", "bay-1"});
  ASSERT_EQ(pushed["models"].size(), 1u);
  pushed = json({"--db", db, "archive", "push", "--to", archive(), "--station", "bay-1"});
  EXPECT_TRUE(pushed["models"].empty());
  EXPECT_EQ(rows("SELECT count(*) FROM models"), 1);
  EXPECT_GT(rows("SELECT count(*) FROM model_errors"), 0);

  const std::string copy = dir_.file("copy.sqlite");
  ASSERT_EQ(
      cli({"--db", copy, "import", "est", MTCAL_EXAMPLES_DIR "/est/guideway_400mm.csv", "--spacing-mm", "20"}).code, 0);
  const auto pulled = json({"--db", copy, "archive", "pull", "m1", "--from", archive()});
  ASSERT_EQ(pulled["models"].size(), 1u);
  EXPECT_EQ(pulled["models"][0]["station"], "bay-1");
  const auto grid = std::vector<std::string>{"--grid", "50:600:3,0:100:2,200:200:1"};
  auto there = std::vector<std::string>{"--db", copy, "model", "predict", "1"};
  auto here = std::vector<std::string>{"--db", db, "model", "predict", "1"};
  there.insert(there.end(), grid.begin(), grid.end());
  here.insert(here.end(), grid.begin(), grid.end());
  EXPECT_EQ(json(there)["points"], json(here)["points"]);
  // And read from the archive directly.
  ASSERT_EQ(::setenv("XDG_CACHE_HOME", dir_.file("cache").c_str(), 1), 0);
  EXPECT_EQ(json({"--db", archive(), "model", "list"})["models"].size(), 1u);
  ::unsetenv("XDG_CACHE_HOME");
  EXPECT_TRUE(json({"--db", copy, "archive", "pull", "m1", "--from", archive()})["models"][0]["already_here"]);
}

// A model names the runs it was identified from by number: in the archive by the archive's
// numbers, in a store by the store's, and runs a store does not hold are said, not mistaken
// for the runs it holds under those numbers.
TEST_F(PlantArchive, AModelsRunsAreNumberedWhereverItIsRead) {
  const std::string other = quickStore("other.sqlite");  // pushed first: it takes archive runs 1..4
  json({"--db", other, "archive", "push", "--to", archive(), "--station", "bay-2"});
  const std::string db = quickStore("station.sqlite");
  ASSERT_EQ(cli({"--db", db, "import", "linear", std::string(MTCAL_TEST_DATA_DIR) + "/linear_deviation.csv"}).code, 0);
  ASSERT_EQ(cli({"--db", db, "model", "identify", "5", "--machine",
                 MTCAL_EXAMPLES_DIR "/machines/vmc3-cn104200063.model.json"})
                .code,
            0);
  const auto pushed = json({"--db", db, "archive", "push", "--to", archive(), "--station", "bay-1"});
  std::int64_t archived = 0;
  for (const auto& r : pushed["runs"])
    if (r["run_id"] == 5) archived = r["archive_id"].get<std::int64_t>();
  EXPECT_EQ(archived, 9);
  EXPECT_EQ(rows("SELECT count(*) FROM models WHERE provenance_json::jsonb -> 'runs' = '[9]'"), 1);

  const auto identifiedFrom = [&](const std::string& store) {
    const auto html = dir_.file("model.html");
    const auto r = cli({"--db", store, "report", "m1", "-o", html});
    EXPECT_EQ(r.code, 0) << r.err;
    std::stringstream text;
    text << std::ifstream(html).rdbuf();
    const auto at = text.str().find("<tr><th>Identified from</th><td>");
    return at == std::string::npos ? std::string() : text.str().substr(at, text.str().find("</td>", at) - at + 5);
  };
  EXPECT_EQ(identifiedFrom(db), "<tr><th>Identified from</th><td>runs 5</td>");
  ASSERT_EQ(::setenv("XDG_CACHE_HOME", dir_.file("cache").c_str(), 1), 0);  // read from the archive
  EXPECT_EQ(identifiedFrom(archive()), "<tr><th>Identified from</th><td>runs 9</td>");
  ::unsetenv("XDG_CACHE_HOME");
  // Pulled into a store that does not hold the run: said, not mistaken for one of its own.
  const auto pulled = json({"--db", other, "archive", "pull", "m1", "--from", archive()});
  ASSERT_EQ(pulled["models"].size(), 1u);
  EXPECT_EQ(identifiedFrom(other),
            "<tr><th>Identified from</th><td>1 run(s) this store does not hold (pulled from the plant "
            "archive)</td>");
}

TEST_F(PlantArchive, ADeletedRunIsATombstoneAndItsHistoryStays) {
  const std::string db = quickStore("station.sqlite");
  json({"--db", db, "archive", "push", "--to", archive(), "--station", "bay-1"});
  ASSERT_EQ(cli({"--db", db, "delete", "3", "--yes"}).code, 0);
  const auto pushed = json({"--db", db, "archive", "push", "--to", archive(), "--station", "bay-1"});
  EXPECT_EQ(outcomes(pushed), (std::map<std::string, int>{{"deleted", 1}, {"unchanged", 3}}));
  EXPECT_EQ(rows("SELECT count(*) FROM probe_steps"), 21 * 3);  // the rows stay: a version says deleted
  const auto listed = json({"archive", "runs", "--from", archive()})["runs"];
  ASSERT_EQ(listed.size(), 4u);
  EXPECT_TRUE(listed[2]["deleted"].get<bool>());
  EXPECT_EQ(listed[2]["version"], 2);
  const auto r = cli({"--db", dir_.file("copy.sqlite"), "archive", "pull", "3", "--from", archive()});
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.err.find("was deleted (version 2, by station bay-1"), std::string::npos) << r.err;
  // A new store of the same station does not delete what another store pushed.
  const std::string other = quickStore("other.sqlite");
  const auto second = json({"--db", other, "archive", "push", "--to", archive(), "--station", "bay-1"});
  EXPECT_EQ(outcomes(second), (std::map<std::string, int>{{"new", 4}}));
  EXPECT_EQ(rows("SELECT count(*) FROM run_versions WHERE tombstone"), 1);
  // A run deleted here and pulled back before the next push stays.
  ASSERT_EQ(cli({"--db", db, "delete", "2", "--yes"}).code, 0);
  json({"--db", db, "archive", "pull", "2", "--from", archive()});
  const auto third = json({"--db", db, "archive", "push", "--to", archive(), "--station", "bay-1"});
  EXPECT_EQ(outcomes(third), (std::map<std::string, int>{{"unchanged", 3}}));
  EXPECT_EQ(rows("SELECT count(*) FROM run_versions WHERE tombstone"), 1);
}

TEST_F(PlantArchive, ACopyOfAStoreNeitherDeletesNorOverwritesWhatItDidNotSee) {
  const std::string db = quickStore("station.sqlite");
  const std::string yesterday = dir_.file("yesterday.sqlite");
  ASSERT_EQ(cli({"--db", db, "backup", yesterday}).code, 0);
  json({"--db", db, "archive", "push", "--to", archive(), "--station", "bay-1"});
  // Today: a new run, a note on run 1, both pushed.
  ASSERT_EQ(cli({"--db", db, "import", "circle", MTCAL_EXAMPLES_DIR "/circle/xy_r100_export.csv", "--radius-mm", "100",
                 "--name", "today"})
                .code,
            0);
  ASSERT_EQ(cli({"--db", db, "note", "1", "checked again"}).code, 0);
  auto pushed = json({"--db", db, "archive", "push", "--to", archive(), "--station", "bay-1"});
  EXPECT_EQ(outcomes(pushed), (std::map<std::string, int>{{"changed", 1}, {"new", 1}, {"unchanged", 3}}));

  // Yesterday's backup restored and pushed: today's run is not deleted, run 1's note not undone.
  const auto r = cli({"--db", yesterday, "--json", "archive", "push", "--to", archive(), "--station", "bay-1"});
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("run 1 ("), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("not pushed: the archive's version 2 (by bay-1"), std::string::npos) << r.err;
  EXPECT_EQ(outcomes(nlohmann::json::parse(r.out)), (std::map<std::string, int>{{"conflict", 1}, {"unchanged", 3}}));
  EXPECT_EQ(rows("SELECT count(*) FROM run_versions WHERE tombstone"), 0);
  EXPECT_EQ(rows("SELECT max(version) FROM run_versions"), 2);

  // A store that pulled the run's newest version may change it; the station's own store then
  // is the one behind.
  const std::string office = dir_.file("office.sqlite");
  json({"--db", office, "archive", "pull", "1", "--from", archive()});
  ASSERT_EQ(cli({"--db", office, "rename", "1", "X, renamed in the office"}).code, 0);
  pushed = json({"--db", office, "archive", "push", "--to", archive(), "--station", "office"});
  EXPECT_EQ(outcomes(pushed), (std::map<std::string, int>{{"changed", 1}}));
  ASSERT_EQ(cli({"--db", db, "rename", "1", "X, renamed at the machine"}).code, 0);
  EXPECT_EQ(cli({"--db", db, "archive", "push", "--to", archive(), "--station", "bay-1"}).code, 1);
  EXPECT_EQ(json({"archive", "runs", "--from", archive()})["runs"][0]["name"], "X, renamed in the office");
  // Deleting a run whose newest version this store has not seen: a conflict too.
  ASSERT_EQ(cli({"--db", db, "delete", "1", "--yes"}).code, 0);
  pushed = nlohmann::json::parse(cli({"--db", db, "--json", "archive", "push", "--to", archive()}).out);
  EXPECT_EQ(outcomes(pushed)["conflict"], 1);
  EXPECT_EQ(rows("SELECT count(*) FROM run_versions WHERE tombstone"), 0);
}

TEST_F(PlantArchive, ACampaignWhoseRunsWereAllDeletedIsNamed) {
  const std::string db = quickStore("station.sqlite");
  json({"--db", db, "archive", "push", "--to", archive(), "--station", "bay-1"});
  ASSERT_EQ(cli({"--db", db, "delete", "c2", "--yes"}).code, 0);
  json({"--db", db, "archive", "push", "--to", archive(), "--station", "bay-1"});
  const auto r = cli({"--db", dir_.file("copy.sqlite"), "archive", "pull", "c2", "--from", archive()});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("every run of campaign c2"), std::string::npos) << r.err;
  // Numbers are given once, without gaps for pushes that changed nothing new.
  EXPECT_EQ(rows("SELECT max(id) FROM runs"), 4);
  EXPECT_EQ(rows("SELECT max(id) FROM campaigns"), 4);
}

/// Waits until a push's session waits for a lock (polling, up to 120 s: no timing to break
/// under load) and returns its server process id; 0 when none came.
int blockedPush(Connection& c) {
  for (int i = 0; i < 12000; ++i) {
    const auto rows =
        c.query("SELECT pid FROM pg_stat_activity WHERE application_name = 'mtcal push' AND wait_event_type = 'Lock'");
    if (!rows.empty()) return std::stoi(*rows[0][0]);
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return 0;
}

/// A push cut off by `cut` (given the server process of the push's session) in the middle of
/// the second run, then pushed again: nothing lost, nothing twice.
void pushCutOffAndResumed(PlantArchive& t, const std::string& db, const std::function<void(int)>& cut) {
  {
    Connection setup(t.archive());
    migratePlant(setup);
  }
  // The first run has no note, the second one: a session holding run_notes makes the push
  // wait in the middle of the second run, after its points were sent.
  Connection locker(t.archive());
  locker.exec("BEGIN");
  locker.exec("LOCK TABLE run_notes IN ACCESS EXCLUSIVE MODE");
  std::string failure;
  std::thread pushing([&] {
    try {
      storage::Store store(db);
      Connection c(t.archive(), "mtcal push");
      push(store, c, {"bay-1", "test", {}});
    } catch (const StorageError& e) {
      failure = e.what();
    }
  });
  Connection admin(t.address("postgres"));
  const int pid = blockedPush(admin);
  ASSERT_NE(pid, 0) << "the push never waited for run_notes";
  cut(pid);
  pushing.join();
  EXPECT_NE(failure.find("archive mtcal@"), std::string::npos) << failure;
  try {
    locker.exec("ROLLBACK");
  } catch (const StorageError&) {  // a restart ended it
  }
  EXPECT_EQ(t.rows("SELECT count(*) FROM run_versions"), 1);   // the first run, whole
  EXPECT_EQ(t.rows("SELECT count(*) FROM circle_points"), 0);  // the second: none of it
  const auto pushed = t.json({"--db", db, "archive", "push", "--to", t.archive(), "--station", "bay-1"});
  EXPECT_EQ(outcomes(pushed), (std::map<std::string, int>{{"new", 3}, {"unchanged", 1}}));
  storage::Store store(db);
  EXPECT_EQ(t.rows("SELECT count(*) FROM circle_points"), static_cast<std::int64_t>(store.circlePoints(2).size()));
  EXPECT_EQ(t.rows("SELECT count(*) FROM run_notes"), 1);
  EXPECT_EQ(t.rows("SELECT count(*) FROM run_versions"), 4);
  // Pulled back whole: the pull checks each run's SHA-256 against the one pushed. (The cut
  // push's campaign number was used up: numbers are unique, not without gaps.)
  const auto listed = t.json({"archive", "runs", "--from", t.archive()})["runs"];
  ASSERT_EQ(listed.size(), 4u);
  const std::string circle_campaign = "c" + std::to_string(listed[1]["campaign_id"].get<int>());
  const auto pulled =
      t.json({"--db", t.dir_.file("copy.sqlite"), "archive", "pull", circle_campaign, "--from", t.archive()});
  ASSERT_EQ(pulled["runs"].size(), 1u);
  EXPECT_EQ(pulled["runs"][0]["kind"], "circle");
}

TEST_F(PlantArchive, APushCutOffIsResumedByTheNextWithoutLossOrDuplicates) {
  const std::string db = quickStore("station.sqlite");
  pushCutOffAndResumed(*this, db, [&](int pid) {
    Connection admin(address("postgres"));
    EXPECT_EQ(admin.scalar("SELECT pg_terminate_backend($1)", {std::to_string(pid)}), "t");
  });
}

TEST_F(PlantArchive, AServerRestartInTheMiddleOfAPushLosesNothing) {
  const std::string db = quickStore("station.sqlite");
  pushCutOffAndResumed(*this, db, [&](int) {
    const std::string command =
        std::string(MTCAL_POSTGRES_SERVER) + " restart " + std::getenv("MTCAL_TEST_POSTGRES_INFO");
    ASSERT_EQ(std::system(command.c_str()), 0);
  });
}

TEST_F(PlantArchive, TwoStationsPushingAtOnceDoNotInterfere) {
  const std::string a = quickStore("a.sqlite"), b = quickStore("b.sqlite");
  std::vector<std::string> failures(2);
  std::vector<PushSummary> summaries(2);
  std::vector<std::thread> stations;
  for (int i = 0; i < 2; ++i) {
    stations.emplace_back([&, i] {
      try {
        storage::Store store(i == 0 ? a : b);
        Connection c(archive(), "mtcal push");
        summaries[static_cast<std::size_t>(i)] = push(store, c, {i == 0 ? "bay-1" : "bay-2", "test", {}});
      } catch (const std::exception& e) {
        failures[static_cast<std::size_t>(i)] = e.what();
      }
    });
  }
  for (auto& s : stations) s.join();
  EXPECT_EQ(failures, (std::vector<std::string>{"", ""}));
  EXPECT_EQ(rows("SELECT count(*) FROM run_versions"), 8);
  EXPECT_EQ(rows("SELECT count(DISTINCT station) FROM run_versions"), 2);
  EXPECT_EQ(rows("SELECT count(*) FROM stations"), 2);
  storage::Store store(a);
  EXPECT_EQ(rows("SELECT count(*) FROM thermal_values"),
            2 * static_cast<std::int64_t>(store.thermalSamples(4).size() * store.thermalChannels(4).size()));
}

/// The statement's error, empty when the server let it through.
std::string refusal(Connection& c, const std::string& sql) {
  try {
    c.exec(sql);
  } catch (const StorageError& e) {
    return e.what();
  }
  return "";
}

TEST_F(PlantArchive, AStationAddsItsOwnRowsOnlyAndNobodyAltersThem) {
  // The administrator creates the archive (the first push migrates it); stations and a
  // quality engineer log in as roles of their own.
  const std::string db = quickStore("bay1.sqlite");
  json({"--db", quickStore("admin.sqlite"), "archive", "push", "--to", archive(), "--station", "office"});
  role("bay1", "mtcal_station");
  role("bay2", "mtcal_station");
  role("qa", "mtcal_quality");

  auto r = cli({"--db", db, "archive", "push", "--to", archive("bay1"), "--station", "bay2"});
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.err.find("connected to the archive as station bay1"), std::string::npos) << r.err;
  const auto pushed = json({"--db", db, "archive", "push", "--to", archive("bay1")});
  EXPECT_EQ(pushed["station"], "bay1");
  EXPECT_EQ(outcomes(pushed), (std::map<std::string, int>{{"new", 4}}));
  EXPECT_EQ(rows("SELECT count(*) FROM run_versions WHERE station = 'bay1'"), 4);

  Connection bay2(archive("bay2"));
  const std::string run = *bay2.scalar("SELECT run_uuid FROM run_versions WHERE station = 'bay1' LIMIT 1");
  for (const std::string sql : {"UPDATE run_versions SET name = 'better' WHERE station = 'bay1'", "DELETE FROM samples",
                                "DELETE FROM run_versions WHERE station = 'bay1'", "TRUNCATE circle_points",
                                "UPDATE run_notes SET text = 'never cleaned'"}) {
    EXPECT_NE(refusal(bay2, sql).find("permission denied"), std::string::npos) << sql;
  }
  // Rows in bay1's name, rows added to bay1's version, to a version of its own pushed before:
  // all refused.
  const auto forged = [&](const std::string& station, const std::string& run_uuid) {
    return refusal(bay2, "INSERT INTO run_notes VALUES ('" + run_uuid + "', 1, '" + station +
                             "', 5, 'x', 'forged', '2026-01-01')");
  };
  EXPECT_NE(forged("bay1", run).find("station bay2 may add rows to run_notes, in its own name, only to the version"),
            std::string::npos)
      << forged("bay1", run);
  EXPECT_NE(forged("bay2", run).find("foreign key"), std::string::npos);
  EXPECT_NE(refusal(bay2, "INSERT INTO run_versions SELECT * FROM run_versions WHERE station = 'bay1' LIMIT 1")
                .find("row-level security"),
            std::string::npos);
  // Nor a version of bay1's run in its own name: a tombstone would bury it.
  EXPECT_NE(refusal(bay2,
                    "INSERT INTO run_versions SELECT run_uuid, version + 1, 'bay2', store_uuid, now(), 'bay2',"
                    " pushed_with, true, '', '{}', instrument_kind, instrument_model, instrument_serial, kind, axis,"
                    " name, plan_json, status, source, software_version, started_at, finished_at, value_unit,"
                    " operator_name, compensation_json FROM run_versions WHERE station = 'bay1' LIMIT 1")
                .find("row-level security"),
            std::string::npos);
  const std::string own = quickStore("bay2.sqlite");
  json({"--db", own, "archive", "push", "--to", archive("bay2")});
  const std::string own_run = *bay2.scalar("SELECT run_uuid FROM run_versions WHERE station = 'bay2' LIMIT 1");
  EXPECT_NE(forged("bay2", own_run).find("only to the version it is pushing"), std::string::npos);
  EXPECT_NE(refusal(bay2, "INSERT INTO stations VALUES ('bay3')").find("row-level security"), std::string::npos);

  // The quality engineer reads everything and adds nothing.
  Connection qa(archive("qa"));
  EXPECT_EQ(qa.scalar("SELECT count(*) FROM run_versions"), "12");
  r = cli({"--db", db, "archive", "push", "--to", archive("qa")});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("role qa may not add to the archive"), std::string::npos) << r.err;
  EXPECT_EQ(json({"archive", "runs", "--from", archive("qa")})["runs"].size(), 12u);

  // Who pushed a version and when are the server's to say: a station writing them by SQL is
  // overruled, and a version follows the one before it.
  const auto forge = [&](int step) {
    return refusal(bay2, "INSERT INTO run_versions SELECT run_uuid, version + " + std::to_string(step) +
                             ", station, store_uuid, '2019-06-01', 'qa', pushed_with, tombstone, content_sha256,"
                             " parts, instrument_kind, instrument_model, instrument_serial, kind, axis, name,"
                             " plan_json, status, source, software_version, started_at, finished_at, value_unit,"
                             " operator_name, compensation_json FROM run_versions WHERE run_uuid = '" +
                             own_run + "' AND version = 1");
  };
  EXPECT_NE(forge(2).find("version 3 of run " + own_run + " does not follow a version 2"), std::string::npos)
      << forge(2);
  EXPECT_EQ(forge(1), "");
  EXPECT_EQ(bay2.scalar("SELECT pushed_by || ' ' || (pushed_at > now() - interval '1 hour') FROM run_versions"
                        " WHERE run_uuid = '" +
                        own_run + "' AND version = 2"),
            "bay2 true");
}

TEST_F(PlantArchive, SeveralPlantsInOneArchiveEachReadOnlyItsOwn) {
  ASSERT_EQ(::setenv("XDG_CACHE_HOME", dir_.file("cache").c_str(), 1), 0);
  // The administrator's office pushes in no plant: every reader sees its runs.
  json({"--db", quickStore("office.sqlite"), "archive", "push", "--to", archive(), "--station", "office"});
  {
    Connection admin(address("postgres"));
    for (const std::string plant : {"plant_north", "plant_south"})
      admin.exec("DO $$ BEGIN IF NOT EXISTS (SELECT FROM pg_roles WHERE rolname = '" + plant + "') THEN CREATE ROLE " +
                 plant + " NOLOGIN IN ROLE mtcal_plant; END IF; END $$");
  }
  for (const auto& [name, groups] : std::vector<std::pair<std::string, std::vector<std::string>>>{
           {"north1", {"mtcal_station", "plant_north"}},
           {"south1", {"mtcal_station", "plant_south"}},
           {"both1", {"mtcal_station", "plant_north", "plant_south"}},
           {"qa_north", {"mtcal_quality", "plant_north"}},
           {"auditor", {"mtcal_quality", "mtcal_every_plant"}}})
    for (const auto& group : groups) role(name, group);

  const std::string north = quickStore("north.sqlite");
  auto pushed = json({"--db", north, "archive", "push", "--to", archive("north1")});
  EXPECT_EQ(pushed["plant"], "plant_north");
  const auto text = cli({"--db", north, "archive", "push", "--to", archive("north1")});
  EXPECT_NE(text.out.find("as station north1 of plant plant_north: 0 new"), std::string::npos) << text.out;
  pushed = json({"--db", quickStore("south.sqlite"), "archive", "push", "--to", archive("south1")});
  EXPECT_EQ(pushed["plant"], "plant_south");
  const auto r = cli({"--db", quickStore("both.sqlite"), "archive", "push", "--to", archive("both1")});
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.err.find("station both1 is a member of the plants plant_north, plant_south: a station belongs to one"),
            std::string::npos)
      << r.err;

  const auto stations = [&](const std::string& reader) {
    std::map<std::string, int> out;
    const auto listed = json({"archive", "runs", "--from", archive(reader)});
    for (const auto& run : listed["runs"]) ++out[run["first_station"].get<std::string>()];
    return out;
  };
  EXPECT_EQ(stations("qa_north"), (std::map<std::string, int>{{"office", 4}, {"north1", 4}}));
  EXPECT_EQ(stations("north1"), (std::map<std::string, int>{{"office", 4}, {"north1", 4}}));
  EXPECT_EQ(stations("south1"), (std::map<std::string, int>{{"office", 4}, {"south1", 4}}));
  EXPECT_EQ(stations("auditor"), (std::map<std::string, int>{{"office", 4}, {"north1", 4}, {"south1", 4}}));
  // A station reads the plant recorded for it, not every plant its role is put in; before its
  // first push, its role's plant if it has one only.
  EXPECT_EQ(stations("both1"), (std::map<std::string, int>{{"office", 4}}));
  role("fresh1", "mtcal_station");
  role("fresh1", "plant_north");
  EXPECT_EQ(stations("fresh1"), (std::map<std::string, int>{{"office", 4}, {"north1", 4}}));

  // Refused by the server, not only left out by mtcal: the parts' tables are read through
  // views of the reader's plants.
  Connection qa(archive("qa_north"));
  EXPECT_NE(refusal(qa, "SELECT count(*) FROM samples").find("permission denied"), std::string::npos);
  EXPECT_EQ(qa.scalar("SELECT count(*) FROM run_versions WHERE station = 'south1'"), "0");
  EXPECT_EQ(std::stoll(*qa.scalar("SELECT count(*) FROM visible_targets")),
            rows("SELECT count(*) FROM targets WHERE station <> 'south1'"));
  EXPECT_GT(rows("SELECT count(*) FROM targets WHERE station = 'south1'"), 0);

  // A south run is not there for the north's reader; a north run pulls and reads the same.
  const std::string south_run = *Connection(archive()).scalar("SELECT uuid FROM runs WHERE station = 'south1' LIMIT 1");
  const std::string pulled = dir_.file("pulled.sqlite");
  const auto refused = cli({"--db", pulled, "archive", "pull", south_run, "--from", archive("qa_north")});
  EXPECT_NE(refused.code, 0);
  EXPECT_NE(refused.err.find("has no run " + south_run), std::string::npos) << refused.err;
  const std::string north_run =
      *Connection(archive()).scalar("SELECT id FROM runs WHERE station = 'north1' ORDER BY id LIMIT 1");
  ASSERT_EQ(cli({"--db", pulled, "archive", "pull", north_run, "--from", archive("qa_north")}).code, 0);
  auto here = json({"--db", north, "analyze", "iso230-2", "1"});
  auto there = json({"--db", archive("qa_north"), "analyze", "iso230-2", north_run});
  EXPECT_EQ(there["run_id"], std::stoll(north_run));
  for (auto* doc : {&here, &there}) {
    doc->erase("result_id");
    doc->erase("run_id");
  }
  EXPECT_EQ(there, here);
  EXPECT_EQ(json({"--db", archive("qa_north"), "runs"})["runs"].size(), 8u);

  // A station that pushed before it was given a plant is read by everyone, and told so, until
  // the administrator moves it: then its whole history is its plant's.
  role("late1", "mtcal_station");
  Connection(address("postgres")).exec("REVOKE plant_north FROM late1");
  const std::string late = quickStore("late.sqlite");
  auto warned = cli({"--json", "--db", late, "archive", "push", "--to", archive("late1")});
  EXPECT_EQ(nlohmann::json::parse(warned.out)["plant"], nullptr);
  EXPECT_NE(warned.err.find("station late1 is in no plant while the archive has plants: every reader sees its runs"),
            std::string::npos)
      << warned.err;
  EXPECT_EQ(stations("south1")["late1"], 4);
  role("late1", "plant_north");
  ASSERT_EQ(
      cli({"--db", late, "import", "circle", MTCAL_EXAMPLES_DIR "/circle/xy_r100_export.csv", "--radius-mm", "100"})
          .code,
      0);
  warned = cli({"--db", late, "archive", "push", "--to", archive("late1")});
  EXPECT_EQ(warned.code, 0) << warned.err;
  EXPECT_NE(warned.err.find("station late1 is recorded in the archive in no plant (so every reader sees its runs), but "
                            "its role is in plant plant_north: the administrator makes them agree"),
            std::string::npos)
      << warned.err;
  Connection owner(archive());
  EXPECT_NE(refusal(owner, "UPDATE stations SET plant = 'plant_nort' WHERE name = 'late1'")
                .find("plant plant_nort is not a plant: a plant is a role in mtcal_plant"),
            std::string::npos);
  owner.exec("UPDATE stations SET plant = 'plant_north' WHERE name = 'late1'");
  EXPECT_EQ(stations("south1").count("late1"), 0u);
  EXPECT_EQ(stations("qa_north")["late1"], 5);
  warned = cli({"--db", late, "archive", "push", "--to", archive("late1")});
  EXPECT_EQ(warned.err.find("is recorded in the archive"), std::string::npos) << warned.err;

  // A version the administrator pushes of a north run goes with the run: the south reads none
  // of it.
  const std::string office = dir_.file("office-copy.sqlite");
  json({"--db", office, "archive", "pull", north_run, "--from", archive()});
  ASSERT_EQ(cli({"--db", office, "note", "1", "checked by the office"}).code, 0);
  const auto by_office = json({"--db", office, "archive", "push", "--to", archive(), "--station", "office"});
  EXPECT_EQ(outcomes(by_office)["changed"], 1);
  EXPECT_EQ(by_office["runs"][0]["archive_id"], std::stoll(north_run));  // its number in the archive, not here (1)
  Connection south(archive("south1"));
  EXPECT_EQ(
      south.scalar("SELECT count(*) FROM run_versions v JOIN runs r ON r.uuid = v.run_uuid WHERE r.id = " + north_run),
      "0");
  EXPECT_EQ(south.scalar("SELECT count(*) FROM visible_run_notes WHERE text = 'checked by the office'"), "0");
  EXPECT_EQ(rows("SELECT count(*) FROM run_notes WHERE text = 'checked by the office'"), 1);
  EXPECT_EQ(qa.scalar("SELECT count(*) FROM visible_run_notes WHERE text = 'checked by the office'"), "1");
  // A run the office adds on the north's machine is listed with that machine: for the north,
  // not for the south.
  ASSERT_EQ(cli({"--db", office, "import", "linear", std::string(MTCAL_TEST_DATA_DIR) + "/linear_deviation.csv",
                 "--name", "X office re-run"})
                .code,
            0);
  EXPECT_EQ(outcomes(json({"--db", office, "archive", "push", "--to", archive(), "--station", "office"}))["new"], 1);
  EXPECT_EQ(stations("qa_north")["office"], 5);
  EXPECT_EQ(stations("south1")["office"], 4);
  EXPECT_EQ(
      qa.scalar("SELECT count(*) FROM run_versions v JOIN runs r ON r.uuid = v.run_uuid WHERE r.id = " + north_run),
      "2");

  // A plant's role dropped: its stations still read and push their own runs.
  {
    Connection admin(address("postgres"));
    admin.exec(
        "DO $$ BEGIN IF NOT EXISTS (SELECT FROM pg_roles WHERE rolname = 'plant_gone') THEN CREATE ROLE "
        "plant_gone NOLOGIN IN ROLE mtcal_plant; END IF; END $$");
  }
  role("gone1", "mtcal_station");
  role("gone1", "plant_gone");
  const std::string gone = quickStore("gone.sqlite");
  EXPECT_EQ(json({"--db", gone, "archive", "push", "--to", archive("gone1")})["plant"], "plant_gone");
  Connection(address("postgres")).exec("DROP ROLE plant_gone");
  ASSERT_EQ(cli({"--db", gone, "note", "1", "after the plant went"}).code, 0);
  EXPECT_EQ(outcomes(json({"--db", gone, "archive", "push", "--to", archive("gone1")}))["changed"], 1);
  EXPECT_EQ(stations("gone1")["gone1"], 4);
  ::unsetenv("XDG_CACHE_HOME");
}

TEST_F(PlantArchive, OverTcpTheConnectionIsEncryptedAndThePasswordStaysInItsFile) {
  {
    Connection admin(address("postgres"));
    admin.exec(
        "DO $$ BEGIN IF NOT EXISTS (SELECT FROM pg_roles WHERE rolname = 'archivist') THEN CREATE ROLE "
        "archivist LOGIN SUPERUSER; END IF; END $$");
    admin.exec("ALTER ROLE archivist PASSWORD 'Kx7-tls-only'");
    admin.exec("ALTER DATABASE " + database_ + " OWNER TO archivist");  // it makes the archive
  }
  // The password in a pgpass file (mode 0600), never in the address.
  const std::string passfile = dir_.file("pgpass");
  {
    std::ofstream out(passfile);
    out << "127.0.0.1:" << port_ << ":*:archivist:Kx7-tls-only\n";
  }
  std::filesystem::permissions(passfile, std::filesystem::perms::owner_read | std::filesystem::perms::owner_write);
  ASSERT_EQ(::setenv("PGPASSFILE", passfile.c_str(), 1), 0);
  const std::string tcp = "postgresql://archivist@127.0.0.1:" + port_ + "/" + database_;
  const std::string verified = tcp + "?sslmode=verify-full&sslrootcert=" + socket_dir_ + "/server.crt";

  const std::string db = quickStore("station.sqlite");
  const auto r = cli({"--db", db, "--log-level", "debug", "archive", "push", "--to", verified, "--station", "bay-1"});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(r.err.find("Kx7"), std::string::npos) << r.err;
  EXPECT_EQ(r.out.find("Kx7"), std::string::npos) << r.out;
  Connection c(verified);
  EXPECT_EQ(c.scalar("SELECT ssl FROM pg_stat_ssl WHERE pid = pg_backend_pid()"), "t");
  EXPECT_EQ(c.scalar("SELECT count(*) FROM run_versions"), "4");

  // Without TLS the server refuses; a certificate from elsewhere is refused by the client.
  auto refused = cli({"archive", "runs", "--from", tcp + "?sslmode=disable"});
  EXPECT_NE(refused.code, 0);
  EXPECT_NE(refused.err.find("no encryption"), std::string::npos) << refused.err;
  refused = cli({"archive", "runs", "--from", tcp + "?sslmode=verify-full&sslrootcert=" + passfile});
  EXPECT_NE(refused.code, 0);
  EXPECT_NE(refused.err.find("cannot connect to the archive"), std::string::npos) << refused.err;
  ::unsetenv("PGPASSFILE");
  refused = cli({"archive", "runs", "--from", verified});
  EXPECT_NE(refused.code, 0);
  EXPECT_NE(refused.err.find("password"), std::string::npos) << refused.err;
}

TEST_F(PlantArchive, ReadCommandsWorkOnTheArchiveDirectly) {
  ASSERT_EQ(::setenv("XDG_CACHE_HOME", dir_.file("cache").c_str(), 1), 0);
  const std::string db = quickStore("station.sqlite");
  ASSERT_EQ(cli({"--db", db, "import", "linear", std::string(MTCAL_TEST_DATA_DIR) + "/linear_deviation.csv", "--name",
                 "X after repair"})
                .code,
            0);
  json({"--db", db, "archive", "push", "--to", archive(), "--station", "bay-1"});
  const std::string plant = archive();
  const auto runs = json({"--db", plant, "runs"})["runs"];
  ASSERT_EQ(runs.size(), 5u);
  // The copy is its user's only: it holds what the role may read.
  namespace fs = std::filesystem;
  EXPECT_EQ(fs::status(dir_.file("cache") + "/mtcal").permissions() & fs::perms::all, fs::perms::owner_all);
  for (const auto& file : fs::directory_iterator(dir_.file("cache") + "/mtcal")) {
    if (file.path().extension() == ".lock") continue;
    EXPECT_EQ(file.status().permissions() & fs::perms::all, fs::perms::owner_read | fs::perms::owner_write)
        << file.path();
  }
  // libpq's keyword = value form names the archive too.
  EXPECT_EQ(
      json({"--db", "host=" + socket_dir_ + " port=" + port_ + " dbname=" + database_ + " user=mtcal", "runs"})["runs"]
          .size(),
      5u);
  const auto local = json({"--db", db, "runs"})["runs"];
  for (std::size_t i = 0; i < 5; ++i) {
    EXPECT_EQ(runs[i]["uuid"], local[i]["uuid"]);
    EXPECT_EQ(runs[i]["name"], local[i]["name"]);
  }
  // The archive's numbers are the ones to give: here they are the station's.
  const auto same = [&](std::vector<std::string> command) {
    SCOPED_TRACE(command[0]);
    auto there = command;
    there.insert(there.begin(), {"--db", plant});
    command.insert(command.begin(), {"--db", db});
    auto here = json(command);
    here.erase("result_id");  // stored in the station's store; the archive is only read
    EXPECT_EQ(json(there), here);
  };
  same({"analyze", "iso230-2", "1"});
  same({"analyze", "iso230-4", "2"});
  same({"analyze", "est", "3"});
  same({"compare", "1", "5"});
  same({"diagnose", "1"});
  EXPECT_EQ(json({"--db", plant, "show", "4"})["name"], "spindle-warmup-8h.csv");
  const auto missing = cli({"--db", plant, "show", "99"});
  EXPECT_NE(missing.err.find("run 99 does not exist in the plant archive mtcal@"), std::string::npos) << missing.err;
  const auto report = cli({"--db", plant, "report", "1", "-o", dir_.file("r.html")});
  EXPECT_EQ(report.code, 0) << report.err;
  EXPECT_TRUE(std::filesystem::exists(dir_.file("r.html")));

  // Read only: writing commands are refused, naming what to do instead.
  auto r =
      cli({"--db", plant, "import", "circle", MTCAL_EXAMPLES_DIR "/circle/xy_r100_export.csv", "--radius-mm", "100"});
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.err.find("is the plant archive: it is read, never written; a command that adds"), std::string::npos)
      << r.err;
  for (const auto& command : std::vector<std::vector<std::string>>{{"rename", "1", "x"},
                                                                   {"note", "1", "x"},
                                                                   {"delete", "1", "--yes"},
                                                                   {"check"},
                                                                   {"backup", dir_.file("b.sqlite")},
                                                                   {"archive", "push", "--to", plant},
                                                                   {"demo"}}) {
    auto args = command;
    args.insert(args.begin(), {"--db", plant});
    r = cli(args);
    EXPECT_EQ(r.code, 2) << command[0];
    EXPECT_NE(r.err.find("is the plant archive: it is read, never written; `mtcal " + command[0]), std::string::npos)
        << r.err;
    EXPECT_EQ(r.out, "") << command[0] << ": refused before anything is printed";
  }
  // Nothing said on every analysis about results not stored: the archive is read.
  r = cli({"--db", plant, "analyze", "iso230-2", "1"});
  EXPECT_EQ(r.err.find("not stored"), std::string::npos) << r.err;

  // A change pushed later is what the next command reads; a deletion drops the run.
  ASSERT_EQ(cli({"--db", db, "rename", "2", "circle after repair"}).code, 0);
  ASSERT_EQ(cli({"--db", db, "delete", "3", "--yes"}).code, 0);
  const auto pushed = json({"--db", db, "archive", "push", "--to", plant, "--station", "bay-1"});
  EXPECT_GE(outcomes(pushed)["changed"], 1);  // renamed, and runs the analyses above stored results of
  r = cli({"--db", plant, "--json", "runs"});
  ASSERT_EQ(r.code, 0) << r.err;
  const auto now = nlohmann::json::parse(r.out)["runs"];
  ASSERT_EQ(now.size(), 4u);
  EXPECT_EQ(now[1]["name"], "circle after repair");
  EXPECT_EQ(now[2]["id"], 4);
  ::unsetenv("XDG_CACHE_HOME");
}

TEST_F(PlantArchive, TheDashboardShowsTheArchiveReadOnly) {
  ASSERT_EQ(::setenv("XDG_CACHE_HOME", dir_.file("cache").c_str(), 1), 0);
  const std::string db = quickStore("station.sqlite");
  json({"--db", db, "archive", "push", "--to", archive(), "--station", "bay-1"});
  web::ServerOptions options;
  options.db_path = archive();
  options.port = 0;
  options.plant_refresh = std::chrono::seconds(1);
  mtcal::testing::Running dashboard(options);
  const auto port = dashboard.server().port();
  const auto status = mtcal::testing::ask("127.0.0.1", port, mtcal::testing::http::verb::get, "/api/status");
  ASSERT_EQ(status.status, 200u);
  EXPECT_TRUE(status.json()["read_only"].get<bool>());  // without --read-only: the plant archive is only read
  const auto runs = mtcal::testing::ask("127.0.0.1", port, mtcal::testing::http::verb::get, "/api/runs");
  ASSERT_EQ(runs.status, 200u);
  ASSERT_EQ(runs.json()["runs"].size(), 4u);
  EXPECT_EQ(runs.json()["runs"][3]["kind"], "thermal");
  const auto run = mtcal::testing::ask("127.0.0.1", port, mtcal::testing::http::verb::get, "/api/runs/2");
  EXPECT_EQ(run.status, 200u);
  EXPECT_EQ(run.json()["kind"], "circle");

  // A run pushed while it serves shows without a restart: the copy is brought up to date.
  ASSERT_EQ(cli({"--db", db, "import", "linear", std::string(MTCAL_TEST_DATA_DIR) + "/linear_deviation.csv", "--name",
                 "X pushed later"})
                .code,
            0);
  json({"--db", db, "archive", "push", "--to", archive(), "--station", "bay-1"});
  nlohmann::json listed;
  for (auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(120);
       std::chrono::steady_clock::now() < deadline; std::this_thread::sleep_for(std::chrono::milliseconds(200))) {
    listed = mtcal::testing::ask("127.0.0.1", port, mtcal::testing::http::verb::get, "/api/runs").json();
    if (listed["runs"].size() == 5u) break;
  }
  ASSERT_EQ(listed["runs"].size(), 5u) << "not seen within 2 minutes";
  EXPECT_EQ(listed["runs"][4]["name"], "X pushed later");
  ::unsetenv("XDG_CACHE_HOME");
}

TEST_F(PlantArchive, WrongAddressesAndRunsAreNamed) {
  const std::string db = quickStore("station.sqlite");
  auto r = cli({"--db", db, "archive", "push", "--to", "postgresql://mtcal:secret@localhost/plant"});
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.err.find("holds a password"), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find("secret"), std::string::npos) << r.err;
  r = cli({"--db", db, "archive", "push", "--to", "postgresql:///plant?host=/nonexistent&user=mtcal"});
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.err.find("cannot connect to the archive"), std::string::npos) << r.err;
  r = cli({"--db", db, "archive", "runs", "--from", archive()});
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.err.find("holds no mtcal archive (is the database's name right?); the administrator makes one with "
                       "mtcal archive init"),
            std::string::npos)
      << r.err;
  // The administrator makes the schema without a store; once made, init changes nothing.
  auto made = json({"archive", "init", "--to", archive()});
  EXPECT_EQ(made["archive_schema_version_before"], 0);
  EXPECT_EQ(made["archive_schema_version"], plantSchemaVersion());
  made = json({"archive", "init", "--to", archive()});
  EXPECT_EQ(made["archive_schema_version_before"], plantSchemaVersion());
  EXPECT_EQ(json({"archive", "runs", "--from", archive()})["runs"].size(), 0u);
  json({"--db", db, "archive", "push", "--to", archive(), "--station", "bay-1"});
  for (const char* what : {"99", "c99", "x1", "m9", "99999999999999999999", "c99999999999999999999"}) {
    r = cli({"--db", dir_.file("copy.sqlite"), "archive", "pull", what, "--from", archive()});
    EXPECT_NE(r.code, 0) << what;
    EXPECT_NE(r.err.find(what), std::string::npos) << r.err;
    EXPECT_EQ(r.code, 2) << what << ": " << r.err;  // wrong input, not a failure of the archive
    EXPECT_FALSE(std::filesystem::exists(dir_.file("copy.sqlite"))) << what << ": a failed pull makes no store";
  }
  r = cli({"archive", "history", "c1", "--from", archive()});
  EXPECT_NE(r.err.find("'c1' names no run of the archive: give its number (12) or its uuid"), std::string::npos)
      << r.err;
  // Only the database's owner makes or migrates the archive; a database of other tables is
  // not taken for one.
  role("bay9", "mtcal_station");
  {
    Connection admin(address("postgres"));
    admin.exec("DROP DATABASE IF EXISTS " + database_ + "_other WITH (FORCE)");
    admin.exec("CREATE DATABASE " + database_ + "_other");
  }
  r = cli({"archive", "init", "--to", address(database_ + "_other", "bay9")});
  EXPECT_NE(r.err.find("role bay9 may not make the archive in"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("the database's owner, mtcal, does"), std::string::npos) << r.err;
  // Nor a superuser in another's database: the tables would be the superuser's.
  Connection(address("postgres")).exec("ALTER DATABASE " + database_ + "_other OWNER TO bay9");
  r = cli({"archive", "init", "--to", address(database_ + "_other")});
  EXPECT_NE(r.err.find("role mtcal may not make the archive in"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("the database's owner, bay9, does"), std::string::npos) << r.err;
  Connection(address("postgres")).exec("ALTER DATABASE " + database_ + "_other OWNER TO mtcal");
  Connection(address(database_ + "_other")).exec("CREATE TABLE runs (id integer)");
  r = cli({"archive", "init", "--to", address(database_ + "_other")});
  EXPECT_EQ(r.code, 2);  // the address given is the mistake
  EXPECT_NE(r.err.find("holds other tables (runs) and no mtcal archive: give the archive a database of its own"),
            std::string::npos)
      << r.err;
  Connection(address("postgres")).exec("DROP DATABASE " + database_ + "_other WITH (FORCE)");
  // A store holding another version of the run refuses it and keeps its own.
  const std::string copy = dir_.file("copy.sqlite");
  json({"--db", copy, "archive", "pull", "1", "--from", archive()});
  ASSERT_EQ(cli({"--db", copy, "rename", "1", "mine"}).code, 0);
  r = cli({"--db", copy, "archive", "pull", "1", "--from", archive()});
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.err.find("in another version"), std::string::npos) << r.err;
  EXPECT_EQ(json({"--db", copy, "show", "1"})["name"], "mine");
}

}  // namespace
}  // namespace mtcal::archive
