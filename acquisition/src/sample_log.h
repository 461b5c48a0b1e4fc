#pragma once
// A stream kept whole in memory (a circle or a gantry pass: minutes at most at 1 kHz), and
// waiting on it until the instrument's clock reaches a time (the machine is there).

#include <fmt/format.h>

#include <chrono>
#include <condition_variable>
#include <mutex>
#include <span>
#include <vector>

#include "mtcal/acquisition/run_clock.h"
#include "mtcal/drivers/instrument.h"
#include "mtcal/error.h"

namespace mtcal::acquisition {

struct SampleLog final : drivers::SampleSink {
  void push(std::span<const drivers::Sample> s) override {
    std::lock_guard lock(mutex);
    samples.insert(samples.end(), s.begin(), s.end());
    cv.notify_all();
  }
  std::mutex mutex;
  std::condition_variable cv;
  std::vector<drivers::Sample> samples;
};

/// Lets the instruments stream (at `rate_hz`) past device time t_s and waits until a sample
/// of device time >= t_s has arrived or the instrument fails.
/// @throws TimeoutError after `limit`; whatever the instrument's reader failed with
inline void waitForDeviceTime(SampleLog& log, drivers::Instrument& instrument, RunClock& clock, std::uint32_t rate_hz,
                              double t_s, std::chrono::seconds limit) {
  clock.advanceTo(t_s + 1.0 / rate_hz);  // the stream's next sample after t_s is there by then
  const auto deadline = std::chrono::steady_clock::now() + limit;
  std::unique_lock lock(log.mutex);
  while (log.samples.empty() || static_cast<double>(log.samples.back().device_time_ns) * 1e-9 < t_s) {
    lock.unlock();
    instrument.poll();
    lock.lock();
    if (std::chrono::steady_clock::now() > deadline) {
      throw TimeoutError(fmt::format("{}: no sample reached device time {:.3f} s within {} s", instrument.info().uri,
                                     t_s, limit.count()));
    }
    log.cv.wait_for(lock, std::chrono::milliseconds(20));
  }
}

}  // namespace mtcal::acquisition
