#include "mtcal/acquisition/stream_recorder.h"

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

  auto flush = [&] {
    if (records.empty()) return;
    store.appendSamples(run_id, records);
    result.stored += records.size();
    ++result.commits;
    records.clear();
  };

  instrument.startStream(options.rate_hz, queue);
  const auto started = Clock::now();
  auto last_commit = started;
  try {
    for (;;) {
      instrument.poll();
      const bool limit_reached = options.sample_limit && result.stored + records.size() >= options.sample_limit;
      const bool time_up = options.duration.count() > 0 && Clock::now() - started >= options.duration;
      const bool stopped = options.stop_requested && options.stop_requested->load();
      if (limit_reached || time_up || stopped) break;
      batch.clear();
      std::size_t want = 1 << 16;
      if (options.sample_limit) want = std::min<std::uint64_t>(want, options.sample_limit - result.stored - records.size());
      queue.popBatch(batch, want, std::chrono::milliseconds(10));
      for (const auto& s : batch) records.push_back({s.seq, s.device_time_ns, s.value, s.beam_ok ? s.signal_pct : -1});
      if (Clock::now() - last_commit >= options.commit_interval) {
        flush();
        last_commit = Clock::now();
      }
    }
    queue.close();
    result.stream = instrument.stopStream();
  } catch (...) {
    queue.close();
    try {
      instrument.stopStream();
    } catch (...) {  // NOLINT(bugprone-empty-catch): the first error is the one to report
    }
    flush();  // keep what arrived before the failure
    throw;
  }
  flush();
  result.dropped = queue.dropped();
  return result;
}

}  // namespace mtcal::acquisition
