#pragma once
// Who records a run: the process (host, pid and when it started, so that a reused pid is not
// taken for it) and its last heartbeat. A run whose status is running but whose owner has
// gone (killed, crashed, the laptop switched off) is stale: shown and resumable as
// interrupted. A run whose owner is alive is refused to every other process.

#include <cstdint>
#include <optional>
#include <string>

namespace mtcal::storage {

struct RunOwner {
  std::string host;
  std::int64_t pid = 0;
  std::string process_start;              ///< boot id and start time of the process
  std::optional<double> heartbeat_age_s;  ///< since the owner last said it is alive
};

/// A run owned by a process on another host is taken as gone when its heartbeat is older.
inline constexpr double kOwnerStaleAfterS = 120.0;
/// How often a recording process renews its runs' heartbeat (storage::Heartbeat).
inline constexpr double kHeartbeatIntervalS = 15.0;

/// This process.
RunOwner thisProcess();
/// Whether `owner` is this process.
bool isThisProcess(const RunOwner& owner);
/// Whether the owner still records: on this host by its pid and start (and, for this process,
/// whether it is still recording the run); on another by its heartbeat.
bool ownerAlive(const RunOwner& owner, const std::string& archive, std::int64_t run_id);

/// What this process is recording, by archive (its canonical path) and run: a run whose
/// recording ended without its status being stored (the disk was full) is stale at once,
/// not only when the process ends.
void setRecording(const std::string& archive, std::int64_t run_id, bool recording);
/// "process 1234 on host" for messages.
std::string describe(const RunOwner& owner);

}  // namespace mtcal::storage
