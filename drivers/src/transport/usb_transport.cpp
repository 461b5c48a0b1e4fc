#include "mtcal/drivers/usb_transport.h"

#include <fmt/format.h>
#include <libusb.h>

#include "mtcal/error.h"

namespace mtcal::drivers {
namespace {

// Converts a libusb status into the mtcal hierarchy; the only place libusb codes are seen.
[[noreturn]] void throwUsb(int rc, const std::string& where) {
  const std::string message = fmt::format("{}: {} ({})", where, libusb_strerror(rc), libusb_error_name(rc));
  if (rc == LIBUSB_ERROR_TIMEOUT) throw TimeoutError(message);
  if (rc == LIBUSB_ERROR_NO_DEVICE) throw TransportError(message + ": device disconnected");
  throw TransportError(message);
}

struct Context {
  libusb_context* ctx = nullptr;
  Context() {
    if (int rc = libusb_init(&ctx); rc != 0) throwUsb(rc, "libusb_init");
  }
  ~Context() { libusb_exit(ctx); }
  Context(const Context&) = delete;
  Context& operator=(const Context&) = delete;
};

struct DeviceList {
  libusb_device** list = nullptr;
  ssize_t count = 0;
  explicit DeviceList(libusb_context* ctx) {
    count = libusb_get_device_list(ctx, &list);
    if (count < 0) throwUsb(static_cast<int>(count), "libusb_get_device_list");
  }
  ~DeviceList() { libusb_free_device_list(list, 1); }
  DeviceList(const DeviceList&) = delete;
  DeviceList& operator=(const DeviceList&) = delete;
};

std::string stringDescriptor(libusb_device_handle* handle, std::uint8_t index) {
  if (index == 0 || handle == nullptr) return {};
  unsigned char text[256];
  int n = libusb_get_string_descriptor_ascii(handle, index, text, sizeof text);
  return n > 0 ? std::string(reinterpret_cast<char*>(text), static_cast<std::size_t>(n)) : std::string();
}

bool matches(const libusb_device_descriptor& d, std::uint16_t vid, std::uint16_t pid) {
  return (vid == 0 && pid == 0) || (d.idVendor == vid && d.idProduct == pid);
}

}  // namespace

std::vector<UsbDeviceDescription> enumerateUsb(std::uint16_t vendor_id, std::uint16_t product_id) {
  Context context;
  DeviceList devices(context.ctx);
  std::vector<UsbDeviceDescription> out;
  for (ssize_t i = 0; i < devices.count; ++i) {
    libusb_device_descriptor desc{};
    if (libusb_get_device_descriptor(devices.list[i], &desc) != 0 || !matches(desc, vendor_id, product_id)) continue;
    UsbDeviceDescription d;
    d.vendor_id = desc.idVendor;
    d.product_id = desc.idProduct;
    d.bus = libusb_get_bus_number(devices.list[i]);
    d.address = libusb_get_device_address(devices.list[i]);
    // Strings need the device opened; a device we may not open is still listed.
    libusb_device_handle* handle = nullptr;
    if (libusb_open(devices.list[i], &handle) == 0) {
      d.serial = stringDescriptor(handle, desc.iSerialNumber);
      d.product = stringDescriptor(handle, desc.iProduct);
      libusb_close(handle);
    }
    out.push_back(d);
  }
  return out;
}

struct UsbBulkTransport::Impl {
  Context context;
  libusb_device_handle* handle = nullptr;
  Endpoints endpoints;
  bool claimed = false;
  std::string description;
};

UsbBulkTransport::UsbBulkTransport(std::uint16_t vendor_id, std::uint16_t product_id, std::optional<std::string> serial,
                                   Endpoints endpoints)
    : impl_(std::make_unique<Impl>()) {
  impl_->endpoints = endpoints;
  const std::string wanted = fmt::format("usb://{:04x}:{:04x}{}", vendor_id, product_id, serial ? "/" + *serial : "");
  {
    DeviceList devices(impl_->context.ctx);
    std::string last_error = "no such device attached";
    for (ssize_t i = 0; i < devices.count && impl_->handle == nullptr; ++i) {
      libusb_device_descriptor desc{};
      if (libusb_get_device_descriptor(devices.list[i], &desc) != 0 || !matches(desc, vendor_id, product_id)) continue;
      libusb_device_handle* handle = nullptr;
      if (int rc = libusb_open(devices.list[i], &handle); rc != 0) {
        last_error = fmt::format("cannot open bus {} address {}: {}", libusb_get_bus_number(devices.list[i]),
                                 libusb_get_device_address(devices.list[i]), libusb_strerror(rc));
        continue;
      }
      if (serial && stringDescriptor(handle, desc.iSerialNumber) != *serial) {
        libusb_close(handle);
        last_error = "no attached device has serial " + *serial;
        continue;
      }
      impl_->handle = handle;
      impl_->description = fmt::format("{} (bus {} address {})", wanted, libusb_get_bus_number(devices.list[i]),
                                       libusb_get_device_address(devices.list[i]));
    }
    if (impl_->handle == nullptr) throw TransportError(wanted + ": " + last_error);
  }
  // Let the kernel driver go if one is bound (not the case for a vendor-class device).
  libusb_set_auto_detach_kernel_driver(impl_->handle, 1);
  if (int rc = libusb_claim_interface(impl_->handle, endpoints.interface_number); rc != 0) {
    libusb_close(impl_->handle);
    impl_->handle = nullptr;
    throwUsb(rc, impl_->description + ": claim interface " + std::to_string(endpoints.interface_number));
  }
  impl_->claimed = true;
}

UsbBulkTransport::~UsbBulkTransport() {
  if (impl_->handle) {
    if (impl_->claimed) libusb_release_interface(impl_->handle, impl_->endpoints.interface_number);
    libusb_close(impl_->handle);
  }
}

std::size_t UsbBulkTransport::read(std::span<std::uint8_t> buffer, milliseconds timeout) {
  int transferred = 0;
  int rc = libusb_bulk_transfer(impl_->handle, impl_->endpoints.in, buffer.data(), static_cast<int>(buffer.size()),
                                &transferred, static_cast<unsigned>(timeout.count()));
  if (rc == LIBUSB_ERROR_TIMEOUT && transferred > 0) return static_cast<std::size_t>(transferred);
  if (rc != 0) throwUsb(rc, impl_->description + ": bulk IN");
  if (transferred == 0) throw TimeoutError(impl_->description + ": bulk IN returned a zero-length packet");
  return static_cast<std::size_t>(transferred);
}

void UsbBulkTransport::write(std::span<const std::uint8_t> data, milliseconds timeout) {
  int transferred = 0;
  int rc = libusb_bulk_transfer(impl_->handle, impl_->endpoints.out, const_cast<std::uint8_t*>(data.data()),
                                static_cast<int>(data.size()), &transferred, static_cast<unsigned>(timeout.count()));
  if (rc != 0) throwUsb(rc, impl_->description + ": bulk OUT");
  if (transferred != static_cast<int>(data.size())) {
    throw TransportError(
        fmt::format("{}: bulk OUT wrote {} of {} bytes", impl_->description, transferred, data.size()));
  }
}

std::string UsbBulkTransport::describe() const { return impl_->description; }

}  // namespace mtcal::drivers
