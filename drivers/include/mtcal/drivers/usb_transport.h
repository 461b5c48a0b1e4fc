#pragma once
// USB bulk transport on libusb-1.0. libusb error codes become TransportError /
// TimeoutError here. One transport claims one interface of one device.

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "mtcal/drivers/transport.h"

namespace mtcal::drivers {

struct UsbDeviceDescription {
  std::uint16_t vendor_id = 0, product_id = 0;
  int bus = 0, address = 0;
  std::string serial;  ///< empty when the string descriptor could not be read
  std::string product;
};

/// Lists attached devices with this VID:PID (all when both are 0). @throws TransportError
std::vector<UsbDeviceDescription> enumerateUsb(std::uint16_t vendor_id, std::uint16_t product_id);

class UsbBulkTransport final : public Transport {
 public:
  struct Endpoints {
    int interface_number = 0;
    std::uint8_t out = 0x01;
    std::uint8_t in = 0x81;
  };
  /// Opens the first device with VID:PID (and serial, when given) and claims the interface.
  /// @throws TransportError naming the device when it is absent or cannot be opened.
  UsbBulkTransport(std::uint16_t vendor_id, std::uint16_t product_id, std::optional<std::string> serial,
                   Endpoints endpoints);
  UsbBulkTransport(std::uint16_t vendor_id, std::uint16_t product_id, std::optional<std::string> serial)
      : UsbBulkTransport(vendor_id, product_id, std::move(serial), Endpoints{}) {}
  ~UsbBulkTransport() override;

  std::size_t read(std::span<std::uint8_t> buffer, milliseconds timeout) override;
  void write(std::span<const std::uint8_t> data, milliseconds timeout) override;
  std::string describe() const override;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace mtcal::drivers
