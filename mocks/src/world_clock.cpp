#include "mtcal/mocks/world_clock.h"

#include <fmt/format.h>

#include <algorithm>

#include "mtcal/error.h"

namespace mtcal::mocks {

namespace {
/// How long a host waits for a world that another hold keeps back before it gives up: a
/// participant that never moves its hold on is a bug, not a slow machine.
constexpr auto kHeldTooLong = std::chrono::seconds(60);
/// How often a waiter looks again while a hold keeps the world below its time.
constexpr auto kHeldPoll = std::chrono::milliseconds(1);
}  // namespace

WorldClock::WorldClock(double time_scale, Mode mode)
    : time_scale_(time_scale), mode_(mode), anchor_wall_(std::chrono::steady_clock::now()) {
  if (!(time_scale > 0.0)) throw InputError("world clock: the time scale must be > 0");
  if (mode_ == Mode::kLockStep) holds_[kHostHold] = 0.0;
}

double WorldClock::limitLocked() const {
  double limit = std::numeric_limits<double>::infinity();
  for (const auto& [id, world_s] : holds_) limit = std::min(limit, world_s);
  return limit;
}

double WorldClock::nowLocked(Wall wall) const {
  const double paced = anchor_world_s_ + std::chrono::duration<double>(wall - anchor_wall_).count() * time_scale_;
  return std::min(paced, limitLocked());
}

double WorldClock::nowS() const {
  std::lock_guard lock(mutex_);
  return nowLocked(std::chrono::steady_clock::now());
}

void WorldClock::setHoldLocked(std::uint64_t id, double world_s) {
  const Wall wall = std::chrono::steady_clock::now();
  const double now = nowLocked(wall);
  // The world resumes from where it stands (never jumps ahead for the time it was held, never
  // goes back: a hold placed in the past holds it where it is).
  anchor_world_s_ = now;
  anchor_wall_ = wall;
  holds_[id] = std::max(world_s, now);
  changed_.notify_all();
}

void WorldClock::releaseLocked(std::uint64_t id) {
  const Wall wall = std::chrono::steady_clock::now();
  anchor_world_s_ = nowLocked(wall);
  anchor_wall_ = wall;
  holds_.erase(id);
  changed_.notify_all();
}

std::chrono::steady_clock::time_point WorldClock::wakeFor(double world_s) const {
  std::lock_guard lock(mutex_);
  const Wall wall = std::chrono::steady_clock::now();
  const double now = nowLocked(wall);
  if (now >= world_s) return wall;
  if (limitLocked() < world_s) return wall + kHeldPoll;
  return wall + toWall(world_s - now);
}

bool WorldClock::heldBelow(double world_s) const {
  std::lock_guard lock(mutex_);
  const double limit = limitLocked();
  return limit < world_s && nowLocked(std::chrono::steady_clock::now()) >= limit;
}

bool WorldClock::waitUntil(double world_s, std::chrono::steady_clock::time_point deadline) const {
  std::unique_lock lock(mutex_);
  for (;;) {
    const Wall wall = std::chrono::steady_clock::now();
    const double now = nowLocked(wall);
    if (now >= world_s) return true;
    if (wall >= deadline) return false;
    // Woken early when a hold moves; otherwise when the pace gets there.
    const Wall paced =
        limitLocked() < world_s ? deadline : wall + toWall(world_s - now) + std::chrono::microseconds(10);
    changed_.wait_until(lock, std::min(deadline, paced));
  }
}

void WorldClock::letRunTo(double world_s) {
  if (mode_ != Mode::kLockStep) return;
  std::lock_guard lock(mutex_);
  if (holds_.at(kHostHold) < world_s) setHoldLocked(kHostHold, world_s);
}

void WorldClock::advanceTo(double world_s) {
  letRunTo(world_s);
  const auto deadline = std::chrono::steady_clock::now() + toWall(std::max(0.0, world_s - nowS())) + kHeldTooLong;
  if (!waitUntil(world_s, deadline)) {
    throw TimeoutError(fmt::format("simulated world: held at {:.3f} s, it did not reach {:.3f} s", nowS(), world_s));
  }
}

WorldClock::Hold::Hold(WorldClock& clock, double world_s) : clock_(clock) {
  std::lock_guard lock(clock_.mutex_);
  id_ = clock_.next_id_++;
  clock_.setHoldLocked(id_, world_s);
}

WorldClock::Hold::~Hold() {
  std::lock_guard lock(clock_.mutex_);
  clock_.releaseLocked(id_);
}

void WorldClock::Hold::moveTo(double world_s) {
  std::lock_guard lock(clock_.mutex_);
  clock_.setHoldLocked(id_, world_s);
}

}  // namespace mtcal::mocks
