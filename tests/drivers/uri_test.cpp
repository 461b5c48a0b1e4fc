#include "mtcal/drivers/uri.h"

#include <gtest/gtest.h>

#include "mtcal/drivers/registry.h"
#include "mtcal/error.h"

namespace mtcal::drivers {
namespace {

TEST(DeviceUri, ParsesEveryScheme) {
  auto usb = DeviceUri::parse("usb://1209:c417/EMU0001");
  EXPECT_EQ(usb.scheme, "usb");
  EXPECT_EQ(usb.vendor_id, 0x1209);
  EXPECT_EQ(usb.product_id, 0xC417);
  EXPECT_EQ(usb.serial, "EMU0001");
  EXPECT_FALSE(DeviceUri::parse("hid://1209:0001").serial.has_value());
  auto serial = DeviceUri::parse("serial:///dev/ttyUSB0?baud=115200");
  EXPECT_EQ(serial.path, "/dev/ttyUSB0");
  EXPECT_EQ(serial.query.at("baud"), "115200");
  auto tcp = DeviceUri::parse("tcp://127.0.0.1:4711");
  EXPECT_EQ(tcp.path, "127.0.0.1");
  EXPECT_EQ(tcp.port, 4711);
  EXPECT_EQ(DeviceUri::parse("mock://interferometer").path, "interferometer");
}

TEST(DeviceUri, RejectsMalformedUrisWithAReason) {
  for (const char* bad :
       {"usb:1209:c417", "usb://1209", "usb://12345:1", "usb://zz:01", "usb://1209:c417/", "tcp://host", "tcp://host:0",
        "tcp://host:70000", "serial://ttyS0", "ftp://x", "mock://", "mock://x?novalue"}) {
    EXPECT_THROW(DeviceUri::parse(bad), InputError) << bad;
  }
  try {
    DeviceUri::parse("usb://12g9:c417");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("vendor id"), std::string::npos) << e.what();
  }
}

TEST(Registry, NamesTheDriversWhenNoneServesAUri) {
  Registry registry;
  registerBuiltInDrivers(registry);
  try {
    registry.open("usb://dead:beef");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("interferometer-usb"), std::string::npos) << e.what();
  }
}

// A reply timeout for an instrument behind a slow link: refused when it is not a whole
// number of milliseconds in range, before any port is opened.
TEST(Registry, ABadReplyTimeoutIsNamed) {
  Registry registry;
  registerBuiltInDrivers(registry);
  for (const char* bad :
       {"serial:///dev/mtcal-no-such-port?reply_timeout_ms=soon", "serial:///dev/mtcal-no-such-port?reply_timeout_ms=0",
        "serial:///dev/mtcal-no-such-port?device=logger&reply_timeout_ms=2.5",
        "tcp://127.0.0.1:9?reply_timeout_ms=-1"}) {
    try {
      registry.open(bad);
      ADD_FAILURE() << bad;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("reply_timeout_ms must be a whole number of milliseconds"),
                std::string::npos)
          << e.what();
    }
  }
  // A good one gets as far as the port, which is missing.
  EXPECT_THROW(registry.open("serial:///dev/mtcal-no-such-port?reply_timeout_ms=5000"), TransportError);
}

}  // namespace
}  // namespace mtcal::drivers
