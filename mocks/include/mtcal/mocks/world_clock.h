#pragma once
// Time of the simulated world, in seconds. Paced in scaled real time: the world runs
// `time_scale` times faster than the steady clock, so a campaign of an hour of machine time
// can run in seconds while the instruments still stream in (scaled) real time.
//
// What happens in the world must not depend on when the host got round to doing something:
// a seeded simulation gives the same values whatever the load. So the world never runs past
// a hold. Holds are placed by
// - the host, in lock step (Mode::kLockStep): the world runs only as far as the host asked
//   (advanceTo), so every command of the host falls at a world time the host chose, and an
//   instrument whose reply takes world time (a tracker's integration, its initialisation) lets
//   the world run until its reply is due (letRunTo): the host waits for that reply;
// - participants with scheduled events (a CNC running a part program): the world waits at an
//   event until its owner has acted on it (Hold).
// In free-running mode (Mode::kFree, the default) only participants hold it: the world of an
// instrument that the host reaches like a real one (serial://, tcp://) runs by itself.
//
// Thread-safety: every method may be called from any thread.

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <limits>
#include <map>
#include <mutex>

namespace mtcal::mocks {

/// How long a driver talking to an emulator waits for an answer, or for a stream, before it
/// calls the device failed. Generous: a loaded computer can delay a reply by a second or more,
/// and a world in lock step streams only as far as its host lets it. They bound how long a
/// real failure takes to show, nothing else.
inline constexpr std::chrono::milliseconds kEmulatorReplyTimeout{10'000};
inline constexpr std::chrono::milliseconds kEmulatorStallTimeout{30'000};

class WorldClock {
 public:
  enum class Mode { kFree, kLockStep };
  explicit WorldClock(double time_scale = 1.0, Mode mode = Mode::kFree);
  WorldClock(const WorldClock&) = delete;
  WorldClock& operator=(const WorldClock&) = delete;

  double nowS() const;
  bool lockStep() const { return mode_ == Mode::kLockStep; }
  double timeScale() const { return time_scale_; }
  /// Wall-clock duration of a world-time interval.
  std::chrono::nanoseconds toWall(double world_s) const {
    return std::chrono::nanoseconds(static_cast<long long>(world_s / time_scale_ * 1e9));
  }
  /// When to look again for the world to reach `world_s`: the wall time it takes at the pace,
  /// or a millisecond when a hold keeps the world below it (a hold may move any time).
  std::chrono::steady_clock::time_point wakeFor(double world_s) const;
  /// The world stands at a hold short of `world_s`: it will not get there until a hold moves.
  bool heldBelow(double world_s) const;
  /// Blocks until the world reaches `world_s` or the wall deadline passes. @return reached
  bool waitUntil(double world_s, std::chrono::steady_clock::time_point deadline) const;

  /// Lock step: lets the world run to `world_s` (the host's hold is never moved back) and
  /// blocks until it is there. Free-running: only waits.
  /// @throws TimeoutError when another hold keeps the world from it for a wall minute.
  void advanceTo(double world_s);
  /// Lock step: lets the world run at least to `world_s` without waiting (an instrument whose
  /// answer is due then). Free-running: nothing.
  void letRunTo(double world_s);

  /// A participant's hold: the world does not pass it until moved on or destroyed.
  class Hold {
   public:
    Hold(WorldClock& clock, double world_s);
    ~Hold();
    Hold(const Hold&) = delete;
    Hold& operator=(const Hold&) = delete;
    void moveTo(double world_s);

   private:
    WorldClock& clock_;
    std::uint64_t id_;
  };

 private:
  using Wall = std::chrono::steady_clock::time_point;
  /// World time now (mutex held).
  double nowLocked(Wall wall) const;
  double limitLocked() const;
  /// Changes a hold (mutex held): the world's position is kept, the pace resumes from it.
  void setHoldLocked(std::uint64_t id, double world_s);
  void releaseLocked(std::uint64_t id);

  const double time_scale_;
  const Mode mode_;
  mutable std::mutex mutex_;
  mutable std::condition_variable changed_;
  Wall anchor_wall_;
  double anchor_world_s_ = 0.0;
  std::map<std::uint64_t, double> holds_;  ///< by id
  std::uint64_t next_id_ = 1;
  static constexpr std::uint64_t kHostHold = 0;
};

}  // namespace mtcal::mocks
