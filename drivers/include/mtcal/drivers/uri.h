#pragma once
// Device URIs: usb://VID:PID[/SERIAL], hid://VID:PID[/SERIAL], serial:///dev/ttyX?baud=N,
// tcp://HOST:PORT, mock://NAME[?key=value&...].

#include <cstdint>
#include <map>
#include <optional>
#include <string>

namespace mtcal::drivers {

struct DeviceUri {
  std::string scheme;  ///< usb, hid, serial, tcp, mock
  std::string text;    ///< the URI as given
  // usb / hid
  std::uint16_t vendor_id = 0, product_id = 0;
  std::optional<std::string> serial;
  // serial: path; tcp: host; mock: name
  std::string path;
  std::uint16_t port = 0;  ///< tcp
  std::map<std::string, std::string> query;

  /// Parses a URI. @throws InputError naming the URI and what is wrong with it.
  static DeviceUri parse(const std::string& text);
};

}  // namespace mtcal::drivers
