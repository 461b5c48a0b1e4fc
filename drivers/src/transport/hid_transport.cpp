#include "mtcal/drivers/hid_transport.h"

#include <fmt/format.h>
#include <hidapi/hidapi.h>

#include "mtcal/error.h"
#include "operation_gate.h"

namespace mtcal::drivers {
namespace {

std::string narrow(const wchar_t* text) {
  if (text == nullptr) return {};
  std::string out;
  for (const wchar_t* p = text; *p != 0; ++p) out.push_back(*p < 128 ? static_cast<char>(*p) : '?');
  return out;
}

std::string lastError(hid_device* device) { return narrow(hid_error(device)); }

// hid_init() once per process; hidapi keeps it until hid_exit(), which we never call
// (other transports may still be open when one closes).
void initialise() {
  static const int result = hid_init();
  if (result != 0) throw TransportError("hidapi: initialisation failed: " + lastError(nullptr));
}

}  // namespace

std::vector<HidDeviceDescription> enumerateHid(std::uint16_t vendor_id, std::uint16_t product_id) {
  initialise();
  std::vector<HidDeviceDescription> out;
  hid_device_info* list = hid_enumerate(vendor_id, product_id);
  for (hid_device_info* d = list; d != nullptr; d = d->next) {
    out.push_back({d->vendor_id, d->product_id, d->path ? d->path : "", narrow(d->serial_number),
                   narrow(d->product_string), narrow(d->manufacturer_string)});
  }
  hid_free_enumeration(list);
  return out;
}

struct HidapiTransport::Impl {
  hid_device* device = nullptr;
  std::string description;
  OperationGate gate;
};

HidapiTransport::HidapiTransport(std::uint16_t vendor_id, std::uint16_t product_id, std::optional<std::string> serial)
    : impl_(std::make_unique<Impl>()) {
  const std::string name = fmt::format("hid://{:04x}:{:04x}{}", vendor_id, product_id, serial ? "/" + *serial : "");
  std::string path;
  for (const auto& d : enumerateHid(vendor_id, product_id)) {
    if (!serial || d.serial == *serial) {
      path = d.path;
      break;
    }
  }
  if (path.empty()) throw TransportError(name + ": no such HID device attached");
  impl_->device = hid_open_path(path.c_str());
  if (impl_->device == nullptr) {
    throw TransportError(fmt::format("{}: cannot open {}: {} (permissions? see docs/protocols/ballbar.md)", name, path,
                                     lastError(nullptr)));
  }
  impl_->description = name + " at " + path;
}

HidapiTransport::~HidapiTransport() {
  if (impl_->device != nullptr) hid_close(impl_->device);
}

std::size_t HidapiTransport::read(std::span<std::uint8_t> buffer, milliseconds timeout) {
  const OperationGate::Turn turn(impl_->gate, OperationGate::Kind::kRead);
  const int n = hid_read_timeout(impl_->device, buffer.data(), buffer.size(), static_cast<int>(timeout.count()));
  if (n < 0) throw TransportError(impl_->description + ": read failed: " + lastError(impl_->device));
  if (n == 0) throw TimeoutError(fmt::format("{}: no input report within {} ms", impl_->description, timeout.count()));
  return static_cast<std::size_t>(n);
}

void HidapiTransport::write(std::span<const std::uint8_t> data, milliseconds) {
  // hidraw writes of output reports complete or fail at once: no timeout to apply.
  const OperationGate::Turn turn(impl_->gate, OperationGate::Kind::kOther);
  if (hid_write(impl_->device, data.data(), data.size()) < 0) {
    throw TransportError(impl_->description + ": write failed: " + lastError(impl_->device));
  }
}

void HidapiTransport::setFeature(std::span<const std::uint8_t> report) {
  const OperationGate::Turn turn(impl_->gate, OperationGate::Kind::kOther);
  if (hid_send_feature_report(impl_->device, report.data(), report.size()) < 0) {
    throw TransportError(fmt::format("{}: feature report 0x{:02x} refused: {}", impl_->description, report[0],
                                     lastError(impl_->device)));
  }
}

std::size_t HidapiTransport::getFeature(std::span<std::uint8_t> buffer) {
  const OperationGate::Turn turn(impl_->gate, OperationGate::Kind::kOther);
  const int n = hid_get_feature_report(impl_->device, buffer.data(), buffer.size());
  if (n < 0) {
    throw TransportError(fmt::format("{}: feature report 0x{:02x} not read: {}", impl_->description, buffer[0],
                                     lastError(impl_->device)));
  }
  return static_cast<std::size_t>(n);
}

std::string HidapiTransport::describe() const { return impl_->description; }

}  // namespace mtcal::drivers
