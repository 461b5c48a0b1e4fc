#pragma once
// Records an instrument's raw stream into a run: the reader thread fills a bounded queue,
// this consumer converts and commits batches, at least every `commit_interval`, so a crash
// loses at most that much and a 50 kHz stream is stored without loss.

#include <atomic>
#include <chrono>
#include <cstdint>

#include "mtcal/acquisition/sample_queue.h"
#include "mtcal/drivers/instrument.h"
#include "mtcal/storage/store.h"

namespace mtcal::acquisition {

struct StreamRecordOptions {
  std::uint32_t rate_hz = 1000;
  std::uint64_t sample_limit = 0;                  ///< stop after this many (0: no limit)
  std::chrono::milliseconds duration{0};           ///< stop after this long (0: no limit)
  std::chrono::milliseconds commit_interval{100};  ///< longest time between commits
  std::size_t queue_capacity = 1 << 20;
  OverflowPolicy overflow = OverflowPolicy::kDropNewest;
  const std::atomic<bool>* stop_requested = nullptr;
};

struct StreamRecordResult {
  std::uint64_t stored = 0;
  std::uint64_t commits = 0;
  std::uint64_t dropped = 0;                    ///< by the queue
  std::chrono::microseconds max_commit_gap{0};  ///< longest time between two durable commits
  drivers::StreamStats stream;
};

/// @throws what the instrument or storage throws; samples committed before stay committed.
StreamRecordResult recordStream(drivers::Instrument& instrument, storage::Store& store, storage::Id run_id,
                                const StreamRecordOptions& options);

}  // namespace mtcal::acquisition
