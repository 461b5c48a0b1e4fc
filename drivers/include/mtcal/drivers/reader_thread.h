#pragma once
// The lifecycle every driver's reader thread shares: run a loop on a thread of its own, keep
// the exception it ends with (never swallowed), ask it to stop, join it, and hand that
// exception to the control thread (docs/adding-a-driver.md, item 4).
//
// The loop polls stopping() between reads (each read has a timeout, so a stop is seen within
// one read timeout) and returns; it may also return on its own (the device said the stream is
// over). Whatever it throws ends it and is kept until the next start(), stop() or takeError().
//
// Thread-safety: start(), stop(), stopAndTakeError() and takeError() from one control
// thread; requestStop(), stopping(), failed() and rethrowIfFailed() from any thread, the
// loop's own included. A loop must not stop or destroy its own ReaderThread (the join would
// wait for itself).

#include <atomic>
#include <exception>
#include <functional>
#include <mutex>
#include <string>
#include <thread>

namespace mtcal::drivers {

class ReaderThread {
 public:
  ReaderThread() = default;
  /// Requests the stop and joins; never throws. A kept exception is dropped: stop the reader
  /// first where it matters.
  ~ReaderThread();
  ReaderThread(const ReaderThread&) = delete;
  ReaderThread& operator=(const ReaderThread&) = delete;

  /// Clears the stop request and the kept exception, then runs `loop` on a new thread named
  /// `name` (what top, gdb and perf show; at most 15 characters; empty: left unnamed).
  /// `on_failure` runs on that thread after an exception is kept, e.g. to wake a control
  /// thread waiting on a condition variable whose predicate asks failed(); it must not throw.
  /// @throws DeviceError when the previous loop was not joined (stop() first);
  /// std::system_error when no thread can be started
  void start(std::string name, std::function<void()> loop, std::function<void()> on_failure = {});

  /// Asks the loop to return; does not wait for it.
  void requestStop() noexcept { stop_requested_ = true; }
  /// Whether requestStop() (or stop()) was called since start(); the loop's condition.
  bool stopping() const noexcept { return stop_requested_; }

  /// Whether the loop ended with an exception that is still kept.
  bool failed() const;
  /// Rethrows the kept exception, if any, and keeps it (a poll(); does not join).
  /// @throws whatever the loop threw
  void rethrowIfFailed() const;
  /// Hands over the kept exception (nullptr if none) and forgets it; does not join.
  std::exception_ptr takeError();

  /// Requests the stop, joins the loop and hands over its exception (nullptr if none),
  /// forgetting it; for a driver that has state to settle after the join before it throws.
  /// Does nothing but that hand-over when no loop was started or it was joined already.
  /// @throws std::system_error when called from the loop itself
  std::exception_ptr stopAndTakeError();
  /// stopAndTakeError(), rethrowing the exception.
  /// @throws whatever the loop threw; std::system_error when called from the loop itself
  void stop();

 private:
  std::thread thread_;
  std::atomic<bool> stop_requested_{false};
  mutable std::mutex mutex_;  // guards error_
  std::exception_ptr error_;
};

}  // namespace mtcal::drivers
