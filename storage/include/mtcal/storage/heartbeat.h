#pragma once
// Says that this process is alive while it records runs: a thread with its own connection
// renews the heartbeat of this process's running runs every kHeartbeatIntervalS, so that a
// station on another host tells a live run from one whose process died (run_owner.h).
//
// Thread-safety: construct and destroy on one thread; the recording thread uses its own Store.

#include <condition_variable>
#include <mutex>
#include <string>
#include <thread>

namespace mtcal::storage {

class Heartbeat {
 public:
  /// Starts beating for the archive at `db_path` (which must exist).
  explicit Heartbeat(std::string db_path);
  ~Heartbeat();
  Heartbeat(const Heartbeat&) = delete;
  Heartbeat& operator=(const Heartbeat&) = delete;

 private:
  void loop();
  std::string db_path_;
  std::mutex mutex_;
  std::condition_variable wake_;
  bool stop_ = false;
  std::thread thread_;
};

}  // namespace mtcal::storage
