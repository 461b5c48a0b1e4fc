#include "mtcal/storage/store.h"

#include <gtest/gtest.h>
#include <sqlite3.h>
#include <unistd.h>

#include "../support/temp_dir.h"
#include "mtcal/error.h"
#include "mtcal/storage/schema.h"

namespace mtcal::storage {
namespace {

class StoreTest : public ::testing::Test {
 protected:
  Id newRun(Store& s) {
    NewRun r;
    r.campaign_id = s.addCampaign(s.ensureMachine("m", "", "{}"), "c");
    r.name = "run";
    r.axis = "X";
    r.software_version = "test";
    return s.addRun(r);
  }

  std::int64_t count(Store& s, const char* table) {
    Statement st(s.database(), std::string("SELECT COUNT(*) FROM ") + table);
    st.step();
    return st.getInt(0);
  }

  mtcal::testing::TempDir dir_;
  std::string path_ = dir_.file("test.sqlite");
};

TEST_F(StoreTest, NewDatabaseIsMigratedWithWalAndForeignKeys) {
  Store s(path_);
  Statement v(s.database(), "PRAGMA user_version");
  ASSERT_TRUE(v.step());
  EXPECT_EQ(v.getInt(0), currentSchemaVersion());
  Statement j(s.database(), "PRAGMA journal_mode");
  ASSERT_TRUE(j.step());
  EXPECT_EQ(j.getText(0), "wal");
  // Foreign keys are enforced: a target of a run that does not exist is refused.
  TargetRecord t;
  EXPECT_THROW(s.addTarget(999, t, {}), StorageError);
}

TEST_F(StoreTest, ReopeningKeepsDataAndDoesNotRemigrate) {
  Id run;
  {
    Store s(path_);
    run = newRun(s);
  }
  Store again(path_);
  EXPECT_EQ(again.run(run).name, "run");
  EXPECT_EQ(again.listRuns().size(), 1u);
}

// A database written by the first release (schema v1) is migrated in place: the model
// tables appear and its runs stay.
TEST_F(StoreTest, ProbeStepsRoundTripAndAreAtomic) {
  Store s(path_);
  const Id run = newRun(s);
  s.addProbeStep(run, {0, 50.0, {{1, 1.25, 0.02, 10}, {2, -0.5, std::nullopt, 1}}});
  s.addProbeStep(run, {1, 70.0, {{1, 1.5, 0.03, 10}, {2, -0.25, 0.01, 10}}});
  // A duplicate channel in one step: the step is refused whole.
  EXPECT_THROW(s.addProbeStep(run, {2, 90.0, {{1, 1.0, 0.01, 10}, {1, 2.0, 0.01, 10}}}), StorageError);
  const auto steps = s.probeSteps(run);
  ASSERT_EQ(steps.size(), 2u);
  EXPECT_DOUBLE_EQ(steps[1].position_mm, 70.0);
  ASSERT_EQ(steps[0].channels.size(), 2u);
  EXPECT_DOUBLE_EQ(steps[0].channels[0].value_um, 1.25);
  EXPECT_FALSE(steps[0].channels[1].s_um.has_value());
  EXPECT_EQ(steps[1].channels[1].readings, 10);
}

TEST_F(StoreTest, ThermalSamplesKeepMissingValuesAndAreAtomic) {
  Store s(path_);
  const Id run = newRun(s);
  s.addThermalChannels(run, {{"T1", "temperature", "degC"}, {"z_um", "displacement", "um"}});
  const std::vector<ThermalSample> first = {{0, 0.0, {20.5, -0.25}}, {1, 60.0, {std::nullopt, -1.5}}};
  s.addThermalSamples(run, first);
  // A sample with a value too few, after a good one: neither is stored.
  const std::vector<ThermalSample> bad = {{2, 120.0, {20.7, -2.0}}, {3, 180.0, {20.8}}};
  EXPECT_THROW(s.addThermalSamples(run, bad), InputError);
  // The same index twice: refused.
  EXPECT_THROW(s.addThermalSamples(run, std::vector<ThermalSample>{{1, 60.0, {20.6, -1.5}}}), StorageError);
  EXPECT_EQ(s.thermalSampleCount(run), 2);
  const auto back = s.thermalSamples(run);
  ASSERT_EQ(back.size(), 2u);
  EXPECT_DOUBLE_EQ(*back[0].values[0], 20.5);
  EXPECT_FALSE(back[1].values[0].has_value());  // missing, not 0
  EXPECT_DOUBLE_EQ(back[1].time_s, 60.0);
  const auto channels = s.thermalChannels(run);
  ASSERT_EQ(channels.size(), 2u);
  EXPECT_EQ(channels[1].kind, "displacement");
  // A kind the schema does not know is refused.
  const Id other = newRun(s);
  EXPECT_THROW(s.addThermalChannels(other, {{"p", "pressure", "Pa"}}), StorageError);
  EXPECT_TRUE(s.thermalChannels(other).empty());
}

TEST_F(StoreTest, TrackerPointsAppendInOrderAndKeepOptionalFields) {
  Store s(path_);
  const Id run = newRun(s);
  const std::vector<TrackerPointRecord> first{{"corner:A:top", "A.top", 1.5, -2.25, 3.0, 10.5, 500},
                                              {"pass:1:+", "TB1", 4.0, 5.0, 6.0, 11.0, std::nullopt}};
  s.addTrackerPoints(run, first);
  const std::vector<TrackerPointRecord> second{{"hole:g1-h01", "TB2", 7.0, 8.0, 9.0, std::nullopt, 200}};
  s.addTrackerPoints(run, second);
  const auto points = s.trackerPoints(run);
  ASSERT_EQ(points.size(), 3u);
  EXPECT_EQ(points[0].feature, "corner:A:top");
  EXPECT_DOUBLE_EQ(points[0].y_mm, -2.25);
  EXPECT_EQ(points[0].integration_ms, 500);
  EXPECT_FALSE(points[1].integration_ms.has_value());
  EXPECT_EQ(points[2].place, "TB2");
  EXPECT_FALSE(points[2].time_s.has_value());
  EXPECT_TRUE(s.trackerPoints(run + 1).empty());
}

TEST_F(StoreTest, MigratesAVersion1Database) {
  Id run;
  {
    Store s(path_);
    run = newRun(s);
    for (const std::string table : {"machines", "instruments", "campaigns", "runs", "models"})
      s.database().exec("DROP TRIGGER " + table + "_uuid_given; DROP INDEX " + table + "_uuid; ALTER TABLE " + table +
                        " DROP COLUMN uuid");
    s.database().exec(
        "DROP TABLE store_identity; DROP TABLE deleted_runs; DROP TABLE archive_versions; ALTER TABLE runs DROP COLUMN "
        "compensation_json; DROP TABLE run_notes; ALTER TABLE "
        "runs DROP COLUMN "
        "owner_host; ALTER TABLE runs DROP COLUMN owner_pid; "
        "ALTER TABLE runs DROP COLUMN owner_start; ALTER TABLE runs DROP COLUMN heartbeat_at; "
        "DROP TABLE run_instruments; ALTER TABLE runs DROP COLUMN operator_name; DROP TABLE thermal_values; DROP TABLE "
        "thermal_samples; DROP TABLE thermal_channels; DROP TABLE tracker_points; DROP TABLE circle_points; DROP TABLE "
        "probe_steps; DROP TABLE model_errors; DROP TABLE models; ALTER TABLE runs DROP COLUMN value_unit; "
        "PRAGMA user_version = 1");
  }
  Store s(path_);
  Statement v(s.database(), "PRAGMA user_version");
  ASSERT_TRUE(v.step());
  EXPECT_EQ(v.getInt(0), currentSchemaVersion());
  EXPECT_EQ(s.run(run).name, "run");
  // The run existing before identities got one: a version 4 UUID.
  const std::string uuid = s.run(run).uuid;
  ASSERT_EQ(uuid.size(), 36u) << uuid;
  EXPECT_EQ(uuid[14], '4');
  EXPECT_NE(std::string("89ab").find(uuid[19]), std::string::npos) << uuid;
  EXPECT_NE(uuid, s.run(newRun(s)).uuid);  // a run added now gets its own
  ModelRecord m;
  m.name = "vmc";
  m.machine_json = "{}";
  m.method = "imported";
  m.provenance_json = "{}";
  m.software_version = "test";
  m.error_functions = {{"EXX", R"({"constant": 1})"}, {"EBX", R"({"constant": 2})"}};
  const Id id = s.addModel(m);
  const auto back = s.model(id);
  EXPECT_EQ(back.name, "vmc");
  ASSERT_EQ(back.error_functions.size(), 2u);
  EXPECT_EQ(back.error_functions[0].first, "EBX");  // by name
  EXPECT_THROW(s.model(id + 1), InputError);
  m.error_functions.push_back({"EXX", "{}"});  // a duplicate name: nothing of the model is stored
  EXPECT_THROW(s.addModel(m), StorageError);
  EXPECT_EQ(s.listModels().size(), 1u);
}

TEST_F(StoreTest, RefusesADatabaseFromANewerMtcal) {
  { Store s(path_); }
  {
    Database db(path_);
    db.exec("PRAGMA user_version = " + std::to_string(currentSchemaVersion() + 1));
  }
  try {
    Store s(path_);
    FAIL();
  } catch (const StorageError& e) {
    EXPECT_NE(std::string(e.what()).find("newer"), std::string::npos) << e.what();
  }
}

TEST_F(StoreTest, TargetAndItsSamplesRoundTrip) {
  Store s(path_);
  const Id run = newRun(s);
  TargetRecord t;
  t.seq = 4;
  t.target_mm = 70.0;
  t.direction = -1;
  t.cycle = 2;
  t.measured_mm = 70.0012;
  t.deviation_um = 1.2;
  t.air_index = 1.00027;
  t.sample_count = 3;
  std::vector<SampleRecord> samples = {{10, 1000, 70.001, 80}, {11, 2000, 70.0012, 81}, {12, 3000, 70.0014, -1}};
  s.addTarget(run, t, samples);
  const auto back = s.targets(run);
  ASSERT_EQ(back.size(), 1u);
  EXPECT_EQ(back[0].seq, 4);
  EXPECT_EQ(back[0].direction, -1);
  EXPECT_DOUBLE_EQ(back[0].deviation_um, 1.2);
  EXPECT_DOUBLE_EQ(*back[0].air_index, 1.00027);
  EXPECT_FALSE(back[0].material_temp_c.has_value());
  const auto raw = s.samplesOfTarget(run, 4);
  ASSERT_EQ(raw.size(), 3u);
  EXPECT_EQ(raw[2].device_seq, 12);
  EXPECT_EQ(raw[2].signal_pct, -1);
  EXPECT_DOUBLE_EQ(raw[1].value, 70.0012);
}

TEST_F(StoreTest, AFailedTargetLeavesNeitherTargetNorSamples) {
  Store s(path_);
  const Id run = newRun(s);
  TargetRecord t;
  t.seq = 0;
  std::vector<SampleRecord> samples(100, SampleRecord{1, 1, 1.0, 50});
  s.addTarget(run, t, samples);
  // The same seq again violates UNIQUE(run_id, seq) after its samples were inserted.
  EXPECT_THROW(s.addTarget(run, t, samples), StorageError);
  EXPECT_EQ(count(s, "targets"), 1);
  EXPECT_EQ(count(s, "samples"), 100);
}

TEST_F(StoreTest, NestedTransactionsRollBackAsOneUnit) {
  Store s(path_);
  {
    Transaction outer(s.database());
    s.ensureMachine("inner-machine", "", "{}");  // its own statement
    {
      Transaction inner(s.database());
      s.ensureMachine("savepoint-machine", "", "{}");
      inner.commit();
    }
    // outer never commits
  }
  EXPECT_EQ(count(s, "machines"), 0);
  {
    Transaction outer(s.database());
    {
      Transaction inner(s.database());
      s.ensureMachine("rolled-back", "", "{}");
    }  // inner rolls back to its savepoint only
    s.ensureMachine("kept", "", "{}");
    outer.commit();
  }
  EXPECT_EQ(count(s, "machines"), 1);
}

TEST_F(StoreTest, ImportRunIsAtomic) {
  Store s(path_);
  NewRun r;
  r.campaign_id = s.addCampaign(s.ensureMachine("m", "", "{}"), "c");
  r.name = "imported";
  r.status = run_status::kImported;
  r.source = "imported";
  std::vector<TargetRecord> targets(3);
  for (int i = 0; i < 3; ++i) targets[i].seq = i;
  std::vector<ChannelRow> channels = {{1.0}, {std::nullopt}, {3.0}};
  const Id id = s.importRun(r, targets, {"spindle_temp_c"}, channels);
  EXPECT_EQ(s.targets(id).size(), 3u);
  EXPECT_EQ(s.channelNames(id), std::vector<std::string>{"spindle_temp_c"});
  EXPECT_EQ(count(s, "channel_values"), 2);  // the empty cell is missing, not zero

  targets[2].seq = 1;  // duplicate seq -> the whole import must vanish
  EXPECT_THROW(s.importRun(r, targets, {"x"}, channels), StorageError);
  EXPECT_EQ(s.listRuns().size(), 1u);
  EXPECT_EQ(count(s, "targets"), 3);
  EXPECT_EQ(count(s, "channels"), 1);
}

// The runs an imported file's digest is in: found by the store, only those.
TEST_F(StoreTest, RunsWhosePlanHoldsATextAreFound) {
  Store s(path_);
  NewRun r;
  r.campaign_id = s.addCampaign(s.ensureMachine("m", "", "{}"), "c");
  r.status = run_status::kImported;
  r.source = "imported";
  std::vector<TargetRecord> targets(1);
  r.plan_json = R"({"imported_sha256":"ab12"})";
  const Id first = s.importRun(r, targets, {}, {});
  r.plan_json = R"({"imported_sha256":"cd34"})";
  s.importRun(r, targets, {}, {});
  r.plan_json = R"({"imported_sha256":"ab12","name":"again"})";
  const Id third = s.importRun(r, targets, {}, {});
  std::vector<Id> found;
  for (const auto& run : s.runsWhosePlanHolds("ab12")) found.push_back(run.id);
  EXPECT_EQ(found, (std::vector<Id>{first, third}));
  EXPECT_TRUE(s.runsWhosePlanHolds("ef56").empty());
}

TEST_F(StoreTest, RunStatusAndEvents) {
  Store s(path_);
  const Id run = newRun(s);
  EXPECT_EQ(s.run(run).status, "running");
  EXPECT_FALSE(s.run(run).finished_at.has_value());
  s.logEvent(run, "warning", "beam weak");
  s.setRunStatus(run, run_status::kInterrupted);
  EXPECT_EQ(s.run(run).status, "interrupted");
  EXPECT_TRUE(s.run(run).finished_at.has_value());
  ASSERT_EQ(s.events(run).size(), 2u);
  EXPECT_EQ(s.events(run)[0].message.rfind("run started by process " + std::to_string(::getpid()), 0), 0u)
      << s.events(run)[0].message;
  EXPECT_EQ(s.events(run)[1].message, "beam weak");
  EXPECT_THROW(s.setRunStatus(run, "bogus"), StorageError);  // CHECK constraint
  EXPECT_THROW(s.run(12345), InputError);
}

}  // namespace
}  // namespace mtcal::storage
