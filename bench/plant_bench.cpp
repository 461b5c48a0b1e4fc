// The plant archive on a private PostgreSQL 15 server (started here by
// tests/archive/postgres-server, on a Unix socket, removed at the end):
//  - BM_PlainInsertLoop: the reference, a prepared single-row INSERT of sample rows in a loop, in
//    one transaction, into the archive's samples table (a subset: MTCAL_BENCH_INSERT_ROWS, 200 000);
//  - BM_Push: `archive push` of a store holding one run of MTCAL_BENCH_SAMPLES raw samples
//    (10 000 000) into an empty archive: COPY, one transaction; its rate against the loop's;
//  - BM_HistoryQuery: all runs of one machine (newest version each) in an archive of five years
//    of synthetic campaigns: 100 machines in two plants, a campaign of 12 runs each month; as
//    the owner, and as a quality engineer of one plant (row-level security).
// docs/archive.md gives the figures.

#include <benchmark/benchmark.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "mtcal/archive/plant_archive.h"
#include "mtcal/archive/plant_schema.h"
#include "mtcal/archive/postgres.h"
#include "mtcal/storage/store.h"

namespace {

using namespace mtcal;

std::int64_t fromEnvironment(const char* name, std::int64_t fallback) {
  const char* value = std::getenv(name);
  return value != nullptr ? std::stoll(value) : fallback;
}

/// The server, started on first use and stopped when the program ends.
class Server {
 public:
  Server() {
    const std::string command = std::string(MTCAL_POSTGRES_SERVER) + " start " + info_;
    if (std::system(command.c_str()) != 0) throw std::runtime_error("the PostgreSQL server did not start");
    std::ifstream in(info_);
    std::getline(in, dir_);
    std::getline(in, port_);
  }
  ~Server() { std::system((std::string(MTCAL_POSTGRES_SERVER) + " stop " + info_).c_str()); }
  std::string address(const std::string& database) const {
    return "postgresql:///" + database + "?host=" + dir_ + "&port=" + port_ + "&user=mtcal";
  }
  /// A new, empty database.
  std::string fresh(const std::string& database) {
    archive::Connection admin(address("postgres"));
    admin.exec("DROP DATABASE IF EXISTS " + database + " WITH (FORCE)");
    admin.exec("CREATE DATABASE " + database);
    return address(database);
  }

 private:
  std::string info_ = (std::filesystem::temp_directory_path() / "mtcal_bench_plant.info").string();
  std::string dir_, port_;
};

Server& server() {
  static Server s;
  return s;
}

/// A store with one completed run of `samples` raw samples (made once per process).
const std::string& store(std::int64_t samples) {
  static const std::string path = [samples] {
    const auto p = (std::filesystem::temp_directory_path() / "mtcal_bench_plant.sqlite").string();
    for (const char* suffix : {"", "-wal", "-shm"}) std::filesystem::remove(p + suffix);
    storage::Store s(p);
    storage::NewRun r;
    r.campaign_id = s.addCampaign(s.ensureMachine("bench machine", "", "{}"), "bench");
    r.axis = "X";
    r.name = "50 kHz capture";
    r.status = storage::run_status::kCompleted;
    const auto run = s.addRun(r);
    std::vector<storage::SampleRecord> batch(100000);
    for (std::int64_t done = 0; done < samples; done += static_cast<std::int64_t>(batch.size())) {
      for (std::size_t i = 0; i < batch.size(); ++i) {
        const auto k = done + static_cast<std::int64_t>(i);
        batch[i] = {k, k * 20000, 0.001 * static_cast<double>(k % 100000), 90};
      }
      s.appendSamples(run, batch);
    }
    return p;
  }();
  return path;
}

/// The plain loop's rate, for the push's ratio.
double g_insert_rows_per_s = 0.0;

void BM_PlainInsertLoop(benchmark::State& state) {
  const auto rows = fromEnvironment("MTCAL_BENCH_INSERT_ROWS", 200000);
  for (auto _ : state) {
    state.PauseTiming();
    archive::Connection c(server().fresh("bench_insert"));
    archive::migratePlant(c);
    c.exec("INSERT INTO stations VALUES ('bench')");
    c.exec("INSERT INTO machines VALUES ('00000000-0000-4000-8000-000000000001', 'm', '', '{}', '', 'bench')");
    c.exec(
        "INSERT INTO campaigns(uuid, machine_uuid, name, created_at, station) VALUES "
        "('00000000-0000-4000-8000-000000000002', '00000000-0000-4000-8000-000000000001', 'c', '', 'bench')");
    c.exec(
        "INSERT INTO runs(uuid, station, store_uuid, campaign_uuid) VALUES ('00000000-0000-4000-8000-000000000003',"
        " 'bench', '00000000-0000-4000-8000-000000000004', '00000000-0000-4000-8000-000000000002')");
    c.exec(
        "INSERT INTO run_versions(run_uuid, version, station, store_uuid, pushed_with, content_sha256, parts, kind,"
        " name, plan_json, status, source, software_version, started_at, value_unit, operator_name,"
        " compensation_json) VALUES ('00000000-0000-4000-8000-000000000003', 1, 'bench',"
        " '00000000-0000-4000-8000-000000000004', '', '', '{}', 'linear', 'r', '{}', 'completed', 'acquired', '',"
        " '2026-11-01T00:00:00Z', 'um', '', '{}')");
    c.exec("SELECT mtcal_samples_partition('2026-11-01')");
    state.ResumeTiming();
    const auto start = std::chrono::steady_clock::now();
    archive::PgTransaction tx(c);
    for (std::int64_t k = 0; k < rows; ++k) {
      c.query(
          "INSERT INTO samples(run_month, run_uuid, version, station, idx, device_seq, device_time_ns, value, "
          "signal_pct) VALUES ('2026-11-01', '00000000-0000-4000-8000-000000000003', 1, 'bench', $1, $1, $2, $3, 90)",
          {std::to_string(k), std::to_string(k * 20000), std::to_string(0.001 * static_cast<double>(k % 100000))});
    }
    tx.commit();
    g_insert_rows_per_s =
        static_cast<double>(rows) / std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  }
  state.SetItemsProcessed(state.iterations() * rows);
  state.counters["rows_per_s"] =
      benchmark::Counter(static_cast<double>(state.iterations() * rows), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_PlainInsertLoop)->Unit(benchmark::kMillisecond)->Iterations(1)->UseRealTime();

void BM_Push(benchmark::State& state) {
  const auto samples = fromEnvironment("MTCAL_BENCH_SAMPLES", 10000000);
  const std::string path = store(samples);
  std::int64_t sent = 0;
  for (auto _ : state) {
    state.PauseTiming();
    const std::string address = server().fresh("bench_push");
    storage::Store s(path, storage::Open::kExisting);
    archive::Connection c(address, "mtcal push");
    archive::migratePlant(c);
    state.ResumeTiming();
    const auto start = std::chrono::steady_clock::now();
    const auto rows = archive::push(s, c, {"bench", "bench", {}}).rows_sent;
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    sent += rows;
    // Against the loop measured before in this process (BM_PlainInsertLoop runs first).
    if (g_insert_rows_per_s > 0)
      state.counters["x_insert_loop"] = static_cast<double>(rows) / seconds / g_insert_rows_per_s;
  }
  state.SetItemsProcessed(sent);
  state.counters["rows_per_s"] = benchmark::Counter(static_cast<double>(sent), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_Push)->Unit(benchmark::kMillisecond)->Iterations(1)->UseRealTime();

/// The five years' archive (made once per process).
const std::string& history() {
  static const std::string address = [] {
    const std::string a = server().fresh("bench_history");
    archive::Connection c(a);
    archive::migratePlant(c);
    // Five years, 100 machines, each a campaign of 12 runs a month: 72 000 runs, one version
    // each (a tenth of them two). Machines of even numbers are plant A's (station bay-1), the
    // others plant B's (bay-2).
    c.exec(R"sql(
DO $$ BEGIN
  IF NOT EXISTS (SELECT FROM pg_roles WHERE rolname = 'bench_plant_a') THEN
    CREATE ROLE bench_plant_a NOLOGIN IN ROLE mtcal_plant;
    CREATE ROLE bench_plant_b NOLOGIN IN ROLE mtcal_plant;
    CREATE ROLE bench_qa_a LOGIN IN ROLE mtcal_quality, bench_plant_a;
  END IF;
END $$;
INSERT INTO stations VALUES ('bay-1', now(), 'bench_plant_a'), ('bay-2', now(), 'bench_plant_b');
CREATE FUNCTION pg_temp.station(m integer) RETURNS text LANGUAGE sql AS
  $$ SELECT CASE WHEN m % 2 = 0 THEN 'bay-1' ELSE 'bay-2' END $$;
INSERT INTO machines(uuid, name, created_at, station)
  SELECT md5('m' || m)::uuid, 'machine ' || lpad(m::text, 3, '0'), '2021-01-01', pg_temp.station(m)
  FROM generate_series(1, 100) m;
INSERT INTO campaigns(uuid, machine_uuid, name, created_at, station)
  SELECT md5('c' || m || '-' || mo)::uuid, md5('m' || m)::uuid, 'month ' || mo, '2021-01-01', pg_temp.station(m)
  FROM generate_series(1, 100) m, generate_series(1, 60) mo;
INSERT INTO runs(uuid, station, store_uuid, campaign_uuid)
  SELECT md5('r' || m || '-' || mo || '-' || k)::uuid, pg_temp.station(m), md5('s')::uuid,
    md5('c' || m || '-' || mo)::uuid
  FROM generate_series(1, 100) m, generate_series(1, 60) mo, generate_series(1, 12) k;
INSERT INTO run_versions(run_uuid, version, station, store_uuid, pushed_with, content_sha256, parts, kind, axis, name,
    plan_json, status, source, software_version, started_at, value_unit, operator_name, compensation_json)
  SELECT r.uuid, v, r.station, md5('s')::uuid, 'bench', md5(r.uuid::text || v), '{}', 'linear', 'X', 'run',
    '{}', 'completed', 'acquired', 'bench', '2021-01-01T00:00:00Z', 'um', '', '{}'
  FROM runs r, generate_series(1, 2) v WHERE v = 1 OR r.id % 10 = 0;
ANALYZE;
)sql");
    return a;
  }();
  return address;
}

/// Machine 042's runs, as `user` (the owner, or plant A's quality engineer).
void historyQuery(benchmark::State& state, const std::string& user) {
  std::string address = history();
  address.replace(address.rfind("user=mtcal"), std::string::npos, "user=" + user);
  archive::Connection c(address);
  std::size_t found = 0;
  for (auto _ : state) found = archive::listArchive(c, "machine 042").size();
  state.counters["runs_found"] = static_cast<double>(found);
  state.counters["runs_in_archive"] = 72000;
}
void BM_HistoryQuery(benchmark::State& state) { historyQuery(state, "mtcal"); }
BENCHMARK(BM_HistoryQuery)->Unit(benchmark::kMillisecond)->UseRealTime();
void BM_HistoryQueryAsPlantReader(benchmark::State& state) { historyQuery(state, "bench_qa_a"); }
BENCHMARK(BM_HistoryQueryAsPlantReader)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
