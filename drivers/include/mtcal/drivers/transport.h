#pragma once
// Byte transport under every protocol: USB bulk, HID reports, TCP, serial. Protocol code
// sees only this interface, so the same codec runs against real hardware, an in-process
// emulator or a recorded session.

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>

namespace mtcal::drivers {

using std::chrono::milliseconds;

class Transport {
 public:
  virtual ~Transport() = default;

  /// Reads what is available, at most buffer.size() bytes, waiting up to `timeout` for the
  /// first byte. @return number of bytes read, > 0.
  /// @throws TimeoutError when nothing arrived in time; TransportError when the link failed.
  virtual std::size_t read(std::span<std::uint8_t> buffer, milliseconds timeout) = 0;

  /// Writes all of `data` within `timeout`. @throws TimeoutError, TransportError
  virtual void write(std::span<const std::uint8_t> data, milliseconds timeout) = 0;

  /// Human-readable endpoint for messages, e.g. "usb://1209:c417 bus 1 address 4".
  virtual std::string describe() const = 0;
};

}  // namespace mtcal::drivers
