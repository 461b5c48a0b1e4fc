#include "mtcal/storage/checkpointer.h"

#include <pthread.h>
#include <sys/resource.h>
#include <unistd.h>

namespace mtcal::storage {

BackgroundCheckpointer::BackgroundCheckpointer(Database& writer, std::chrono::milliseconds period)
    : writer_(writer), own_(writer.path()), period_(period) {
  writer_.exec("PRAGMA wal_autocheckpoint = 0");
  thread_ = std::thread([this] { loop(); });
}

BackgroundCheckpointer::~BackgroundCheckpointer() {
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
  }
  wake_.notify_all();
  thread_.join();
  try {
    writer_.exec("PRAGMA wal_autocheckpoint = 1000");  // SQLite's default
    own_.exec("PRAGMA wal_checkpoint(TRUNCATE)");      // the writer is idle now
  } catch (...) {  // NOLINT(bugprone-empty-catch): a later commit or close checkpoints anyway
  }
}

void BackgroundCheckpointer::loop() {
  pthread_setname_np(pthread_self(), "mtcal-ckpt");
  // Housekeeping: when the cores are busy, the writer and the instrument's reader come first.
  setpriority(PRIO_PROCESS, static_cast<id_t>(gettid()), 10);
  std::unique_lock lock(mutex_);
  while (!wake_.wait_for(lock, period_, [this] { return stop_; })) {
    lock.unlock();
    try {
      own_.exec("PRAGMA wal_checkpoint(PASSIVE)");
      ++checkpoints_;
    } catch (...) {  // NOLINT(bugprone-empty-catch): a busy checkpoint is retried next period
    }
    lock.lock();
  }
}

}  // namespace mtcal::storage
