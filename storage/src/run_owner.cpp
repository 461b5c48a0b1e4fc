#include "mtcal/storage/run_owner.h"

#include <signal.h>
#include <unistd.h>

#include <cerrno>
#include <fstream>
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

bool ownerAlive(const RunOwner& owner) {
  if (owner.pid <= 0) return false;
  if (owner.host != hostName()) return owner.heartbeat_age_s && *owner.heartbeat_age_s < kOwnerStaleAfterS;
  if (!owner.process_start.empty()) return processStart(owner.pid) == owner.process_start;
  // No /proc: the pid alone (a reused pid then looks alive).
  return ::kill(static_cast<pid_t>(owner.pid), 0) == 0 || errno == EPERM;
}

std::string describe(const RunOwner& owner) { return "process " + std::to_string(owner.pid) + " on " + owner.host; }

}  // namespace mtcal::storage
