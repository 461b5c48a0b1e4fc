#pragma once
// Independent work items spread over the machine's cores. Each item is done whole on one thread
// and puts its result where its index says, so what comes out does not depend on the threads.

#include <algorithm>
#include <atomic>
#include <cstddef>
#include <exception>
#include <functional>
#include <mutex>
#include <system_error>
#include <thread>
#include <utility>
#include <vector>

namespace mtcal::processing::detail {

/// At most this many threads: each holds a fit's copies of every reading (a million readings,
/// hundreds of megabytes).
constexpr std::size_t kMostThreads = 4;

/// Whether this thread does an item of inParallel's: work inside one runs on its own thread, the
/// cores being busy already.
inline bool& insideParallelWork() {
  thread_local bool inside = false;
  return inside;
}

/// work(k) for every k in [0, count), on up to the machine's cores (this thread one of them,
/// kMostThreads at most; this thread alone inside another inParallel's work); `done(n)`, where
/// given, on this thread after each item it finishes, n the items finished on all threads so far
/// (a progress display). The first exception thrown (by work, or by done) is thrown here once
/// every thread has stopped; the items not yet begun then are not done.
inline void inParallel(std::size_t count, const std::function<void(std::size_t)>& work,
                       const std::function<void(std::size_t)>& done = {}) {
  const std::size_t cores = std::max(1u, std::thread::hardware_concurrency());
  const std::size_t threads = insideParallelWork() ? 1 : std::min({count, cores, kMostThreads});
  std::atomic<std::size_t> next{0}, finished{0};
  std::atomic<bool> failed{false};
  std::exception_ptr failure;
  std::mutex failure_mutex;
  const auto run = [&](bool here) {
    const bool was_inside = std::exchange(insideParallelWork(), true);
    for (std::size_t k = next++; k < count && !failed; k = next++) {
      try {
        work(k);
        const std::size_t n = ++finished;
        if (here && done) done(n);
      } catch (...) {
        const std::lock_guard lock(failure_mutex);
        if (!failure) failure = std::current_exception();
        failed = true;
      }
    }
    insideParallelWork() = was_inside;
  };
  std::vector<std::thread> others;
  for (std::size_t t = 1; t < threads; ++t) {
    try {
      others.emplace_back(run, false);
    } catch (const std::system_error&) {  // no thread to be had: fewer do the work
      break;
    }
  }
  run(true);
  for (auto& t : others) t.join();
  if (failure) std::rethrow_exception(failure);
}

}  // namespace mtcal::processing::detail
