#pragma once
// Serial line transport on Boost.Asio's serial_port (termios underneath): 8N1, no flow
// control, a chosen baud rate. Asio and errno codes become TransportError / TimeoutError
// here. Works on real ports (/dev/ttyUSB0) and on pseudo-terminals alike.
//
// Thread-safety: any threads may call it; one operation runs at a time (Asio runs the port's
// operations on one io_context), so a write waits for a pending read, at most its timeout (no
// read begins while it waits).

#include <memory>
#include <string>

#include "mtcal/drivers/transport.h"

namespace mtcal::drivers {

class SerialTransport final : public Transport {
 public:
  /// Opens and configures the port. @throws TransportError naming the path and why
  SerialTransport(const std::string& path, unsigned baud_rate);
  ~SerialTransport() override;

  std::size_t read(std::span<std::uint8_t> buffer, milliseconds timeout) override;
  void write(std::span<const std::uint8_t> data, milliseconds timeout) override;
  std::string describe() const override;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace mtcal::drivers
