#include "mtcal/mocks/emulator_transport.h"

#include "mtcal/drivers/interferometer/driver.h"
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
            std::make_unique<EmulatorTransport>(world.interferometer), uri.text);
      },
  });
}

}  // namespace mtcal::mocks
