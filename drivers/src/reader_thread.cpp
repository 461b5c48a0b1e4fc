#include "mtcal/drivers/reader_thread.h"

#include <pthread.h>

#include <utility>

#include "mtcal/error.h"

namespace mtcal::drivers {

ReaderThread::~ReaderThread() {
  requestStop();
  if (thread_.joinable()) thread_.join();
}

void ReaderThread::start(std::string name, std::function<void()> loop, std::function<void()> on_failure) {
  // Assigning over a joinable std::thread would terminate the program.
  if (thread_.joinable()) throw DeviceError("reader thread '" + name + "' started while the previous one runs");
  {
    std::lock_guard lock(mutex_);
    error_ = nullptr;
  }
  stop_requested_ = false;
  thread_ = std::thread([this, name = std::move(name), loop = std::move(loop), on_failure = std::move(on_failure)] {
    if (!name.empty()) pthread_setname_np(pthread_self(), name.c_str());
    try {
      loop();
    } catch (...) {
      {
        std::lock_guard lock(mutex_);
        error_ = std::current_exception();
      }
      // After the lock is released: on_failure may take the driver's mutex, under which a
      // waiter calls failed() (which takes ours).
      if (on_failure) on_failure();
    }
  });
}

bool ReaderThread::failed() const {
  std::lock_guard lock(mutex_);
  return error_ != nullptr;
}

void ReaderThread::rethrowIfFailed() const {
  std::exception_ptr error;
  {
    std::lock_guard lock(mutex_);
    error = error_;
  }
  if (error) std::rethrow_exception(error);
}

std::exception_ptr ReaderThread::takeError() {
  std::lock_guard lock(mutex_);
  return std::exchange(error_, nullptr);
}

std::exception_ptr ReaderThread::stopAndTakeError() {
  requestStop();
  if (thread_.joinable()) thread_.join();
  return takeError();
}

void ReaderThread::stop() {
  if (auto error = stopAndTakeError()) std::rethrow_exception(error);
}

}  // namespace mtcal::drivers
