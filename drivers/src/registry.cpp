#include "mtcal/drivers/registry.h"

#include <fmt/format.h>

#include "mtcal/drivers/ballbar/driver.h"
#include "mtcal/drivers/hid_transport.h"
#include "mtcal/drivers/interferometer/driver.h"
#include "mtcal/drivers/logger/driver.h"
#include "mtcal/drivers/probes/driver.h"
#include "mtcal/drivers/serial_transport.h"
#include "mtcal/drivers/tcp_transport.h"
#include "mtcal/drivers/tracker/driver.h"
#include "mtcal/drivers/usb_transport.h"

namespace mtcal::drivers {

void Registry::add(DriverEntry entry) { drivers_.push_back(std::move(entry)); }

std::unique_ptr<Instrument> Registry::open(const std::string& uri) const {
  const DeviceUri parsed = DeviceUri::parse(uri);
  for (const auto& d : drivers_) {
    if (d.scheme == parsed.scheme && d.matches(parsed)) return d.open(parsed);
  }
  std::string known;
  for (const auto& d : drivers_) known += (known.empty() ? "" : ", ") + d.name + " (" + d.scheme + "://)";
  throw InputError("no driver serves '" + uri + "'; drivers: " + known);
}

std::vector<ScanResult> Registry::scan() const {
  std::vector<ScanResult> out;
  for (const auto& d : drivers_) {
    if (!d.scan) continue;
    try {
      for (auto& uri : d.scan()) out.push_back({d.name, uri});
    } catch (const Error&) {
      // A bus we cannot read (no permission, no USB at all) has nothing to list.
    }
  }
  return out;
}

void registerBuiltInDrivers(Registry& registry) {
  namespace ifm = interferometer;
  registry.add(DriverEntry{
      "interferometer-usb",
      "interferometer",
      "usb",
      [](const DeviceUri& uri) { return uri.vendor_id == ifm::kUsbVendorId && uri.product_id == ifm::kUsbProductId; },
      [] {
        std::vector<std::string> uris;
        for (const auto& d : enumerateUsb(ifm::kUsbVendorId, ifm::kUsbProductId)) {
          uris.push_back(
              fmt::format("usb://{:04x}:{:04x}{}", d.vendor_id, d.product_id, d.serial.empty() ? "" : "/" + d.serial));
        }
        return uris;
      },
      [](const DeviceUri& uri) -> std::unique_ptr<Instrument> {
        auto transport = std::make_unique<UsbBulkTransport>(uri.vendor_id, uri.product_id, uri.serial);
        return std::make_unique<ifm::InterferometerDevice>(std::move(transport), uri.text);
      },
  });
  registry.add(DriverEntry{
      "ballbar-hid",
      "ballbar",
      "hid",
      [](const DeviceUri& uri) {
        return uri.vendor_id == ballbar::kUsbVendorId && uri.product_id == ballbar::kUsbProductId;
      },
      [] {
        std::vector<std::string> uris;
        for (const auto& d : enumerateHid(ballbar::kUsbVendorId, ballbar::kUsbProductId)) {
          uris.push_back(
              fmt::format("hid://{:04x}:{:04x}{}", d.vendor_id, d.product_id, d.serial.empty() ? "" : "/" + d.serial));
        }
        return uris;
      },
      [](const DeviceUri& uri) -> std::unique_ptr<Instrument> {
        auto transport = std::make_unique<HidapiTransport>(uri.vendor_id, uri.product_id, uri.serial);
        return std::make_unique<ballbar::BallbarDevice>(std::move(transport), uri.text);
      },
  });
  // How long a command's reply may take: ?reply_timeout_ms=N on serial and tcp URIs (an
  // instrument behind a slow converter or network; the drivers' default otherwise).
  const auto replyTimeout = [](const DeviceUri& uri, std::chrono::milliseconds fallback) {
    const auto it = uri.query.find("reply_timeout_ms");
    if (it == uri.query.end()) return fallback;
    try {
      std::size_t used = 0;
      const long ms = std::stol(it->second, &used);
      if (used != it->second.size() || ms < 1 || ms > 600000) throw std::out_of_range("reply_timeout_ms");
      return std::chrono::milliseconds(ms);
    } catch (const std::exception&) {
      throw InputError("device URI '" + uri.text +
                       "': reply_timeout_ms must be a whole number of milliseconds, 1..600000");
    }
  };
  // Serial ports cannot tell what is attached: the URI says which instrument
  // (?device=probes, the default, or ?device=logger).
  const auto serialDevice = [](const DeviceUri& uri) {
    const auto it = uri.query.find("device");
    const std::string device = it == uri.query.end() ? "probes" : it->second;
    if (device != "probes" && device != "logger") {
      throw InputError("device URI '" + uri.text + "': device must be probes or logger, not '" + device + "'");
    }
    return device;
  };
  const auto serialTransport = [](const DeviceUri& uri) {
    unsigned baud = 115200;
    if (auto it = uri.query.find("baud"); it != uri.query.end()) {
      try {
        baud = static_cast<unsigned>(std::stoul(it->second));
      } catch (const std::exception&) {
        throw InputError("device URI '" + uri.text + "': baud must be a number");
      }
    }
    return std::make_unique<SerialTransport>(uri.path, baud);
  };
  registry.add(DriverEntry{
      "probes-serial",
      "probes",
      "serial",
      [=](const DeviceUri& uri) { return serialDevice(uri) == "probes"; },
      nullptr,
      [=](const DeviceUri& uri) -> std::unique_ptr<Instrument> {
        LineTimeouts timeouts;
        timeouts.command = replyTimeout(uri, timeouts.command);
        return std::make_unique<probes::ProbeBoxDevice>(serialTransport(uri), uri.text, timeouts);
      },
  });
  registry.add(DriverEntry{
      "logger-serial",
      "logger",
      "serial",
      [=](const DeviceUri& uri) { return serialDevice(uri) == "logger"; },
      nullptr,
      [=](const DeviceUri& uri) -> std::unique_ptr<Instrument> {
        LineTimeouts timeouts;
        timeouts.command = replyTimeout(uri, timeouts.command);
        // Records may be a day apart: the thermal run watches for late records itself.
        timeouts.stall = std::chrono::seconds(logger::kMaxIntervalS + 60);
        return std::make_unique<logger::TemperatureLoggerDevice>(serialTransport(uri), uri.text, timeouts);
      },
  });
  registry.add(DriverEntry{
      "tracker-tcp",
      "tracker",
      "tcp",
      [](const DeviceUri&) { return true; },  // the one network instrument so far
      nullptr,                                // no discovery on the network
      [=](const DeviceUri& uri) -> std::unique_ptr<Instrument> {
        tracker::Timeouts timeouts;
        timeouts.command = replyTimeout(uri, timeouts.command);
        return std::make_unique<tracker::TrackerDevice>(std::make_unique<TcpTransport>(uri.path, uri.port), uri.text,
                                                        timeouts);
      },
  });
}

}  // namespace mtcal::drivers
