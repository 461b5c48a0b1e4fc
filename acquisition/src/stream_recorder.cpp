#include "mtcal/acquisition/stream_recorder.h"

#include <optional>

#include "mtcal/storage/checkpointer.h"
#include "stop_after_failure.h"

namespace mtcal::acquisition {

StreamRecordResult recordStream(drivers::Instrument& instrument, storage::Store& store, storage::Id run_id,
                                const StreamRecordOptions& options) {
  using Clock = std::chrono::steady_clock;
  SampleQueue queue(options.queue_capacity, options.overflow);
  StreamRecordResult result;
  std::vector<drivers::Sample> batch;
  std::vector<storage::SampleRecord> records;
  batch.reserve(1 << 16);
  records.reserve(1 << 16);

  // Samples are inserted as they arrive, into a transaction that is committed (made
  // durable) within every commit_interval: inserting overlaps the stream instead of piling
  // up behind it, and a crash loses at most one interval. Commits are started at 80 % of
  // the interval so that the batch in hand and the commit itself still fit in it, and WAL
  // checkpoints run on their own thread so that no commit waits for one.
  const storage::BackgroundCheckpointer checkpointer(store.database());
  const auto commit_after = options.commit_interval * 4 / 5;
  std::optional<storage::Transaction> open;
  std::uint64_t uncommitted = 0;
  auto last_durable = Clock::now();
  auto commit = [&] {
    if (!open) return;
    open->commit();
    open.reset();
    const auto now = Clock::now();
    result.max_commit_gap =
        std::max(result.max_commit_gap, std::chrono::duration_cast<std::chrono::microseconds>(now - last_durable));
    last_durable = now;
    result.stored += uncommitted;
    uncommitted = 0;
    ++result.commits;
  };

  auto append = [&] {
    records.clear();
    for (const auto& s : batch) records.push_back({s.seq, s.device_time_ns, s.value, s.beam_ok ? s.signal_pct : -1});
    if (!open) open.emplace(store.database());
    store.appendSamples(run_id, records);
    uncommitted += records.size();
  };

  instrument.startStream(options.rate_hz, queue);
  const auto started = Clock::now();
  last_durable = started;
  auto last_commit = started;
  try {
    for (;;) {
      instrument.poll();
      const bool limit_reached = options.sample_limit && result.stored + uncommitted >= options.sample_limit;
      const bool time_up = options.duration.count() > 0 && Clock::now() - started >= options.duration;
      const bool stopped = options.stop_requested && options.stop_requested->load();
      if (limit_reached || time_up || stopped) break;
      batch.clear();
      std::size_t want = 4096;  // a few ms of work between two looks at the clock
      if (options.sample_limit)
        want = std::min<std::uint64_t>(want, options.sample_limit - result.stored - uncommitted);
      if (queue.popBatch(batch, want, std::chrono::milliseconds(10)) > 0) append();
      if (const auto now = Clock::now(); now - last_commit >= commit_after) {
        last_commit = now;  // commits start every interval, however long one takes
        commit();
      }
    }
    commit();  // before stopping: stopping takes a round trip to the device
    queue.close();
    result.stream = instrument.stopStream();
  } catch (...) {
    queue.close();
    stopAfterFailure(instrument);
    // Keep what arrived before the failure, the samples still queued included (unless
    // storing is what failed: then the error at hand is the one to report).
    try {
      for (batch.clear(); queue.popBatch(batch, 1 << 16, std::chrono::milliseconds(0)) > 0; batch.clear()) append();
      commit();
    } catch (...) {  // NOLINT(bugprone-empty-catch): the first error is reported
    }
    throw;
  }
  commit();
  result.dropped = queue.dropped();
  return result;
}

}  // namespace mtcal::acquisition
