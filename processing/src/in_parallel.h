#pragma once
// Independent work items spread over the machine's cores. Each item is done whole on one thread
// and puts its result where its index says, so what comes out does not depend on the threads.

#include <algorithm>
#include <atomic>
#include <cstddef>
#include <exception>
#include <functional>
#include <mutex>
#include <thread>
#include <utility>
#include <vector>

namespace mtcal::processing::detail {

/// At most this many threads: each holds a fit's copies of every reading (a million readings,
/// hundreds of megabytes).
constexpr std::size_t kMostThreads = 4;

/// Whether this thread does an item of inParallel's, beside other threads: work inside it runs
/// on this thread alone, the cores being busy already.
inline bool& insideParallelWork() {
  thread_local bool inside = false;
  return inside;
}

/// work(k) for every k in [0, count), on up to the machine's cores (this thread one of them,
/// kMostThreads at most; this thread alone inside another inParallel's work); `done(n)`, where
/// given, on this thread after each item it finishes, and at the end where other threads
/// finished the last ones, n the items finished on all threads so far (a progress display).
/// As in a loop: where an item throws (or `done` after it), every item before it is done, none
/// after it is begun but those already under way, and its exception is thrown here once every
/// thread has stopped.
inline void inParallel(std::size_t count, const std::function<void(std::size_t)>& work,
                       const std::function<void(std::size_t)>& done = {}) {
  const std::size_t cores = std::max(1u, std::thread::hardware_concurrency());
  const std::size_t threads = insideParallelWork() ? 1 : std::min({count, cores, kMostThreads});
  std::atomic<std::size_t> next{0}, finished{0}, first_failed{count};
  std::exception_ptr failure;  // of the item first_failed
  std::mutex failure_mutex;
  const auto fail = [&](std::size_t k) {
    const std::lock_guard lock(failure_mutex);
    if (k < first_failed) {
      first_failed = k;
      failure = std::current_exception();
    }
  };
  std::size_t reported = 0;
  const auto run = [&](bool here) noexcept {
    const bool was_inside = std::exchange(insideParallelWork(), threads > 1);
    for (std::size_t k = next++; k < first_failed; k = next++) {
      try {
        work(k);
        const std::size_t n = ++finished;
        if (here && done) done(reported = n);
      } catch (...) {
        fail(k);
      }
    }
    insideParallelWork() = was_inside;
  };
  std::vector<std::thread> others;
  others.reserve(threads);
  for (std::size_t t = 1; t < threads; ++t) {
    try {
      others.emplace_back(run, false);
    } catch (...) {  // no thread to be had: fewer do the work
      break;
    }
  }
  run(true);
  for (auto& t : others) t.join();
  if (failure) std::rethrow_exception(failure);
  if (done && reported < finished) done(finished);  // the workers finished last
}

}  // namespace mtcal::processing::detail
