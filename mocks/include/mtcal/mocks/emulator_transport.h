#pragma once
// In-process fake USB transport: the real driver and codec talk to the emulator through it
// exactly as they would through UsbBulkTransport.

#include <memory>

#include "mtcal/drivers/transport.h"
#include "mtcal/mocks/interferometer_emulator.h"

namespace mtcal::mocks {

class EmulatorTransport final : public drivers::Transport {
 public:
  explicit EmulatorTransport(std::shared_ptr<InterferometerEmulator> emulator) : emulator_(std::move(emulator)) {}
  std::size_t read(std::span<std::uint8_t> buffer, drivers::milliseconds timeout) override;
  void write(std::span<const std::uint8_t> data, drivers::milliseconds timeout) override;
  std::string describe() const override { return "mock://interferometer (in-process emulator)"; }

 private:
  std::shared_ptr<InterferometerEmulator> emulator_;
};

}  // namespace mtcal::mocks
