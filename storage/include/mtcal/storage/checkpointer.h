#pragma once
// Moves WAL checkpoints off a busy writer. SQLite normally checkpoints inside the COMMIT
// that grows the WAL past 1000 pages, copying pages into the database file and syncing it:
// that commit then takes tens to hundreds of milliseconds. While a BackgroundCheckpointer
// lives, the writer's automatic checkpoints are off and a thread with its own connection
// runs PASSIVE checkpoints (which never wait for the writer) every `period`; at the end it
// checkpoints everything and truncates the WAL.
//
// Thread-safety: construct and destroy on the writer's thread; the writer keeps using its
// Database as before.

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <mutex>
#include <thread>

#include "mtcal/storage/sqlite.h"

namespace mtcal::storage {

class BackgroundCheckpointer {
 public:
  /// @throws StorageError when the second connection cannot be opened
  explicit BackgroundCheckpointer(Database& writer, std::chrono::milliseconds period = std::chrono::milliseconds(200));
  ~BackgroundCheckpointer();
  BackgroundCheckpointer(const BackgroundCheckpointer&) = delete;
  BackgroundCheckpointer& operator=(const BackgroundCheckpointer&) = delete;

  /// Checkpoints run so far (for tests and benchmarks).
  int checkpoints() const { return checkpoints_.load(); }

 private:
  void loop();
  Database& writer_;
  Database own_;
  std::chrono::milliseconds period_;
  std::mutex mutex_;
  std::condition_variable wake_;
  bool stop_ = false;
  std::atomic<int> checkpoints_{0};
  std::thread thread_;
};

}  // namespace mtcal::storage
