// Ingest throughput: what a 50 kHz interferometer stream costs on this machine.
//
// BM_RawSqliteInsert is the physical reference: a bare prepared INSERT loop into the same
// samples table, in one transaction. BM_IngestPipeline is the real path: the mock
// interferometer (unpaced) -> EmulatorTransport -> InterferometerDevice (codec, reader
// thread) -> bounded SampleQueue -> recordStream (batches, a durable commit at least every
// 100 ms) -> Store. Both report items_per_second (samples); docs/performance.md gives the
// ratio measured in one process.

#include <benchmark/benchmark.h>

#include <filesystem>

#include "mtcal/acquisition/stream_recorder.h"
#include "mtcal/services/workshop.h"
#include "mtcal/storage/store.h"

namespace {

using namespace mtcal;

constexpr std::int64_t kSamplesPerIteration = 500000;

std::string freshDatabase(const char* name) {
  const auto path = std::filesystem::temp_directory_path() / (std::string("mtcal_bench_") + name + ".sqlite");
  for (const char* suffix : {"", "-wal", "-shm"}) std::filesystem::remove(path.string() + suffix);
  return path.string();
}

storage::Id newRun(storage::Store& store) {
  storage::NewRun r;
  r.campaign_id = store.addCampaign(store.ensureMachine("bench", "", "{}"), "bench");
  r.kind = "stream";
  r.name = "bench";
  return store.addRun(r);
}

void BM_RawSqliteInsert(benchmark::State& state) {
  storage::Store store(freshDatabase("raw"));
  const storage::Id run = newRun(store);
  storage::Statement insert(
      store.database(),
      "INSERT INTO samples(run_id, device_seq, device_time_ns, value, signal_pct) VALUES (?,?,?,?,?)");
  std::int64_t seq = 0;
  for (auto _ : state) {
    storage::Transaction tx(store.database());
    for (std::int64_t i = 0; i < kSamplesPerIteration; ++i, ++seq) {
      insert.bind(1, run)
          .bind(2, seq)
          .bind(3, seq * 20000)
          .bind(4, 100.0 + 1e-9 * static_cast<double>(seq))
          .bind(5, 85);
      insert.run();
    }
    tx.commit();
  }
  state.SetItemsProcessed(state.iterations() * kSamplesPerIteration);
}
BENCHMARK(BM_RawSqliteInsert)->Unit(benchmark::kMillisecond)->UseRealTime()->MinTime(2.0);

// The same bare loop with the statement shape the Store uses (32 rows per INSERT): the
// ceiling of what any pipeline writing these rows can reach on this machine.
void BM_RawSqliteInsertBatched(benchmark::State& state) {
  storage::Store store(freshDatabase("raw_batched"));
  const storage::Id run = newRun(store);
  constexpr int kRows = storage::Store::kSampleRowsPerStatement;
  std::string sql = "INSERT INTO samples(run_id, device_seq, device_time_ns, value, signal_pct) VALUES (?,?,?,?,?)";
  for (int i = 1; i < kRows; ++i) sql += ",(?,?,?,?,?)";
  storage::Statement insert(store.database(), sql);
  std::int64_t seq = 0;
  for (auto _ : state) {
    storage::Transaction tx(store.database());
    for (std::int64_t i = 0; i < kSamplesPerIteration; i += kRows) {
      for (int r = 0; r < kRows; ++r, ++seq) {
        insert.bind(5 * r + 1, run)
            .bind(5 * r + 2, seq)
            .bind(5 * r + 3, seq * 20000)
            .bind(5 * r + 4, 100.0 + 1e-9 * static_cast<double>(seq))
            .bind(5 * r + 5, 85);
      }
      insert.run();
    }
    tx.commit();
  }
  state.SetItemsProcessed(state.iterations() * kSamplesPerIteration);
}
BENCHMARK(BM_RawSqliteInsertBatched)->Unit(benchmark::kMillisecond)->UseRealTime()->MinTime(2.0);

// The mock interferometer on the demo machine, its device opened through the registry, and a
// fresh database with a run to record into.
struct IngestRig {
  IngestRig(const char* name, bool paced)
      : sim(mocks::VirtualMachineConfig::demo(1), interferometer(paced), 1.0,
            mocks::WorldClock::Mode::kFree),  // streams in real time
        store(freshDatabase(name)),
        run(newRun(store)),
        device(sim.registry.openAs<drivers::interferometer::InterferometerDevice>("mock://interferometer")) {}
  static mocks::InterferometerEmulatorConfig interferometer(bool paced) {
    auto c = services::demoInterferometer();
    c.paced = paced;
    return c;
  }
  services::Simulation sim;
  storage::Store store;
  storage::Id run;
  std::unique_ptr<drivers::interferometer::InterferometerDevice> device;
};

void BM_IngestPipeline(benchmark::State& state) {
  IngestRig rig("pipeline", /*paced=*/false);
  acquisition::StreamRecordOptions options;
  options.rate_hz = 50000;
  options.sample_limit = kSamplesPerIteration;
  options.commit_interval = std::chrono::milliseconds(100);
  options.overflow = acquisition::OverflowPolicy::kBlock;  // measure without loss
  std::uint64_t commits = 0, stored = 0;
  std::chrono::microseconds max_gap{0};
  for (auto _ : state) {
    const auto result = acquisition::recordStream(*rig.device, rig.store, rig.run, options);
    if (result.stored != kSamplesPerIteration || result.stream.lost_samples != 0) state.SkipWithError("samples lost");
    commits += result.commits;
    max_gap = std::max(max_gap, result.max_commit_gap);
    stored += result.stored;
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(stored));
  state.counters["max_commit_gap_ms"] = static_cast<double>(max_gap.count()) / 1000.0;
  state.counters["commits_per_iteration"] =
      benchmark::Counter(static_cast<double>(commits), benchmark::Counter::kAvgIterations);
}
BENCHMARK(BM_IngestPipeline)->Unit(benchmark::kMillisecond)->UseRealTime()->MinTime(2.0);

// The real use: a 50 kHz stream in real time (paced emulator) recorded for 2 s per
// iteration. items_per_second is 50k by construction; what this measures is what the
// stream costs (CPU time per wall second) and the longest gap between durable commits.
void BM_Ingest50kHzRealTime(benchmark::State& state) {
  IngestRig rig("realtime", /*paced=*/true);
  acquisition::StreamRecordOptions options;
  options.rate_hz = 50000;
  options.duration = std::chrono::milliseconds(2000);
  options.commit_interval = std::chrono::milliseconds(100);
  std::uint64_t stored = 0, lost = 0;
  std::chrono::microseconds max_gap{0};
  for (auto _ : state) {
    const auto result = acquisition::recordStream(*rig.device, rig.store, rig.run, options);
    // 2 s at 50 kHz: a recording far short of 100 000 samples did not stream in real time.
    if (result.stored < 90000) state.SkipWithError("the stream did not run in real time");
    stored += result.stored;
    lost += result.stream.lost_samples + result.dropped;
    max_gap = std::max(max_gap, result.max_commit_gap);
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(stored));
  state.counters["lost"] = static_cast<double>(lost);
  state.counters["max_commit_gap_ms"] = static_cast<double>(max_gap.count()) / 1000.0;
}
BENCHMARK(BM_Ingest50kHzRealTime)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(3);

}  // namespace
