#include "mtcal/storage/schema.h"

#include <spdlog/spdlog.h>

#include <string>
#include <vector>

#include "mtcal/error.h"

namespace mtcal::storage {
namespace {

// A random UUID (version 4, RFC 9562) in SQL, so that rows added by any program get one.
constexpr const char* kUuid4Sql =
    "lower(hex(randomblob(4))) || '-' || lower(hex(randomblob(2))) || '-4' || substr(lower(hex(randomblob(2))), 2)"
    " || '-' || substr('89ab', 1 + (abs(random()) % 4), 1) || substr(lower(hex(randomblob(2))), 2) || '-'"
    " || lower(hex(randomblob(6)))";

// Gives every row of the tables with a global identity a uuid column, filled for the rows there
// are and, by a trigger, for every row added without one (a pulled run brings its own).
std::string identities() {
  std::string sql = std::string("INSERT INTO store_identity(uuid) VALUES (") + kUuid4Sql + ");\n";
  for (const char* table : {"machines", "instruments", "campaigns", "runs", "models"}) {
    const std::string t = table;
    sql += "ALTER TABLE " + t + " ADD COLUMN uuid TEXT;\n";
    sql += "UPDATE " + t + " SET uuid = " + kUuid4Sql + ";\n";
    sql += "CREATE UNIQUE INDEX " + t + "_uuid ON " + t + "(uuid);\n";
    sql += "CREATE TRIGGER " + t + "_uuid_given AFTER INSERT ON " + t + " WHEN NEW.uuid IS NULL BEGIN UPDATE " + t +
           " SET uuid = " + kUuid4Sql + " WHERE id = NEW.id; END;\n";
  }
  return sql;
}

// Migration k brings the schema from version k to k + 1. Never edit a released entry:
// append a new one.
const std::vector<std::string>& migrations() {
  static const std::vector<std::string> kMigrations = {
      // v1: machines, instruments, campaigns, runs, targets, samples, environment,
      // auxiliary channels, processing results, events.
      R"sql(
CREATE TABLE machines (
  id INTEGER PRIMARY KEY,
  name TEXT NOT NULL UNIQUE,
  description TEXT,
  config_json TEXT,
  created_at TEXT NOT NULL DEFAULT (strftime('%Y-%m-%dT%H:%M:%fZ','now'))
);
CREATE TABLE instruments (
  id INTEGER PRIMARY KEY,
  kind TEXT NOT NULL,              -- interferometer, ballbar, probes, tracker, imported
  model TEXT NOT NULL,
  serial TEXT NOT NULL,
  firmware TEXT,
  driver_uri TEXT NOT NULL,
  created_at TEXT NOT NULL DEFAULT (strftime('%Y-%m-%dT%H:%M:%fZ','now')),
  UNIQUE (kind, model, serial)
);
CREATE TABLE campaigns (
  id INTEGER PRIMARY KEY,
  machine_id INTEGER NOT NULL REFERENCES machines(id),
  name TEXT NOT NULL,
  created_at TEXT NOT NULL DEFAULT (strftime('%Y-%m-%dT%H:%M:%fZ','now'))
);
CREATE TABLE runs (
  id INTEGER PRIMARY KEY,
  campaign_id INTEGER NOT NULL REFERENCES campaigns(id),
  instrument_id INTEGER REFERENCES instruments(id),
  kind TEXT NOT NULL,              -- linear, ...
  axis TEXT,
  name TEXT NOT NULL,
  plan_json TEXT NOT NULL,         -- the full plan as run, so the run can be resumed or repeated
  status TEXT NOT NULL CHECK (status IN ('running','interrupted','completed','failed','imported')),
  source TEXT NOT NULL CHECK (source IN ('acquired','imported')),
  software_version TEXT NOT NULL,
  started_at TEXT NOT NULL DEFAULT (strftime('%Y-%m-%dT%H:%M:%fZ','now')),
  finished_at TEXT
);
CREATE TABLE targets (
  id INTEGER PRIMARY KEY,
  run_id INTEGER NOT NULL REFERENCES runs(id),
  seq INTEGER NOT NULL,            -- position in the plan's target sequence
  target_mm REAL NOT NULL,
  direction INTEGER NOT NULL CHECK (direction IN (1, -1)),
  cycle INTEGER NOT NULL CHECK (cycle >= 1),
  measured_mm REAL NOT NULL,       -- compensated mean over the capture window
  deviation_um REAL NOT NULL,      -- measured - target
  time_s REAL,                     -- since the start of the run
  sample_count INTEGER NOT NULL DEFAULT 0,
  sample_stddev_um REAL,
  air_temp_c REAL, air_pressure_pa REAL, humidity_pct REAL, material_temp_c REAL,
  air_index REAL,                  -- the index used to compensate, NULL when imported compensated
  first_sample_rowid INTEGER,      -- raw samples of this target: samples.rowid in [first, last]
  last_sample_rowid INTEGER,
  captured_at TEXT NOT NULL DEFAULT (strftime('%Y-%m-%dT%H:%M:%fZ','now')),
  UNIQUE (run_id, seq)
);
-- Raw samples: no index besides the rowid so that a 50 kHz stream inserts at full speed;
-- targets point at their rowid range.
CREATE TABLE samples (
  run_id INTEGER NOT NULL REFERENCES runs(id),
  device_seq INTEGER NOT NULL,
  device_time_ns INTEGER NOT NULL,
  value REAL NOT NULL,             -- mm (raw, uncompensated) for linear optics
  signal_pct INTEGER NOT NULL      -- beam signal strength; negative when the beam was lost
);
CREATE TABLE environment (
  id INTEGER PRIMARY KEY,
  run_id INTEGER NOT NULL REFERENCES runs(id),
  device_time_ns INTEGER,
  air_temp_c REAL, air_pressure_pa REAL, humidity_pct REAL,
  material_temp1_c REAL, material_temp2_c REAL, material_temp3_c REAL,
  recorded_at TEXT NOT NULL DEFAULT (strftime('%Y-%m-%dT%H:%M:%fZ','now'))
);
CREATE INDEX environment_run ON environment(run_id);
CREATE TABLE channels (
  id INTEGER PRIMARY KEY,
  run_id INTEGER NOT NULL REFERENCES runs(id),
  name TEXT NOT NULL,
  UNIQUE (run_id, name)
);
CREATE TABLE channel_values (
  channel_id INTEGER NOT NULL REFERENCES channels(id),
  target_id INTEGER NOT NULL REFERENCES targets(id),
  value REAL NOT NULL,
  PRIMARY KEY (channel_id, target_id)
) WITHOUT ROWID;
CREATE TABLE results (
  id INTEGER PRIMARY KEY,
  run_id INTEGER NOT NULL REFERENCES runs(id),
  processor TEXT NOT NULL,
  processor_version TEXT NOT NULL,
  parameters_json TEXT NOT NULL,
  output_json TEXT NOT NULL,
  created_at TEXT NOT NULL DEFAULT (strftime('%Y-%m-%dT%H:%M:%fZ','now'))
);
CREATE INDEX results_run ON results(run_id);
CREATE TABLE events (
  id INTEGER PRIMARY KEY,
  run_id INTEGER REFERENCES runs(id),
  level TEXT NOT NULL CHECK (level IN ('info','warning','error')),
  message TEXT NOT NULL,
  created_at TEXT NOT NULL DEFAULT (strftime('%Y-%m-%dT%H:%M:%fZ','now'))
);
CREATE INDEX events_run ON events(run_id);
)sql",
      // v2: geometric error models: the machine's kinematic description, one
      // function per error term, and where the model came from.
      R"sql(
CREATE TABLE models (
  id INTEGER PRIMARY KEY,
  name TEXT NOT NULL,
  machine_json TEXT NOT NULL,        -- kinematic description (examples/machines/*.model.json)
  method TEXT NOT NULL,              -- imported, direct, 9-line
  provenance_json TEXT NOT NULL,     -- source file or runs, options
  software_version TEXT NOT NULL,
  created_at TEXT NOT NULL DEFAULT (strftime('%Y-%m-%dT%H:%M:%fZ','now'))
);
CREATE TABLE model_errors (
  model_id INTEGER NOT NULL REFERENCES models(id),
  name TEXT NOT NULL,                -- ISO 230-1 name
  function_json TEXT NOT NULL,       -- B-spline or constant, node sigmas, degrees of freedom
  PRIMARY KEY (model_id, name)
) WITHOUT ROWID;
)sql",
      // v3: the unit of a run's values (angular runs hold urad in targets.deviation_um).
      R"sql(
ALTER TABLE runs ADD COLUMN value_unit TEXT NOT NULL DEFAULT 'um' CHECK (value_unit IN ('um', 'urad'));
)sql",
      // v4: probe stepping runs: per step and channel the mean of the readings
      // averaged there, their standard deviation and count.
      R"sql(
CREATE TABLE probe_steps (
  run_id INTEGER NOT NULL REFERENCES runs(id),
  step INTEGER NOT NULL,             -- 0-based index along the plan
  position_mm REAL NOT NULL,         -- commanded carriage position
  channel INTEGER NOT NULL,          -- 1..n
  value_um REAL NOT NULL,
  s_um REAL,                         -- NULL for a single reading
  readings INTEGER NOT NULL,
  PRIMARY KEY (run_id, step, channel)
) WITHOUT ROWID;
)sql",
      // v5: circular tests: the radial deviation of the path at each angle, per
      // direction; the test's radius, plane and feed are in the run's plan.
      R"sql(
CREATE TABLE circle_points (
  run_id INTEGER NOT NULL REFERENCES runs(id),
  direction TEXT NOT NULL CHECK (direction IN ('ccw', 'cw')),
  idx INTEGER NOT NULL,              -- order of measurement within the direction
  angle_deg REAL NOT NULL,
  deviation_um REAL NOT NULL,        -- radial, from the nominal radius, + outward
  time_s REAL,                       -- since the start of the direction's circle
  PRIMARY KEY (run_id, direction, idx)
) WITHOUT ROWID;
)sql",
      // v6: laser tracker points: every measured point of a run in the
      // tracker's frame, with the feature it belongs to (a corner face, a gantry pass, a
      // rotary sweep, a target at a hole) and where the reflector was.
      R"sql(
CREATE TABLE tracker_points (
  run_id INTEGER NOT NULL REFERENCES runs(id),
  idx INTEGER NOT NULL,              -- order of measurement within the run
  feature TEXT NOT NULL,             -- e.g. corner:A:top, pass:1:+, c-sweep, hole:g1-h01
  place TEXT NOT NULL,               -- the reflector's nest or face, e.g. TB2, A.side1
  x_mm REAL NOT NULL, y_mm REAL NOT NULL, z_mm REAL NOT NULL,
  time_s REAL,                       -- tracker clock
  integration_ms INTEGER,            -- NULL for points of a continuous measurement
  PRIMARY KEY (run_id, idx)
) WITHOUT ROWID;
)sql",
      // v7: thermal monitoring: the channels of a run (temperatures, the
      // displacement, the spindle speed) and their values at each sample. A value the
      // instrument did not deliver (a sensor out) is NULL: missing, never 0.
      R"sql(
CREATE TABLE thermal_channels (
  run_id INTEGER NOT NULL REFERENCES runs(id),
  idx INTEGER NOT NULL,              -- 0-based column of the run
  name TEXT NOT NULL,
  kind TEXT NOT NULL CHECK (kind IN ('temperature', 'displacement', 'speed')),
  unit TEXT NOT NULL,                -- degC, um, rpm
  PRIMARY KEY (run_id, idx),
  UNIQUE (run_id, name)
) WITHOUT ROWID;
CREATE TABLE thermal_samples (
  run_id INTEGER NOT NULL REFERENCES runs(id),
  idx INTEGER NOT NULL,              -- 0-based sample of the run
  time_s REAL NOT NULL,              -- since the run's start
  PRIMARY KEY (run_id, idx)
) WITHOUT ROWID;
CREATE TABLE thermal_values (
  run_id INTEGER NOT NULL,
  sample INTEGER NOT NULL,
  channel INTEGER NOT NULL,
  value REAL,                        -- NULL: no valid reading
  PRIMARY KEY (run_id, sample, channel),
  FOREIGN KEY (run_id, sample) REFERENCES thermal_samples(run_id, idx)
) WITHOUT ROWID;
)sql",
      // v8: who measured and with what: the operator of a run, and every instrument that
      // took part (a thermal run's logger, probes and interferometer; a gantry run's tracker)
      // with its role. runs.instrument_id stays the main instrument.
      R"sql(
ALTER TABLE runs ADD COLUMN operator_name TEXT NOT NULL DEFAULT '';
CREATE TABLE run_instruments (
  run_id INTEGER NOT NULL REFERENCES runs(id),
  instrument_id INTEGER NOT NULL REFERENCES instruments(id),
  role TEXT NOT NULL,                -- measuring (the run's main instrument), displacement, environment ...
  PRIMARY KEY (run_id, instrument_id)
) WITHOUT ROWID;
INSERT INTO run_instruments(run_id, instrument_id, role)
  SELECT id, instrument_id, 'measuring' FROM runs WHERE instrument_id IS NOT NULL;
)sql",
      // v9: runs that survive: the process recording a run (host, pid, its start) and its
      // heartbeat, so a run whose process died is known as interrupted; notes people add to a
      // run; the segment of each thermal sample (a resumed run starts a new one: the machine's
      // state is not continuous across the gap).
      R"sql(
ALTER TABLE runs ADD COLUMN owner_host TEXT;
ALTER TABLE runs ADD COLUMN owner_pid INTEGER;
ALTER TABLE runs ADD COLUMN owner_start TEXT;      -- boot id / start ticks: a reused pid is another process
ALTER TABLE runs ADD COLUMN heartbeat_at TEXT;
CREATE TABLE run_notes (
  id INTEGER PRIMARY KEY,
  run_id INTEGER NOT NULL REFERENCES runs(id),
  author TEXT NOT NULL DEFAULT '',
  text TEXT NOT NULL,
  created_at TEXT NOT NULL DEFAULT (strftime('%Y-%m-%dT%H:%M:%fZ','now'))
);
CREATE INDEX run_notes_run ON run_notes(run_id);
ALTER TABLE thermal_samples ADD COLUMN segment INTEGER NOT NULL DEFAULT 0;
)sql",
      // v10: the compensation tables the controller applied while a run measured.
      R"sql(
ALTER TABLE runs ADD COLUMN compensation_json TEXT NOT NULL DEFAULT '{}';
)sql",
      // v11: global identities for the plant archive (docs/archive.md): a random UUID (version 4)
      // for every machine, instrument, campaign, run and model, given when the row is added and
      // never changed, and one for the store itself (which store a pushed run came from).
      R"sql(
CREATE TABLE store_identity (uuid TEXT NOT NULL);
-- Runs this store deleted (a push tombstones them in the archive: a store restored from a
-- backup deletes nothing it never held).
CREATE TABLE deleted_runs (
  uuid TEXT PRIMARY KEY,
  deleted_at TEXT NOT NULL DEFAULT (strftime('%Y-%m-%dT%H:%M:%fZ','now'))
);
-- The version of each run this store last pushed to or pulled from a plant archive: a push
-- refuses a run changed in the archive since (by another store) instead of overwriting it.
CREATE TABLE archive_versions (
  archive_uuid TEXT NOT NULL,
  run_uuid TEXT NOT NULL,
  version INTEGER NOT NULL,
  sha256 TEXT NOT NULL,
  PRIMARY KEY (archive_uuid, run_uuid)
) WITHOUT ROWID;
)sql" + identities(),
  };
  return kMigrations;
}

/// Refuses a file that is not an mtcal archive (its schema version 0).
void requireArchive(Database& db, bool create) {
  const auto tables = db.tableNames();
  if (!tables.empty()) {
    throw InputError("'" + db.path() + "' is an SQLite database but not an mtcal store (its tables: " + tables +
                     "); nothing was written to it: give the store's path with --db");
  }
  if (!create) {
    throw InputError("'" + db.path() + "' is not an mtcal store (it holds nothing): give the store's path with --db");
  }
}

}  // namespace

int currentSchemaVersion() { return static_cast<int>(migrations().size()); }

void migrate(Database& db, bool create) {
  auto newer = [&](int version) {
    return StorageError("database '" + db.path() + "' has schema v" + std::to_string(version) +
                        ", newer than this mtcal understands (v" + std::to_string(currentSchemaVersion()) + ")");
  };
  int version = db.userVersion();
  if (version > currentSchemaVersion()) throw newer(version);
  if (version == currentSchemaVersion()) return;
  if (db.readOnly()) {
    if (version == 0) requireArchive(db, false);
    throw StorageError("store '" + db.path() + "' is read-only and has schema v" + std::to_string(version) +
                       "; this mtcal reads v" + std::to_string(currentSchemaVersion()) +
                       ": copy it somewhere writable and open the copy once (it is migrated)");
  }
  // One process migrates, under the write lock; one that waited for it finds the work done.
  // The version and the tables are read inside it: read apart, another process creating the
  // archive may commit between the two reads, and its tables would look foreign.
  Transaction tx(db);
  version = db.userVersion();
  if (version > currentSchemaVersion()) throw newer(version);
  if (version == 0) requireArchive(db, create);  // another process may have made it something else meanwhile
  for (; version < currentSchemaVersion(); ++version) {
    Transaction step(db);
    db.exec(migrations()[static_cast<std::size_t>(version)]);
    db.exec("PRAGMA user_version = " + std::to_string(version + 1));
    step.commit();
    spdlog::info("{}: schema migrated to v{}", db.path(), version + 1);
  }
  tx.commit();
}

}  // namespace mtcal::storage
