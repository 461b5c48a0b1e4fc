#include "mtcal/drivers/uri.h"

#include <charconv>

#include "mtcal/error.h"

namespace mtcal::drivers {
namespace {

[[noreturn]] void bad(const std::string& uri, const std::string& why) {
  throw InputError("device URI '" + uri + "': " + why);
}

std::uint16_t parseHex16(const std::string& uri, std::string_view text, const char* what) {
  unsigned value = 0;
  auto [ptr, ec] = std::from_chars(text.data(), text.data() + text.size(), value, 16);
  if (ec != std::errc() || ptr != text.data() + text.size() || text.empty() || text.size() > 4) {
    bad(uri, std::string(what) + " must be 1 to 4 hex digits, got '" + std::string(text) + "'");
  }
  return static_cast<std::uint16_t>(value);
}

}  // namespace

DeviceUri DeviceUri::parse(const std::string& text) {
  DeviceUri uri;
  uri.text = text;
  auto sep = text.find("://");
  if (sep == std::string::npos) bad(text, "expected SCHEME://..., e.g. usb://1209:c417");
  uri.scheme = text.substr(0, sep);
  std::string rest = text.substr(sep + 3);
  if (auto q = rest.find('?'); q != std::string::npos) {
    std::string query = rest.substr(q + 1);
    rest.resize(q);
    std::size_t start = 0;
    while (start <= query.size()) {
      auto amp = query.find('&', start);
      std::string pair = query.substr(start, amp == std::string::npos ? std::string::npos : amp - start);
      if (!pair.empty()) {
        auto eq = pair.find('=');
        if (eq == std::string::npos || eq == 0) bad(text, "query item '" + pair + "' is not key=value");
        uri.query[pair.substr(0, eq)] = pair.substr(eq + 1);
      }
      if (amp == std::string::npos) break;
      start = amp + 1;
    }
  }
  if (uri.scheme == "usb" || uri.scheme == "hid") {
    std::string ids = rest;
    if (auto slash = rest.find('/'); slash != std::string::npos) {
      ids = rest.substr(0, slash);
      uri.serial = rest.substr(slash + 1);
      if (uri.serial->empty()) bad(text, "empty serial number after '/'");
    }
    auto colon = ids.find(':');
    if (colon == std::string::npos) bad(text, "expected VID:PID in hex, e.g. 1209:c417");
    uri.vendor_id = parseHex16(text, std::string_view(ids).substr(0, colon), "vendor id");
    uri.product_id = parseHex16(text, std::string_view(ids).substr(colon + 1), "product id");
  } else if (uri.scheme == "serial") {
    if (rest.empty() || rest[0] != '/') bad(text, "expected serial:///dev/ttyX");
    uri.path = rest;
  } else if (uri.scheme == "tcp") {
    auto colon = rest.rfind(':');
    if (colon == std::string::npos || colon == 0) bad(text, "expected tcp://HOST:PORT");
    uri.path = rest.substr(0, colon);
    unsigned port = 0;
    std::string_view p = std::string_view(rest).substr(colon + 1);
    auto [ptr, ec] = std::from_chars(p.data(), p.data() + p.size(), port);
    if (ec != std::errc() || ptr != p.data() + p.size() || port == 0 || port > 65535) {
      bad(text, "port must be 1..65535");
    }
    uri.port = static_cast<std::uint16_t>(port);
  } else if (uri.scheme == "mock") {
    if (rest.empty()) bad(text, "expected mock://NAME");
    uri.path = rest;
  } else {
    bad(text, "unknown scheme '" + uri.scheme + "' (known: usb, hid, serial, tcp, mock)");
  }
  return uri;
}

}  // namespace mtcal::drivers
