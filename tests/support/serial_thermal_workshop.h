#pragma once
// A thermal monitoring session's real instruments, simulated: a temperature logger and a probe
// box on serial ports (the pseudo-terminals of a simulated workshop on a warming machine),
// reached by URI like any port. The workshop stands still until the logger starts logging; the
// CNC's spindle program (an hour at 2000 rpm, an hour at rest) starts then, however long the
// command takes to get there, so the warm-up is recorded from its start.

#include <atomic>
#include <chrono>
#include <memory>
#include <string>
#include <thread>

#include "mtcal/mocks/simulation.h"
#include "time_scale.h"

namespace mtcal::testing {

class SerialThermalWorkshop {
 public:
  SerialThermalWorkshop()
      : world_(config(), mocks::InterferometerEmulatorConfig{}, timeScale(3000.0), mocks::WorldClock::Mode::kFree),
        standstill_(std::make_unique<mocks::WorldClock::Hold>(world_.clock, 0.0)) {
    world_.probes.setMeasuring(2);
    cycle_start_ = std::thread([this] {
      for (const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
           !world_.logger.logging() && !abandoned_ && std::chrono::steady_clock::now() < deadline;) {
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
      }
      world_.machine.thermal()->startProgram({{3600.0, 2000.0}, {3600.0, 0.0}}, world_.clock.nowS());
      standstill_.reset();
    });
  }
  /// A test that ends (or fails) before the logger logged does not wait for it.
  ~SerialThermalWorkshop() {
    abandoned_ = true;
    waitForTheProgram();
  }
  SerialThermalWorkshop(const SerialThermalWorkshop&) = delete;
  SerialThermalWorkshop& operator=(const SerialThermalWorkshop&) = delete;

  std::string loggerUri() { return "serial://" + world_.loggerSerialPath() + "?device=logger&reply_timeout_ms=10000"; }
  std::string probesUri() { return "serial://" + world_.probesSerialPath() + "?reply_timeout_ms=10000"; }
  /// Once the logger has started logging (or a minute has passed without it).
  void waitForTheProgram() {
    if (cycle_start_.joinable()) cycle_start_.join();
  }

 private:
  static mocks::VirtualMachineConfig config() {
    auto c = mocks::VirtualMachineConfig::demo(4);
    c.thermal = mocks::MachineThermalConfig{};
    return c;
  }
  mocks::SimulatedWorld world_;
  std::unique_ptr<mocks::WorldClock::Hold> standstill_;
  std::atomic<bool> abandoned_{false};
  std::thread cycle_start_;
};

}  // namespace mtcal::testing
