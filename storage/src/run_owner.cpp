#include "mtcal/storage/run_owner.h"

#include <signal.h>
#include <unistd.h>

#include <cerrno>
#include <fstream>
#include <mutex>
#include <set>
#include <sstream>

namespace mtcal::storage {

namespace {

std::string hostName() {
  char name[256] = {};
  if (::gethostname(name, sizeof name - 1) != 0) return "unknown";
  return name;
}

std::string bootId() {
  std::ifstream in("/proc/sys/kernel/random/boot_id");
  std::string id;
  std::getline(in, id);
  return id;
}

/// Field 22 of /proc/PID/stat: the process's start in clock ticks after boot; empty when unknown.
std::string startTicks(std::int64_t pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/stat");
  std::string line;
  if (!std::getline(in, line)) return {};
  const auto comm_end = line.rfind(')');  // the command name may hold spaces and parentheses
  if (comm_end == std::string::npos) return {};
  std::istringstream fields(line.substr(comm_end + 1));
  std::string field;
  for (int k = 3; k <= 22 && fields >> field; ++k) {
    if (k == 22) return field;
  }
  return {};
}

std::string processStart(std::int64_t pid) {
  const std::string ticks = startTicks(pid);
  return ticks.empty() ? std::string() : bootId() + "/" + ticks;
}

}  // namespace

RunOwner thisProcess() {
  const auto pid = static_cast<std::int64_t>(::getpid());
  return {hostName(), pid, processStart(pid), std::nullopt};
}

bool isThisProcess(const RunOwner& owner) {
  const auto self = thisProcess();
  return owner.host == self.host && owner.pid == self.pid && owner.process_start == self.process_start;
}

namespace {
std::mutex recording_mutex;
std::set<std::pair<std::string, std::int64_t>>& recording() {
  static std::set<std::pair<std::string, std::int64_t>> runs;
  return runs;
}
}  // namespace

void setRecording(const std::string& archive, std::int64_t run_id, bool recording_now) {
  const std::lock_guard lock(recording_mutex);
  if (recording_now) {
    recording().insert({archive, run_id});
  } else {
    recording().erase({archive, run_id});
  }
}

bool ownerAlive(const RunOwner& owner, const std::string& archive, std::int64_t run_id) {
  if (owner.pid <= 0) return false;
  if (isThisProcess(owner)) {
    const std::lock_guard lock(recording_mutex);
    return recording().contains({archive, run_id});
  }
  if (owner.host != hostName()) return owner.heartbeat_age_s && *owner.heartbeat_age_s < kOwnerStaleAfterS;
  if (!owner.process_start.empty()) return processStart(owner.pid) == owner.process_start;
  // No /proc: the pid alone (a reused pid then looks alive).
  return ::kill(static_cast<pid_t>(owner.pid), 0) == 0 || errno == EPERM;
}

std::string describe(const RunOwner& owner) { return "process " + std::to_string(owner.pid) + " on " + owner.host; }

}  // namespace mtcal::storage
