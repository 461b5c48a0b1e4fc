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

/// At most this many threads working at once: each holds a fit's copies of every reading (a
/// million readings, hundreds of megabytes).
constexpr std::size_t kMostThreads = 4;

/// The threads inParallel may run beside the ones already working, over all its calls at once:
/// at first the machine's cores (kMostThreads at most) less the one that calls. A thread
/// spreading work takes one for each thread it starts, which gives it back when it has no item
/// left; a thread waiting for the threads it started gives back its own while it waits. So work
/// inside another's item spreads onto a core that the other's threads have left (the last,
/// longest items of a round would otherwise run alone), and no more threads work than cores.
inline std::atomic<int>& spareThreads() {
  static std::atomic<int> spare{
      static_cast<int>(std::min<std::size_t>(std::max(1u, std::thread::hardware_concurrency()), kMostThreads)) - 1};
  return spare;
}

/// One of spareThreads, where there is one.
inline bool takeSpareThread() {
  auto& spare = spareThreads();
  for (int n = spare.load(); n > 0;) {
    if (spare.compare_exchange_weak(n, n - 1)) return true;
  }
  return false;
}

/// A thread given back to spareThreads.
inline void giveBackThread() {
  ++spareThreads();
  spareThreads().notify_all();
}

/// A thread taken from spareThreads once there is one (a thread that gave back its own while it
/// waited, taking it again: another may have taken it meanwhile, and works till it gives it back).
inline void takeThreadBack() {
  auto& spare = spareThreads();
  for (int n = spare.load();; n = spare.load()) {
    if (n > 0) {
      if (spare.compare_exchange_weak(n, n - 1)) return;
    } else {
      spare.wait(n);
    }
  }
}

/// Whether inParallel runs every item on the calling thread (OneThread).
inline bool& onOneThreadOnly() {
  thread_local bool only = false;
  return only;
}

/// While it lives, inParallel on this thread runs every item here (a result to compare with the
/// one spread over the cores).
class OneThread {
 public:
  OneThread() : was_(std::exchange(onOneThreadOnly(), true)) {}
  ~OneThread() { onOneThreadOnly() = was_; }
  OneThread(const OneThread&) = delete;
  OneThread& operator=(const OneThread&) = delete;

 private:
  bool was_;
};

/// work(k) for every k in [0, count), on this thread and on as many others as spareThreads has
/// (taken when the work begins, and again after each item this thread finishes, while at least
/// two items are left); `done(n)`, where given, on this thread after each item it finishes, and
/// at the end where other threads finished the last ones, n the items finished on all threads so
/// far (a progress display). Each item is done whole on one thread and puts its result where its
/// index says, so what comes out does not depend on the threads. As in a loop: where an item
/// throws (or `done` after it), every item before it is done, none after it is begun but those
/// already under way, and its exception is thrown here once every thread has stopped.
inline void inParallel(std::size_t count, const std::function<void(std::size_t)>& work,
                       const std::function<void(std::size_t)>& done = {}) {
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
  std::vector<std::thread> others;
  // Another thread for the items left, while two or more are (this thread does one of them).
  const auto spread = [&] {
    while (!onOneThreadOnly() && others.size() + 1 < kMostThreads &&
           next + 1 < std::min<std::size_t>(count, first_failed) && takeSpareThread()) {
      try {
        others.emplace_back([&] {
          for (std::size_t k = next++; k < first_failed; k = next++) {
            try {
              work(k);
              ++finished;
            } catch (...) {
              fail(k);
            }
          }
          giveBackThread();
        });
      } catch (...) {  // no thread to be had: fewer do the work
        giveBackThread();
        return;
      }
    }
  };
  spread();
  for (std::size_t k = next++; k < first_failed; k = next++) {
    try {
      work(k);
      const std::size_t n = ++finished;
      if (done) done(reported = n);
    } catch (...) {
      fail(k);
    }
    spread();
  }
  if (!others.empty()) {
    giveBackThread();  // this thread's core, while it waits
    for (auto& t : others) t.join();
    takeThreadBack();
  }
  if (failure) std::rethrow_exception(failure);
  if (done && reported < finished) done(finished);  // the workers finished last
}

}  // namespace mtcal::processing::detail
