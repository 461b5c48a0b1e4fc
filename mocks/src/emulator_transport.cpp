#include "mtcal/mocks/emulator_transport.h"

#include "mtcal/drivers/ballbar/driver.h"
#include "mtcal/drivers/interferometer/driver.h"
#include "mtcal/drivers/logger/driver.h"
#include "mtcal/drivers/probes/driver.h"
#include "mtcal/drivers/serial_transport.h"
#include "mtcal/drivers/tcp_transport.h"
#include "mtcal/drivers/tracker/driver.h"
#include "mtcal/error.h"
#include "mtcal/mocks/simulation.h"

namespace mtcal::mocks {

std::size_t EmulatorTransport::read(std::span<std::uint8_t> buffer, drivers::milliseconds timeout) {
  const std::size_t n = emulator_->transmit(buffer, timeout);
  if (n == 0) throw TimeoutError(describe() + ": bulk IN timed out");
  return n;
}

void EmulatorTransport::write(std::span<const std::uint8_t> data, drivers::milliseconds /*timeout*/) {
  emulator_->receive(data);
}

void registerMockDrivers(drivers::Registry& registry, SimulatedWorld& world) {
  registry.add(drivers::DriverEntry{
      "interferometer-mock",
      "interferometer",
      "mock",
      [](const drivers::DeviceUri& uri) { return uri.path == "interferometer"; },
      [] { return std::vector<std::string>{"mock://interferometer"}; },
      [&world](const drivers::DeviceUri& uri) -> std::unique_ptr<drivers::Instrument> {
        return std::make_unique<drivers::interferometer::InterferometerDevice>(
            std::make_unique<EmulatorTransport>(world.interferometer), uri.text,
            drivers::interferometer::Timeouts{kEmulatorReplyTimeout, std::chrono::milliseconds(100),
                                              kEmulatorStallTimeout});
      },
  });
  registry.add(drivers::DriverEntry{
      "probes-mock",
      "probes",
      "mock",
      [](const drivers::DeviceUri& uri) { return uri.path == "probes"; },
      [] { return std::vector<std::string>{"mock://probes"}; },
      [&world](const drivers::DeviceUri& uri) -> std::unique_ptr<drivers::Instrument> {
        return std::make_unique<drivers::probes::ProbeBoxDevice>(
            std::make_unique<drivers::SerialTransport>(world.probesSerialPath(), 115200), uri.text,
            drivers::LineTimeouts{kEmulatorReplyTimeout, std::chrono::milliseconds(100), kEmulatorStallTimeout});
      },
  });
  registry.add(drivers::DriverEntry{
      "logger-mock",
      "logger",
      "mock",
      [](const drivers::DeviceUri& uri) { return uri.path == "logger"; },
      [] { return std::vector<std::string>{"mock://logger"}; },
      [&world](const drivers::DeviceUri& uri) -> std::unique_ptr<drivers::Instrument> {
        drivers::LineTimeouts timeouts;
        timeouts.command = kEmulatorReplyTimeout;
        timeouts.stall =
            std::chrono::seconds(drivers::logger::kMaxIntervalS + 60);  // the thermal run watches for late records
        return std::make_unique<drivers::logger::TemperatureLoggerDevice>(
            std::make_unique<drivers::SerialTransport>(world.loggerSerialPath(), 115200), uri.text, timeouts);
      },
  });
  registry.add(drivers::DriverEntry{
      "tracker-mock",
      "tracker",
      "mock",
      [](const drivers::DeviceUri& uri) { return uri.path == "tracker"; },
      [] { return std::vector<std::string>{"mock://tracker"}; },
      [&world](const drivers::DeviceUri& uri) -> std::unique_ptr<drivers::Instrument> {
        return world.tracker().connect(uri.text);
      },
  });
  registry.add(drivers::DriverEntry{
      "ballbar-mock",
      "ballbar",
      "mock",
      [](const drivers::DeviceUri& uri) { return uri.path == "ballbar"; },
      [] { return std::vector<std::string>{"mock://ballbar"}; },
      [&world](const drivers::DeviceUri& uri) -> std::unique_ptr<drivers::Instrument> {
        return std::make_unique<drivers::ballbar::BallbarDevice>(
            std::make_unique<EmulatorHidTransport>(world.ballbar), uri.text,
            drivers::ballbar::Timeouts{std::chrono::milliseconds(20), kEmulatorStallTimeout});
      },
  });
}

TrackerEmulator& SimulatedWorld::tracker() {
  if (!tracker_)
    tracker_ = std::make_unique<TrackerEmulator>(
        machine, TrackerEmulatorConfig::forGantry(machine.config(), machine.config().seed));
  return *tracker_;
}

const std::string& SimulatedWorld::probesSerialPath() {
  if (!probes_link_) {
    probes_link_ =
        std::make_unique<PtyLink>([this](auto bytes) { probes.receive(bytes); },
                                  [this](auto buffer, auto timeout) { return probes.transmit(buffer, timeout); });
  }
  return probes_link_->slavePath();
}

const std::string& SimulatedWorld::loggerSerialPath() {
  if (!logger_link_) {
    logger_link_ =
        std::make_unique<PtyLink>([this](auto bytes) { logger.receive(bytes); },
                                  [this](auto buffer, auto timeout) { return logger.transmit(buffer, timeout); });
  }
  return logger_link_->slavePath();
}

}  // namespace mtcal::mocks
