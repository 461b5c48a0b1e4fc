#pragma once
// The explicit list of drivers, keyed by URI. No self-registering statics: the built-in
// drivers are added by registerBuiltInDrivers() (drivers/src/registry.cpp) and the mock
// instruments by mocks::registerMockDrivers(), each called explicitly by the program.

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "mtcal/drivers/instrument.h"
#include "mtcal/drivers/uri.h"
#include "mtcal/error.h"

namespace mtcal::drivers {

struct DriverEntry {
  std::string name;    ///< e.g. "interferometer-usb"
  std::string kind;    ///< instrument kind it opens
  std::string scheme;  ///< URI scheme it serves
  /// Whether this driver serves the URI (e.g. a VID:PID match). Called only for its scheme.
  std::function<bool(const DeviceUri&)> matches;
  /// URIs of attached devices this driver can open (may be empty).
  std::function<std::vector<std::string>()> scan;
  /// Opens the device. @throws TransportError, ProtocolError, DeviceError
  std::function<std::unique_ptr<Instrument>(const DeviceUri&)> open;
};

struct ScanResult {
  std::string driver;
  std::string uri;
};

class Registry {
 public:
  void add(DriverEntry entry);
  const std::vector<DriverEntry>& drivers() const { return drivers_; }

  /// Opens the device a URI names. @throws InputError when the URI is malformed or no
  /// driver serves it; whatever the driver's open throws.
  std::unique_ptr<Instrument> open(const std::string& uri) const;

  /// Opens and checks the instrument is of type T. @throws InputError otherwise.
  template <typename T>
  std::unique_ptr<T> openAs(const std::string& uri) const {
    auto instrument = open(uri);
    if (auto* typed = dynamic_cast<T*>(instrument.get())) {
      instrument.release();
      return std::unique_ptr<T>(typed);
    }
    const auto info = instrument->info();
    throw InputError("device URI '" + uri + "' opens an instrument of the kind '" + info.kind + "' (" + info.model +
                     "), not the one this command reads");
  }

  /// Asks every driver for attached devices. A driver whose scan fails is skipped.
  std::vector<ScanResult> scan() const;

 private:
  std::vector<DriverEntry> drivers_;
};

/// Adds the drivers for real hardware: USB interferometer, HID ballbar, serial probe box,
/// TCP laser tracker.
void registerBuiltInDrivers(Registry& registry);

}  // namespace mtcal::drivers
