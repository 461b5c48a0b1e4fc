#pragma once
// Bounded queue between an instrument's reader thread (producer, through SampleSink) and
// one consumer. The overflow policy is explicit and every dropped sample is counted.

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <mutex>
#include <vector>

#include "mtcal/drivers/instrument.h"

namespace mtcal::acquisition {

enum class OverflowPolicy {
  kBlock,       ///< the producer waits for room (backpressure onto the device buffer)
  kDropNewest,  ///< samples that do not fit are dropped and counted
};

class SampleQueue final : public drivers::SampleSink {
 public:
  SampleQueue(std::size_t capacity, OverflowPolicy policy) : capacity_(capacity), policy_(policy) {}

  void push(std::span<const drivers::Sample> samples) override;

  /// Moves up to `max` samples into `out` (appending), waiting up to `timeout` for the
  /// first. @return number moved.
  std::size_t popBatch(std::vector<drivers::Sample>& out, std::size_t max, std::chrono::milliseconds timeout);
  /// Discards everything queued. @return number discarded.
  std::size_t clear();
  /// Wakes a blocked producer and consumer for good (shutdown).
  void close();

  std::uint64_t dropped() const;
  std::size_t size() const;

 private:
  const std::size_t capacity_;
  const OverflowPolicy policy_;
  mutable std::mutex mutex_;
  std::condition_variable not_empty_, not_full_;
  std::deque<drivers::Sample> samples_;
  std::uint64_t dropped_ = 0;
  bool closed_ = false;
};

}  // namespace mtcal::acquisition
