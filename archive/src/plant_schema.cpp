#include "mtcal/archive/plant_schema.h"

#include <spdlog/spdlog.h>

#include <string>
#include <vector>

#include "mtcal/error.h"

namespace mtcal::archive {
namespace {

// Never edit a released entry: append a new one. Times are the local store's texts (UTC ISO
// 8601) so that a pulled run is the run pushed; pushed_at is the server's.
const std::vector<const char*>& migrations() {
  static const std::vector<const char*> kMigrations = {
      // v1: stations, the machines, instruments and campaigns runs belong to, every version
      // of every run, and the rows of each version's parts.
      R"sql(
CREATE TABLE stations (
  name text PRIMARY KEY,
  first_push_at timestamptz NOT NULL DEFAULT now()
);
CREATE TABLE machines (
  uuid uuid PRIMARY KEY,
  name text NOT NULL,
  description text,
  config_json text,
  created_at text NOT NULL,
  station text NOT NULL REFERENCES stations(name)
);
CREATE INDEX machines_name ON machines(name);
CREATE TABLE instruments (
  uuid uuid PRIMARY KEY,
  kind text NOT NULL, model text NOT NULL, serial text NOT NULL, firmware text, driver_uri text NOT NULL,
  created_at text NOT NULL,
  station text NOT NULL REFERENCES stations(name),
  UNIQUE (kind, model, serial)  -- the first uuid pushed names it: two stores may have given it two
);
CREATE TABLE campaigns (
  id bigint GENERATED ALWAYS AS IDENTITY UNIQUE,  -- the archive's number: cN
  uuid uuid PRIMARY KEY,
  machine_uuid uuid NOT NULL REFERENCES machines(uuid),
  name text NOT NULL,
  created_at text NOT NULL,
  station text NOT NULL REFERENCES stations(name)
);
CREATE INDEX campaigns_machine ON campaigns(machine_uuid);
CREATE TABLE runs (
  id bigint GENERATED ALWAYS AS IDENTITY UNIQUE,  -- the archive's number of the run
  uuid uuid PRIMARY KEY,
  station text NOT NULL REFERENCES stations(name),  -- where it was first pushed from
  store_uuid uuid NOT NULL,                          -- the local store it was recorded in
  campaign_uuid uuid NOT NULL REFERENCES campaigns(uuid)
);
CREATE INDEX runs_campaign ON runs(campaign_uuid);
-- A run as one push found it. Never updated: a change is a new version, a deletion a tombstone.
CREATE TABLE run_versions (
  run_uuid uuid NOT NULL REFERENCES runs(uuid),
  version integer NOT NULL CHECK (version >= 1),
  station text NOT NULL REFERENCES stations(name),
  store_uuid uuid NOT NULL,
  pushed_at timestamptz NOT NULL DEFAULT now(),
  pushed_by text NOT NULL DEFAULT current_user,
  pushed_with text NOT NULL,            -- the mtcal version that pushed
  tombstone boolean NOT NULL DEFAULT false,
  content_sha256 text NOT NULL,         -- of the run's metadata and every part (docs/archive.md)
  parts jsonb NOT NULL,                 -- {table: {"sha256", "rows", "version" holding the rows}}
  instrument_kind text, instrument_model text, instrument_serial text,  -- the main instrument
  kind text NOT NULL, axis text, name text NOT NULL, plan_json text NOT NULL, status text NOT NULL,
  source text NOT NULL, software_version text NOT NULL, started_at text NOT NULL, finished_at text,
  value_unit text NOT NULL, operator_name text NOT NULL, compensation_json text NOT NULL,
  PRIMARY KEY (run_uuid, version),
  UNIQUE (run_uuid, version, station)  -- a version's rows name its station (row-level security)
);
-- Geometric error models (a store's `models`): never changed once made, so never versioned.
CREATE TABLE models (
  id bigint GENERATED ALWAYS AS IDENTITY UNIQUE,  -- the archive's number: mN
  uuid uuid PRIMARY KEY,
  station text NOT NULL REFERENCES stations(name),
  store_uuid uuid NOT NULL,
  pushed_at timestamptz NOT NULL DEFAULT now(),
  name text NOT NULL, machine_json text NOT NULL, method text NOT NULL,
  provenance_json text NOT NULL,        -- as made: run numbers in it are the making store's
  software_version text NOT NULL, created_at text NOT NULL
);
CREATE TABLE model_errors (
  model_uuid uuid NOT NULL REFERENCES models(uuid),
  station text NOT NULL,
  name text NOT NULL, function_json text NOT NULL,
  PRIMARY KEY (model_uuid, name)
);
-- Raw samples, partitioned by the month the run started: years of 50 kHz captures stay
-- fast to add to and to drop or move a month at a time.
CREATE TABLE samples (
  run_month date NOT NULL,
  run_uuid uuid NOT NULL, version integer NOT NULL, station text NOT NULL,
  idx bigint NOT NULL,                  -- order within the run, from 0
  device_seq bigint NOT NULL, device_time_ns bigint NOT NULL, value double precision NOT NULL,
  signal_pct integer NOT NULL,
  PRIMARY KEY (run_month, run_uuid, version, idx)
  -- No foreign key: checking one per row tripled the time of a COPY (docs/archive.md); a
  -- station's rows are checked by mtcal_station_rows() below, and a pull by the SHA-256.
) PARTITION BY RANGE (run_month);
-- The partition of a month, made when a push first needs it (by its owner's rights: a
-- station may add rows, not tables).
CREATE FUNCTION mtcal_samples_partition(month date) RETURNS void LANGUAGE plpgsql SECURITY DEFINER
SET search_path = public AS $$
DECLARE
  first date := date_trunc('month', month)::date;
  name text := 'samples_' || to_char(first, 'YYYY_MM');
BEGIN
  PERFORM pg_advisory_xact_lock(hashtext(name));
  IF to_regclass(name) IS NULL THEN
    EXECUTE format('CREATE TABLE %I PARTITION OF samples FOR VALUES FROM (%L) TO (%L)',
                   name, first, (first + interval '1 month')::date);
  END IF;
END $$;
CREATE TABLE targets (
  run_uuid uuid NOT NULL, version integer NOT NULL, station text NOT NULL,
  seq bigint NOT NULL, target_mm double precision NOT NULL, direction integer NOT NULL, cycle integer NOT NULL,
  measured_mm double precision NOT NULL, deviation_um double precision NOT NULL, time_s double precision,
  sample_count bigint NOT NULL, sample_stddev_um double precision,
  air_temp_c double precision, air_pressure_pa double precision, humidity_pct double precision,
  material_temp_c double precision, air_index double precision,
  first_sample bigint, last_sample bigint,  -- samples.idx
  captured_at text NOT NULL,
  PRIMARY KEY (run_uuid, version, seq),
  FOREIGN KEY (run_uuid, version, station) REFERENCES run_versions (run_uuid, version, station)
);
CREATE TABLE environment (
  run_uuid uuid NOT NULL, version integer NOT NULL, station text NOT NULL, idx bigint NOT NULL,
  device_time_ns bigint, air_temp_c double precision, air_pressure_pa double precision,
  humidity_pct double precision, material_temp1_c double precision, material_temp2_c double precision,
  material_temp3_c double precision, recorded_at text NOT NULL,
  PRIMARY KEY (run_uuid, version, idx),
  FOREIGN KEY (run_uuid, version, station) REFERENCES run_versions (run_uuid, version, station)
);
CREATE TABLE channels (
  run_uuid uuid NOT NULL, version integer NOT NULL, station text NOT NULL, idx bigint NOT NULL, name text NOT NULL,
  PRIMARY KEY (run_uuid, version, idx),
  FOREIGN KEY (run_uuid, version, station) REFERENCES run_versions (run_uuid, version, station)
);
CREATE TABLE channel_values (
  run_uuid uuid NOT NULL, version integer NOT NULL, station text NOT NULL, channel text NOT NULL, target_seq bigint NOT NULL,
  value double precision NOT NULL,
  PRIMARY KEY (run_uuid, version, channel, target_seq),
  FOREIGN KEY (run_uuid, version, station) REFERENCES run_versions (run_uuid, version, station)
);
CREATE TABLE results (
  run_uuid uuid NOT NULL, version integer NOT NULL, station text NOT NULL, idx bigint NOT NULL,
  processor text NOT NULL, processor_version text NOT NULL, parameters_json text NOT NULL,
  output_json text NOT NULL, created_at text NOT NULL,
  PRIMARY KEY (run_uuid, version, idx),
  FOREIGN KEY (run_uuid, version, station) REFERENCES run_versions (run_uuid, version, station)
);
CREATE TABLE events (
  run_uuid uuid NOT NULL, version integer NOT NULL, station text NOT NULL, idx bigint NOT NULL,
  level text NOT NULL, message text NOT NULL, created_at text NOT NULL,
  PRIMARY KEY (run_uuid, version, idx),
  FOREIGN KEY (run_uuid, version, station) REFERENCES run_versions (run_uuid, version, station)
);
CREATE TABLE run_notes (
  run_uuid uuid NOT NULL, version integer NOT NULL, station text NOT NULL, idx bigint NOT NULL,
  author text NOT NULL, text text NOT NULL, created_at text NOT NULL,
  PRIMARY KEY (run_uuid, version, idx),
  FOREIGN KEY (run_uuid, version, station) REFERENCES run_versions (run_uuid, version, station)
);
CREATE TABLE run_instruments (
  run_uuid uuid NOT NULL, version integer NOT NULL, station text NOT NULL,
  instrument_kind text NOT NULL, instrument_model text NOT NULL, instrument_serial text NOT NULL, role text NOT NULL,
  PRIMARY KEY (run_uuid, version, instrument_kind, instrument_model, instrument_serial),
  FOREIGN KEY (instrument_kind, instrument_model, instrument_serial) REFERENCES instruments(kind, model, serial),
  FOREIGN KEY (run_uuid, version, station) REFERENCES run_versions (run_uuid, version, station)
);
CREATE TABLE probe_steps (
  run_uuid uuid NOT NULL, version integer NOT NULL, station text NOT NULL, step bigint NOT NULL, position_mm double precision NOT NULL,
  channel integer NOT NULL, value_um double precision NOT NULL, s_um double precision, readings integer NOT NULL,
  PRIMARY KEY (run_uuid, version, step, channel),
  FOREIGN KEY (run_uuid, version, station) REFERENCES run_versions (run_uuid, version, station)
);
CREATE TABLE circle_points (
  run_uuid uuid NOT NULL, version integer NOT NULL, station text NOT NULL, direction text NOT NULL, idx bigint NOT NULL,
  angle_deg double precision NOT NULL, deviation_um double precision NOT NULL, time_s double precision,
  PRIMARY KEY (run_uuid, version, direction, idx),
  FOREIGN KEY (run_uuid, version, station) REFERENCES run_versions (run_uuid, version, station)
);
CREATE TABLE tracker_points (
  run_uuid uuid NOT NULL, version integer NOT NULL, station text NOT NULL, idx bigint NOT NULL, feature text NOT NULL, place text NOT NULL,
  x_mm double precision NOT NULL, y_mm double precision NOT NULL, z_mm double precision NOT NULL,
  time_s double precision, integration_ms integer,
  PRIMARY KEY (run_uuid, version, idx),
  FOREIGN KEY (run_uuid, version, station) REFERENCES run_versions (run_uuid, version, station)
);
CREATE TABLE thermal_channels (
  run_uuid uuid NOT NULL, version integer NOT NULL, station text NOT NULL, idx integer NOT NULL, name text NOT NULL, kind text NOT NULL,
  unit text NOT NULL,
  PRIMARY KEY (run_uuid, version, idx),
  FOREIGN KEY (run_uuid, version, station) REFERENCES run_versions (run_uuid, version, station)
);
CREATE TABLE thermal_samples (
  run_uuid uuid NOT NULL, version integer NOT NULL, station text NOT NULL, idx bigint NOT NULL, time_s double precision NOT NULL,
  segment integer NOT NULL,
  PRIMARY KEY (run_uuid, version, idx),
  FOREIGN KEY (run_uuid, version, station) REFERENCES run_versions (run_uuid, version, station)
);
CREATE TABLE thermal_values (
  run_uuid uuid NOT NULL, version integer NOT NULL, station text NOT NULL, sample bigint NOT NULL, channel integer NOT NULL,
  value double precision,
  PRIMARY KEY (run_uuid, version, sample, channel),
  FOREIGN KEY (run_uuid, version, station) REFERENCES run_versions (run_uuid, version, station)
);
-- Who may do what (docs/archive.md). A station logs in as a role of its own, member of
-- mtcal_station, named as the station: it reads everything and adds rows of its own station
-- only; it never updates or deletes. A quality engineer's role, member of mtcal_quality, reads.
-- The archive's owner (an administrator) migrates, adds stations and backs up.
DO $$
BEGIN
  IF NOT EXISTS (SELECT FROM pg_roles WHERE rolname = 'mtcal_station') THEN CREATE ROLE mtcal_station NOLOGIN; END IF;
  IF NOT EXISTS (SELECT FROM pg_roles WHERE rolname = 'mtcal_quality') THEN CREATE ROLE mtcal_quality NOLOGIN; END IF;
END $$;
GRANT SELECT ON ALL TABLES IN SCHEMA public TO mtcal_station, mtcal_quality;
REVOKE EXECUTE ON FUNCTION mtcal_samples_partition(date) FROM PUBLIC;
GRANT EXECUTE ON FUNCTION mtcal_samples_partition(date) TO mtcal_station;
-- The rows that describe runs: row-level security, each row in the name of the station adding it.
DO $$
DECLARE
  t text;
BEGIN
  FOREACH t IN ARRAY ARRAY['machines', 'instruments', 'campaigns', 'runs', 'run_versions', 'models',
                           'model_errors'] LOOP
    EXECUTE format('GRANT INSERT ON %I TO mtcal_station', t);
    EXECUTE format('ALTER TABLE %I ENABLE ROW LEVEL SECURITY', t);
    EXECUTE format('CREATE POLICY everyone_reads ON %I FOR SELECT USING (true)', t);
    EXECUTE format('CREATE POLICY a_station_adds_its_own ON %I FOR INSERT TO mtcal_station'
                   ' WITH CHECK (station = current_user)', t);
  END LOOP;
END $$;
-- A version of a run only from the station that first pushed it: no station buries another's run.
ALTER POLICY a_station_adds_its_own ON run_versions WITH CHECK (station = current_user AND
  EXISTS (SELECT 1 FROM runs r WHERE r.uuid = run_versions.run_uuid AND r.station = current_user));
GRANT INSERT ON stations TO mtcal_station;
ALTER TABLE stations ENABLE ROW LEVEL SECURITY;
CREATE POLICY everyone_reads ON stations FOR SELECT USING (true);
CREATE POLICY a_station_adds_itself ON stations FOR INSERT TO mtcal_station WITH CHECK (name = current_user);
-- The rows of a version's parts come by COPY, which row-level security does not allow: a check
-- after each statement refuses, for a station, rows in another station's name and rows added
-- to a version that an earlier transaction pushed (a pushed version never changes).
CREATE FUNCTION mtcal_station_rows() RETURNS trigger LANGUAGE plpgsql AS $$
BEGIN
  IF pg_has_role(current_user, 'mtcal_station', 'MEMBER')
     AND NOT (SELECT rolsuper FROM pg_roles WHERE rolname = current_user) THEN
    IF EXISTS (SELECT 1 FROM (SELECT DISTINCT run_uuid, version, station FROM added) a
               LEFT JOIN run_versions v ON v.run_uuid = a.run_uuid AND v.version = a.version
               WHERE a.station IS DISTINCT FROM current_user
                  OR v.xmin::text::bigint IS DISTINCT FROM txid_current() % 4294967296) THEN
      RAISE EXCEPTION 'station % may add rows to %, in its own name, only to the version it is pushing',
        current_user, TG_TABLE_NAME USING ERRCODE = 'insufficient_privilege';
    END IF;
  END IF;
  RETURN NULL;
END $$;
DO $$
DECLARE
  t text;
BEGIN
  FOREACH t IN ARRAY ARRAY['samples', 'targets', 'environment', 'channels', 'channel_values', 'results', 'events',
      'run_notes', 'run_instruments', 'probe_steps', 'circle_points', 'tracker_points', 'thermal_channels',
      'thermal_samples', 'thermal_values'] LOOP
    EXECUTE format('GRANT INSERT ON %I TO mtcal_station', t);
    EXECUTE format('CREATE TRIGGER station_rows AFTER INSERT ON %I REFERENCING NEW TABLE AS added'
                   ' FOR EACH STATEMENT EXECUTE FUNCTION mtcal_station_rows()', t);
  END LOOP;
END $$;
)sql",
      // v2: several plants in one archive. A plant is a role in mtcal_plant; a station's role,
      // member of one plant, registers in it at its first push. A reader sees the runs first
      // pushed by the stations of its plants (a station's: the one recorded for it; another
      // role's: those whose roles it holds; mtcal_every_plant: all), by stations in no plant
      // (every run of an archive without plants) and by itself, and, as the owner, all; every
      // version of a run, whoever pushed it, goes with the run. Runs'
      // descriptive rows by row-level security; the rows of their parts, which stations add by
      // COPY and so carry no row-level security, through views (visible_samples, ...).
      R"sql(
DO $$
BEGIN
  IF NOT EXISTS (SELECT FROM pg_roles WHERE rolname = 'mtcal_plant') THEN CREATE ROLE mtcal_plant NOLOGIN; END IF;
  IF NOT EXISTS (SELECT FROM pg_roles WHERE rolname = 'mtcal_every_plant') THEN CREATE ROLE mtcal_every_plant NOLOGIN; END IF;
END $$;
ALTER TABLE stations ADD COLUMN plant text;  -- as at the station's first push; the owner may change it
CREATE FUNCTION mtcal_plants() RETURNS SETOF text LANGUAGE sql STABLE AS $$
  SELECT p.rolname::text FROM pg_auth_members m JOIN pg_roles p ON p.oid = m.member
  WHERE m.roleid = (SELECT oid FROM pg_roles WHERE rolname = 'mtcal_plant')
$$;
CREATE FUNCTION mtcal_plants_of(who name) RETURNS text[] LANGUAGE sql STABLE AS $$
  SELECT coalesce(array_agg(p ORDER BY p), '{}') FROM mtcal_plants() p
  WHERE pg_has_role(who, p, 'MEMBER') AND NOT (SELECT rolsuper FROM pg_roles WHERE rolname = who)
$$;
-- The plants a reader reads: a station, the plant recorded for it, whatever else its role
-- holds (before its first push, its role's plant if it has one only); another role, the plants
-- whose roles it holds.
CREATE FUNCTION mtcal_reader_plants() RETURNS text[] LANGUAGE sql STABLE AS $$
  SELECT CASE WHEN NOT pg_has_role(current_user, 'mtcal_station', 'MEMBER') OR r.rolsuper
                THEN mtcal_plants_of(current_user)
              WHEN EXISTS (SELECT 1 FROM public.stations WHERE name = current_user)
                THEN ARRAY[(SELECT plant FROM public.stations WHERE name = current_user)]
              WHEN cardinality(mtcal_plants_of(current_user)) = 1 THEN mtcal_plants_of(current_user)
              ELSE '{}' END
  FROM pg_roles r WHERE r.rolname = current_user
$$;
CREATE FUNCTION mtcal_visible_stations() RETURNS SETOF text LANGUAGE sql STABLE AS $$
  SELECT s.name FROM public.stations s
  WHERE s.plant IS NULL OR s.name = current_user OR pg_has_role(current_user, 'mtcal_every_plant', 'MEMBER')
     OR pg_has_role(current_user, (SELECT relowner FROM pg_class WHERE oid = 'public.stations'::regclass), 'MEMBER')
     OR s.plant = ANY (mtcal_reader_plants())
$$;
-- A station's plant at its first push; a plant the owner gives later must be one.
CREATE FUNCTION mtcal_station_plant() RETURNS trigger LANGUAGE plpgsql AS $$
DECLARE
  plants text[];
BEGIN
  IF TG_OP = 'INSERT' AND NEW.name = current_user AND pg_has_role(current_user, 'mtcal_station', 'MEMBER')
     AND NOT (SELECT rolsuper FROM pg_roles WHERE rolname = current_user) THEN
    plants := mtcal_plants_of(current_user);
    IF cardinality(plants) > 1 THEN
      RAISE EXCEPTION 'station % is a member of the plants %: a station belongs to one plant', current_user,
        array_to_string(plants, ', ') USING ERRCODE = 'invalid_grant_operation';
    END IF;
    NEW.plant := plants[1];
  ELSIF NEW.plant IS NOT NULL AND NEW.plant NOT IN (SELECT mtcal_plants()) THEN
    RAISE EXCEPTION 'plant % is not a plant: a plant is a role in mtcal_plant (CREATE ROLE % NOLOGIN IN ROLE mtcal_plant)',
      NEW.plant, NEW.plant USING ERRCODE = 'foreign_key_violation';
  END IF;
  RETURN NEW;
END $$;
CREATE TRIGGER station_plant BEFORE INSERT OR UPDATE ON stations FOR EACH ROW EXECUTE FUNCTION mtcal_station_plant();
DO $$
DECLARE
  t text;
BEGIN
  FOR t IN SELECT tablename FROM pg_policies WHERE policyname = 'everyone_reads' AND schemaname = 'public'
           AND tablename NOT IN ('stations', 'instruments') LOOP  -- names only, and an instrument travels
    EXECUTE format('ALTER POLICY everyone_reads ON %I USING (%s)', t,
                   CASE WHEN t = 'run_versions' THEN 'EXISTS (SELECT 1 FROM runs r WHERE r.uuid = run_versions.run_uuid)'
                        ELSE 'station IN (SELECT mtcal_visible_stations())' END);
    EXECUTE format('ALTER POLICY everyone_reads ON %I RENAME TO its_plants_read', t);
  END LOOP;
  FOR t IN SELECT tgrelid::regclass::text FROM pg_trigger WHERE tgname = 'station_rows' AND tgparentid = 0 LOOP
    EXECUTE format('REVOKE SELECT ON %I FROM mtcal_station, mtcal_quality', t);
    EXECUTE format('CREATE VIEW %I WITH (security_barrier) AS SELECT * FROM %I WHERE run_uuid IN'
                   ' (SELECT r.uuid FROM runs r WHERE r.station IN (SELECT mtcal_visible_stations()))',
                   'visible_' || t, t);
    EXECUTE format('GRANT SELECT ON %I TO mtcal_station, mtcal_quality', 'visible_' || t);
  END LOOP;
END $$;
)sql",
      // v3: who pushed a version and when are the server's to say, not the client's, and a run's
      // versions are numbered without gaps.
      R"sql(
CREATE FUNCTION mtcal_stamp_push() RETURNS trigger LANGUAGE plpgsql AS $$
BEGIN
  NEW.pushed_at := now();
  IF TG_TABLE_NAME = 'run_versions' THEN
    NEW.pushed_by := current_user;
  END IF;
  RETURN NEW;
END $$;
CREATE TRIGGER stamp_push BEFORE INSERT ON run_versions FOR EACH ROW EXECUTE FUNCTION mtcal_stamp_push();
CREATE TRIGGER stamp_push BEFORE INSERT ON models FOR EACH ROW EXECUTE FUNCTION mtcal_stamp_push();
CREATE FUNCTION mtcal_version_follows() RETURNS trigger LANGUAGE plpgsql SECURITY DEFINER SET search_path = public AS $$
BEGIN
  IF NEW.version > 1 AND NOT EXISTS (SELECT 1 FROM run_versions
                                     WHERE run_uuid = NEW.run_uuid AND version = NEW.version - 1) THEN
    RAISE EXCEPTION 'version % of run % does not follow a version %: a run''s versions are numbered without gaps',
      NEW.version, NEW.run_uuid, NEW.version - 1 USING ERRCODE = 'check_violation';
  END IF;
  RETURN NULL;
END $$;
CREATE TRIGGER version_follows AFTER INSERT ON run_versions FOR EACH ROW EXECUTE FUNCTION mtcal_version_follows();
)sql",
  };
  return kMigrations;
}

int currentVersion(Connection& c) {
  if (!c.scalar("SELECT to_regclass('mtcal_schema') IS NOT NULL").value_or("f").starts_with("t")) return 0;
  return std::stoi(c.scalar("SELECT version FROM mtcal_schema").value_or("0"));
}

StorageError newer(const Connection& c, int version) {
  return StorageError("archive " + c.where() + " has schema v" + std::to_string(version) +
                      ", newer than this mtcal understands (v" + std::to_string(plantSchemaVersion()) + ")");
}

}  // namespace

int plantSchemaVersion() { return static_cast<int>(migrations().size()); }

int migratePlant(Connection& c) {
  const int found = currentVersion(c);
  if (found == plantSchemaVersion()) return found;
  if (found == 0) {  // an archive gets a database of its own
    const auto tables =
        c.scalar("SELECT string_agg(tablename, ', ' ORDER BY tablename) FROM pg_tables WHERE schemaname = 'public'");
    if (tables)
      throw InputError("database " + c.where() + " holds other tables (" + *tables +
                       ") and no mtcal archive: give the archive a database of its own (createdb)");
  }
  // The database's owner only: tables a superuser made would be the superuser's, and the owner
  // could no longer migrate them.
  const auto owner =
      c.scalar("SELECT pg_get_userbyid(datdba) FROM pg_database WHERE datname = current_database()").value_or("");
  if (const auto role = c.scalar("SELECT current_user").value_or(""); role != owner)
    throw StorageError("role " + role + " may not " + (found == 0 ? "make the archive in " : "migrate the archive ") +
                       c.where() +
                       (found == 0 ? " (it holds none yet)" : " (at schema v" + std::to_string(found) + ")") +
                       ": the database's owner, " + owner + ", does, with mtcal archive init --to ADDRESS");
  PgTransaction tx(c);
  // One client migrates at a time; one that waited finds the work done.
  c.exec("SELECT pg_advisory_xact_lock(7236105)");
  // The archive's identity: stores remember which version of a run they saw in which archive.
  c.exec(
      "CREATE TABLE IF NOT EXISTS mtcal_schema (version integer NOT NULL,"
      " archive_uuid uuid NOT NULL DEFAULT gen_random_uuid())");
  if (c.query("SELECT 1 FROM mtcal_schema").empty()) c.exec("INSERT INTO mtcal_schema VALUES (0)");
  int version = currentVersion(c);
  if (version > plantSchemaVersion()) throw newer(c, version);
  const int before = version;
  for (; version < plantSchemaVersion(); ++version) {
    c.exec(migrations()[static_cast<std::size_t>(version)]);
    c.exec("UPDATE mtcal_schema SET version = " + std::to_string(version + 1));
    spdlog::info("archive {}: schema migrated to v{}", c.where(), version + 1);
  }
  tx.commit();
  return before;
}

std::string archiveUuid(Connection& c) { return c.scalar("SELECT archive_uuid FROM mtcal_schema").value_or(""); }

void requirePlantSchema(Connection& c) {
  const int version = currentVersion(c);
  if (version > plantSchemaVersion()) throw newer(c, version);
  if (version == 0)
    throw StorageError(
        "archive " + c.where() +
        " holds no mtcal archive (is the database's name right?); the administrator makes one with mtcal "
        "archive init --to ADDRESS");
  if (version < plantSchemaVersion())
    throw StorageError("archive " + c.where() + " has schema v" + std::to_string(version) + "; this mtcal reads v" +
                       std::to_string(plantSchemaVersion()) +
                       ": the administrator migrates it with mtcal archive init --to ADDRESS");
}

}  // namespace mtcal::archive
