// The reader thread lifecycle the drivers share: the loop's exception is kept and rethrown,
// never swallowed; a stop is a request the loop sees; the destructor joins without throwing.

#include "mtcal/drivers/reader_thread.h"

#include <gtest/gtest.h>
#include <pthread.h>

#include <array>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>

#include "mtcal/error.h"

namespace mtcal::drivers {
namespace {

using namespace std::chrono_literals;

// Waits (bounded) until `done` holds.
template <typename Predicate>
bool eventually(Predicate done) {
  for (const auto deadline = std::chrono::steady_clock::now() + 10s; std::chrono::steady_clock::now() < deadline;) {
    if (done()) return true;
    std::this_thread::sleep_for(1ms);
  }
  return done();
}

TEST(ReaderThread, AStopIsARequestTheLoopSeesAndAJoin) {
  ReaderThread reader;
  std::atomic<int> rounds{0};
  std::array<char, 16> name{};
  std::atomic<bool> named{false};
  reader.start("mtcal-test-rd", [&] {
    pthread_getname_np(pthread_self(), name.data(), name.size());
    named = true;
    while (!reader.stopping()) {
      ++rounds;
      std::this_thread::sleep_for(1ms);
    }
  });
  ASSERT_TRUE(eventually([&] { return rounds > 3; }));
  EXPECT_FALSE(reader.stopping());
  EXPECT_NO_THROW(reader.rethrowIfFailed());
  EXPECT_NO_THROW(reader.stop());  // returns once the loop has: nothing runs after it
  EXPECT_TRUE(reader.stopping());
  const int after_stop = rounds;
  std::this_thread::sleep_for(5ms);
  EXPECT_EQ(rounds, after_stop);
  ASSERT_TRUE(named);
  EXPECT_EQ(std::string(name.data()), "mtcal-test-rd");
  EXPECT_NO_THROW(reader.stop());  // a second stop has nothing to do
}

TEST(ReaderThread, TheLoopsExceptionIsKeptForPollAndHandedOverByStop) {
  ReaderThread reader;
  reader.start("", [] { throw TimeoutError("test: stream stalled"); });
  ASSERT_TRUE(eventually([&] { return reader.failed(); }));
  // rethrowIfFailed() keeps it: every poll sees it.
  EXPECT_THROW(reader.rethrowIfFailed(), TimeoutError);
  EXPECT_THROW(reader.rethrowIfFailed(), TimeoutError);
  EXPECT_TRUE(reader.failed());
  // stop() joins and hands it over, once.
  try {
    reader.stop();
    FAIL() << "the loop's exception was swallowed";
  } catch (const TimeoutError& e) {
    EXPECT_STREQ(e.what(), "test: stream stalled");
  }
  EXPECT_FALSE(reader.failed());
  EXPECT_NO_THROW(reader.rethrowIfFailed());
  EXPECT_NO_THROW(reader.stop());
}

TEST(ReaderThread, TakeErrorAndStopAndTakeErrorHandOverWithoutThrowing) {
  ReaderThread reader;
  reader.start("", [] { throw std::runtime_error("not an mtcal error"); });  // anything is kept
  ASSERT_TRUE(eventually([&] { return reader.failed(); }));
  const std::exception_ptr taken = reader.takeError();
  ASSERT_TRUE(taken);
  EXPECT_THROW(std::rethrow_exception(taken), std::runtime_error);
  EXPECT_FALSE(reader.failed());
  EXPECT_FALSE(reader.stopAndTakeError());  // joined; nothing left to hand over

  // A loop that ends by itself (the device said the stream is over) is no failure, and the
  // reader starts again after the join.
  bool ran = false;
  reader.start("", [&] { ran = true; });
  EXPECT_FALSE(reader.stopAndTakeError());
  EXPECT_TRUE(ran);
  reader.start("", [] { throw DeviceError("second run"); });
  EXPECT_THROW(reader.stop(), DeviceError);
}

TEST(ReaderThread, OnFailureRunsAfterTheErrorIsKeptSoAWaiterWakesToIt) {
  ReaderThread reader;
  std::mutex mutex;
  std::condition_variable cv;
  bool kept_when_called = false;
  reader.start(
      "", [] { throw TransportError("test: disconnected"); },
      [&] {
        kept_when_called = reader.failed();
        std::lock_guard lock(mutex);
        cv.notify_all();
      });
  {
    // A control thread waiting for a reply wakes to the failure long before its timeout.
    std::unique_lock lock(mutex);
    const auto before = std::chrono::steady_clock::now();
    EXPECT_TRUE(cv.wait_for(lock, 10s, [&] { return reader.failed(); }));
    EXPECT_LT(std::chrono::steady_clock::now() - before, 5s);
  }
  EXPECT_THROW(reader.stop(), TransportError);
  EXPECT_TRUE(kept_when_called);
}

TEST(ReaderThread, StartingOverARunningLoopIsRefused) {
  ReaderThread reader;
  reader.start("", [&] {
    while (!reader.stopping()) std::this_thread::sleep_for(1ms);
  });
  EXPECT_THROW(reader.start("", [] {}), DeviceError);
  EXPECT_FALSE(reader.stopping());  // the refused start changed nothing
  EXPECT_NO_THROW(reader.stop());
}

TEST(ReaderThread, TheDestructorStopsAndJoinsWithoutThrowing) {
  std::atomic<bool> ended{false};
  {
    ReaderThread running;
    running.start("", [&] {
      while (!running.stopping()) std::this_thread::sleep_for(1ms);
      ended = true;
    });
  }
  EXPECT_TRUE(ended);
  {
    ReaderThread failed;
    failed.start("", [] { throw TransportError("never fetched"); });
    ASSERT_TRUE(eventually([&] { return failed.failed(); }));
  }  // the error is dropped, not thrown from the destructor
}

}  // namespace
}  // namespace mtcal::drivers
