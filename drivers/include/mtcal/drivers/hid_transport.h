#pragma once
// HID transport: input and output reports through Transport::read/write, feature reports
// through setFeature/getFeature. The hidapi implementation (hidraw backend) converts hidapi
// failures into TransportError / TimeoutError here; nothing above sees a hidapi handle.
//
// Report buffers carry the report ID in byte 0, as hidapi does (numbered reports).

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "mtcal/drivers/transport.h"

namespace mtcal::drivers {

class HidTransport : public Transport {
 public:
  /// read(): one input report (report ID first), waiting up to `timeout` for it.
  /// write(): one output report.
  /// Sends a feature report (`report[0]` is its ID). @throws TransportError when the device
  /// refuses it (hidraw: the ioctl fails) or is gone.
  virtual void setFeature(std::span<const std::uint8_t> report) = 0;
  /// Reads feature report `buffer[0]` into `buffer`. @return its length including the ID.
  /// @throws TransportError
  virtual std::size_t getFeature(std::span<std::uint8_t> buffer) = 0;
};

struct HidDeviceDescription {
  std::uint16_t vendor_id = 0, product_id = 0;
  std::string path;  ///< e.g. /dev/hidraw3
  std::string serial, product, manufacturer;
};

/// Lists HID devices with this VID:PID (all when both are 0). @throws TransportError
std::vector<HidDeviceDescription> enumerateHid(std::uint16_t vendor_id, std::uint16_t product_id);

/// hidapi (hidraw) transport on one device. Thread-safety: every call takes a lock, so a
/// reader thread and a control thread may share it; a read holds the lock for at most its
/// timeout (and none begins while another call waits), so keep reader timeouts short (tens of ms) where features are
/// sent meanwhile.
class HidapiTransport final : public HidTransport {
 public:
  /// Opens the first device with VID:PID (and serial, when given).
  /// @throws TransportError naming the device when it is absent or cannot be opened.
  HidapiTransport(std::uint16_t vendor_id, std::uint16_t product_id, std::optional<std::string> serial);
  ~HidapiTransport() override;

  std::size_t read(std::span<std::uint8_t> buffer, milliseconds timeout) override;
  void write(std::span<const std::uint8_t> data, milliseconds timeout) override;
  void setFeature(std::span<const std::uint8_t> report) override;
  std::size_t getFeature(std::span<std::uint8_t> buffer) override;
  std::string describe() const override;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace mtcal::drivers
