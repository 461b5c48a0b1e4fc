#pragma once
// The simulated world a demo or a test runs against: a world clock, a virtual machine and
// the instruments observing it, reachable through the driver registry as mock://NAME.

#include <memory>

#include "mtcal/drivers/registry.h"
#include "mtcal/mocks/ballbar_emulator.h"
#include "mtcal/mocks/interferometer_emulator.h"
#include "mtcal/mocks/logger_emulator.h"
#include "mtcal/mocks/probe_emulator.h"
#include "mtcal/mocks/tracker_emulator.h"
#include "mtcal/mocks/virtual_machine.h"
#include "mtcal/mocks/world_clock.h"

namespace mtcal::mocks {

struct SimulatedWorld {
  /// In lock step (the default) the world runs only as far as the host asks (a run through
  /// mock:// devices); free-running, it runs by itself, as a real workshop does for a host
  /// that reaches its instruments as real ones (serial://, tcp://).
  SimulatedWorld(VirtualMachineConfig machine_config, InterferometerEmulatorConfig interferometer_config,
                 double time_scale, WorldClock::Mode mode = WorldClock::Mode::kLockStep)
      : clock(time_scale, mode),
        machine(std::move(machine_config), clock),
        interferometer(std::make_shared<InterferometerEmulator>(machine, std::move(interferometer_config))) {
    logger.setTriggerOutput([this](double t_s) { probes.trigger(t_s); });
  }
  WorldClock clock;
  VirtualMachine machine;
  std::shared_ptr<InterferometerEmulator> interferometer;
  ProbeBoxEmulator probes{machine, ProbeBoxEmulatorConfig{}};
  std::shared_ptr<BallbarEmulator> ballbar = std::make_shared<BallbarEmulator>(machine, BallbarEmulatorConfig{});
  /// Its record output is wired to the probe box's trigger input.
  LoggerEmulator logger{machine, LoggerEmulatorConfig{}};
  /// The probe box's serial line: a pseudo-terminal opened on first use. @throws TransportError
  const std::string& probesSerialPath();
  /// The temperature logger's serial line, likewise.
  const std::string& loggerSerialPath();
  /// The laser tracker: its TCP server on 127.0.0.1 started on first use (the gantry's
  /// set-up, TrackerEmulatorConfig::forGantry, seeded with the machine's seed). @throws TransportError
  TrackerEmulator& tracker();

 private:
  std::unique_ptr<PtyLink> probes_link_, logger_link_;
  std::unique_ptr<TrackerEmulator> tracker_;
};

/// Adds mock://interferometer, served by the world's emulator through EmulatorTransport and
/// the real InterferometerDevice, and mock://probes, the world's probe box behind a
/// pseudo-terminal opened with the real SerialTransport and ProbeBoxDevice, and mock://ballbar,
/// the world's ballbar through EmulatorHidTransport and the real BallbarDevice, and
/// mock://tracker, the world's laser tracker over a real TCP connection to 127.0.0.1 and the
/// real TrackerDevice, and mock://logger, the world's temperature logger behind a
/// pseudo-terminal with the real SerialTransport and TemperatureLoggerDevice. The world must outlive the registry's
/// use.
void registerMockDrivers(drivers::Registry& registry, SimulatedWorld& world);

}  // namespace mtcal::mocks
