#include "mtcal/storage/heartbeat.h"

#include <spdlog/spdlog.h>

#include <chrono>

#include "mtcal/error.h"
#include "mtcal/storage/run_owner.h"
#include "mtcal/storage/sqlite.h"

namespace mtcal::storage {

Heartbeat::Heartbeat(std::string db_path) : db_path_(std::move(db_path)), thread_([this] { loop(); }) {}

Heartbeat::~Heartbeat() {
  {
    const std::lock_guard lock(mutex_);
    stop_ = true;
  }
  wake_.notify_all();
  thread_.join();
}

void Heartbeat::loop() {
  const auto self = thisProcess();
  const auto period = std::chrono::duration<double>(kHeartbeatIntervalS);
  std::unique_lock lock(mutex_);
  while (!wake_.wait_for(lock, period, [this] { return stop_; })) {
    lock.unlock();
    try {
      Database db(db_path_, Open::kExisting);
      Statement beat(db,
                     "UPDATE runs SET heartbeat_at = strftime('%Y-%m-%dT%H:%M:%fZ','now')"
                     " WHERE status = 'running' AND owner_host = ? AND owner_pid = ? AND owner_start = ?");
      beat.bind(1, self.host).bind(2, self.pid).bind(3, self.process_start).run();
    } catch (const Error& e) {
      // A missed beat only makes a remote reader think the run stale sooner; recording goes on.
      spdlog::warn("heartbeat of {}: {}", db_path_, e.what());
    }
    lock.lock();
  }
}

}  // namespace mtcal::storage
