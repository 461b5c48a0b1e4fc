// The real libusb code path of the interferometer driver against a USB device emulated by
// umockdev: enumeration through udev/sysfs, open, claim, string descriptors over control
// transfers and bulk transfers, all through libusb's usbdevfs backend. umockdev's preload
// library (the test runs under umockdev-wrapper) routes the usbdevfs ioctls to the handler
// below, which answers them with our device emulator (umockdev's documentation of
// UMockdevIoctlBase and umockdev-wrapper(1), https://github.com/martinpitt/umockdev).

#include <gtest/gtest.h>
#include <linux/ioctl.h>
#include <linux/usbdevice_fs.h>
#include <umockdev.h>

#include <cerrno>
#include <cstddef>
#include <cstring>
#include <deque>
#include <thread>

#include "mtcal/drivers/interferometer/driver.h"
#include "mtcal/drivers/registry.h"
#include "mtcal/error.h"
#include "mtcal/mocks/interferometer_emulator.h"

namespace mtcal {
namespace {

using namespace std::chrono_literals;
namespace ifm = drivers::interferometer;

// Device 1209:c417 on bus 1 address 2: vendor class, one interface, bulk EP 0x81 IN and
// 0x01 OUT of 512 bytes; strings 1 manufacturer, 2 product, 3 serial.
constexpr const char* kDeviceDescription =
    "P: /devices/pci0000:00/0000:00:14.0/usb1/1-2\n"
    "N: bus/usb/001/002\n"
    "E: SUBSYSTEM=usb\n"
    "E: DEVTYPE=usb_device\n"
    "E: DRIVER=usb\n"
    "E: BUSNUM=001\n"
    "E: DEVNUM=002\n"
    "E: DEVNAME=/dev/bus/usb/001/002\n"
    "E: PRODUCT=1209/c417/100\n"
    "A: busnum=1\\n\n"
    "A: devnum=2\\n\n"
    "A: bConfigurationValue=1\\n\n"
    "A: speed=480\\n\n"
    "A: idVendor=1209\\n\n"
    "A: idProduct=c417\\n\n"
    "H: descriptors=12010002FF000040091217C4000101020301"
    "09022000010100803209040000"
    "02FF000000"
    "07058102000200"
    "07050102000200\n";
constexpr const char* kDeviceNode = "/dev/bus/usb/001/002";

// usbdevfs as seen by libusb, backed by the emulator. Runs on umockdev's ioctl thread only.
class UsbDeviceModel {
 public:
  explicit UsbDeviceModel(mocks::InterferometerEmulator& emulator) : emulator_(emulator) {}
  ~UsbDeviceModel() {
    for (auto* list : {&completed_, &pending_in_, &discarded_}) {
      for (auto& u : *list) release(u);
    }
  }

  static gboolean onIoctl(UMockdevIoctlBase*, UMockdevIoctlClient* client, gpointer self) {
    return static_cast<UsbDeviceModel*>(self)->handle(client);
  }

  int submitted_out = 0, submitted_in = 0, control_transfers = 0;

 private:
  struct Urb {
    UMockdevIoctlData* urb = nullptr;
    UMockdevIoctlData* buffer = nullptr;
    usbdevfs_urb* fields() const { return reinterpret_cast<usbdevfs_urb*>(urb->data); }
  };
  static void release(Urb& u) {
    umockdev_ioctl_data_unref(u.buffer);
    umockdev_ioctl_data_unref(u.urb);
  }

  gboolean handle(UMockdevIoctlClient* client) {
    const gulong request = umockdev_ioctl_client_get_request(client);
    UMockdevIoctlData* arg = umockdev_ioctl_client_get_arg(client);
    switch (request) {
      case USBDEVFS_GET_CAPABILITIES: {
        UMockdevIoctlData* caps = umockdev_ioctl_data_resolve(arg, 0, sizeof(guint32), nullptr);
        *reinterpret_cast<guint32*>(caps->data) = USBDEVFS_CAP_BULK_CONTINUATION | USBDEVFS_CAP_NO_PACKET_SIZE_LIM |
                                                  USBDEVFS_CAP_REAP_AFTER_DISCONNECT | USBDEVFS_CAP_ZERO_PACKET;
        umockdev_ioctl_data_unref(caps);
        umockdev_ioctl_client_complete(client, 0, 0);
        return TRUE;
      }
      case USBDEVFS_CLAIMINTERFACE:
      case USBDEVFS_RELEASEINTERFACE:
      case USBDEVFS_DISCONNECT_CLAIM:
      case USBDEVFS_CLEAR_HALT:
      case USBDEVFS_RESETEP:
        umockdev_ioctl_client_complete(client, 0, 0);
        return TRUE;
      case USBDEVFS_GETDRIVER:
      case USBDEVFS_IOCTL:
        umockdev_ioctl_client_complete(client, -1, ENODATA);  // no kernel driver bound
        return TRUE;
      case USBDEVFS_SUBMITURB:
        return submit(client, arg);
      case USBDEVFS_REAPURB:
      case USBDEVFS_REAPURBNDELAY:
        return reap(client, arg);
      case USBDEVFS_DISCARDURB: {
        const auto addr = reinterpret_cast<gulong>(*reinterpret_cast<void**>(arg->data));
        for (auto it = pending_in_.begin(); it != pending_in_.end(); ++it) {
          if (it->urb->client_addr == addr) {
            it->fields()->status = -ENOENT;
            discarded_.push_back(*it);
            pending_in_.erase(it);
            umockdev_ioctl_client_complete(client, 0, 0);
            return TRUE;
          }
        }
        umockdev_ioctl_client_complete(client, -1, EINVAL);
        return TRUE;
      }
      default:
        return FALSE;
    }
  }

  gboolean submit(UMockdevIoctlClient* client, UMockdevIoctlData* arg) {
    Urb u;
    u.urb = umockdev_ioctl_data_resolve(arg, 0, sizeof(usbdevfs_urb), nullptr);
    usbdevfs_urb* f = u.fields();
    u.buffer = umockdev_ioctl_data_resolve(u.urb, offsetof(usbdevfs_urb, buffer), static_cast<gsize>(f->buffer_length),
                                           nullptr);
    auto* data = reinterpret_cast<std::uint8_t*>(u.buffer->data);
    f->status = 0;
    if (f->type == USBDEVFS_URB_TYPE_CONTROL) {
      ++control_transfers;
      f->actual_length = controlIn(data, f->buffer_length);
      completed_.push_back(u);
    } else if (f->endpoint == 0x01) {
      ++submitted_out;
      emulator_.receive(std::span<const std::uint8_t>(data, static_cast<std::size_t>(f->buffer_length)));
      f->actual_length = f->buffer_length;
      completed_.push_back(u);
    } else if (f->endpoint == 0x81) {
      ++submitted_in;
      pending_in_.push_back(u);
    } else {
      release(u);
      umockdev_ioctl_client_complete(client, -1, EINVAL);
      return TRUE;
    }
    umockdev_ioctl_client_complete(client, 0, 0);
    return TRUE;
  }

  gboolean reap(UMockdevIoctlClient* client, UMockdevIoctlData* arg) {
    std::deque<Urb>* from = nullptr;
    if (!discarded_.empty()) {
      from = &discarded_;
    } else if (!completed_.empty()) {
      from = &completed_;
    } else if (!pending_in_.empty()) {
      Urb& u = pending_in_.front();
      usbdevfs_urb* f = u.fields();
      const std::size_t n = emulator_.transmit(std::span<std::uint8_t>(reinterpret_cast<std::uint8_t*>(u.buffer->data),
                                                                       static_cast<std::size_t>(f->buffer_length)),
                                               std::chrono::nanoseconds(0));
      if (n > 0) {
        f->actual_length = static_cast<int>(n);
        from = &pending_in_;
      }
    }
    if (from == nullptr) {
      umockdev_ioctl_client_complete(client, -1, EAGAIN);
      return TRUE;
    }
    Urb u = from->front();
    from->pop_front();
    UMockdevIoctlData* out = umockdev_ioctl_data_resolve(arg, 0, sizeof(gpointer), nullptr);
    umockdev_ioctl_data_set_ptr(out, 0, u.urb);
    umockdev_ioctl_data_unref(out);
    umockdev_ioctl_client_complete(client, 0, 0);
    release(u);
    return TRUE;
  }

  // GET_DESCRIPTOR(STRING) on the default pipe: the setup packet is the first 8 bytes.
  int controlIn(std::uint8_t* data, int length) {
    const int w_value = data[2] | (data[3] << 8);
    const int w_length = data[6] | (data[7] << 8);
    if (data[0] != 0x80 || data[1] != 6 || (w_value >> 8) != 3) return 0;
    std::vector<std::uint8_t> d;
    const int index = w_value & 0xFF;
    if (index == 0) {
      d = {4, 3, 0x09, 0x04};  // en-US
    } else {
      const std::string text = index == 1 ? "mtcal" : index == 2 ? "MTCAL-LI1 (emulated)" : "EMU0001";
      d.push_back(static_cast<std::uint8_t>(2 + 2 * text.size()));
      d.push_back(3);
      for (char c : text) {
        d.push_back(static_cast<std::uint8_t>(c));
        d.push_back(0);
      }
    }
    const int n = std::min({static_cast<int>(d.size()), w_length, length - 8});
    std::memcpy(data + 8, d.data(), static_cast<std::size_t>(n));
    return n;
  }

  mocks::InterferometerEmulator& emulator_;
  std::deque<Urb> completed_, pending_in_, discarded_;
};

class UsbUmockdev : public ::testing::Test {
 protected:
  void SetUp() override {
    emulator_ = std::make_unique<mocks::InterferometerEmulator>(machine_, mocks::InterferometerEmulatorConfig{});
    model_ = std::make_unique<UsbDeviceModel>(*emulator_);
    testbed_ = umockdev_testbed_new();
    ASSERT_TRUE(umockdev_in_mock_environment()) << "run this test under umockdev-wrapper (LD_PRELOAD)";
    handler_ = umockdev_ioctl_base_new();
    g_signal_connect(handler_, "handle-ioctl", G_CALLBACK(UsbDeviceModel::onIoctl), model_.get());
    GError* error = nullptr;
    ASSERT_TRUE(umockdev_testbed_attach_ioctl(testbed_, kDeviceNode, handler_, &error)) << error->message;
    ASSERT_TRUE(umockdev_testbed_add_from_string(testbed_, kDeviceDescription, &error)) << error->message;
    drivers::registerBuiltInDrivers(registry_);
  }
  void TearDown() override {
    if (testbed_) umockdev_testbed_detach_ioctl(testbed_, kDeviceNode, nullptr);
    g_clear_object(&handler_);
    g_clear_object(&testbed_);
  }

  mocks::WorldClock clock_{1.0, mocks::WorldClock::Mode::kLockStep};  // the world runs as far as the test lets it
  mocks::VirtualMachine machine_{mocks::VirtualMachineConfig::demo(2), clock_};
  std::unique_ptr<mocks::InterferometerEmulator> emulator_;
  std::unique_ptr<UsbDeviceModel> model_;
  UMockdevTestbed* testbed_ = nullptr;
  UMockdevIoctlBase* handler_ = nullptr;
  drivers::Registry registry_;
};

TEST_F(UsbUmockdev, ScanFindsTheDeviceWithItsSerialThroughLibusb) {
  const auto found = registry_.scan();
  ASSERT_EQ(found.size(), 1u);
  EXPECT_EQ(found[0].uri, "usb://1209:c417/EMU0001");
  EXPECT_EQ(found[0].driver, "interferometer-usb");
  EXPECT_GT(model_->control_transfers, 0);
}

TEST_F(UsbUmockdev, OpensByUriAndTalksOverBulkTransfers) {
  auto device = registry_.openAs<ifm::InterferometerDevice>("usb://1209:c417/EMU0001");
  EXPECT_EQ(device->identity().serial, "EMU0001");
  EXPECT_EQ(device->identity().model, "MTCAL-LI1 (emulated)");
  EXPECT_GE(model_->submitted_out, 2);  // STOP_STREAM and IDENTIFY went out as bulk OUT URBs
  EXPECT_GE(model_->submitted_in, 1);
  const auto env = device->readEnvironment();
  EXPECT_NEAR(env.air_temp_c, machine_.config().air_temp_c, 0.05);
}

TEST_F(UsbUmockdev, StreamsSamplesOverBulkIn) {
  auto device = registry_.openAs<ifm::InterferometerDevice>("usb://1209:c417");
  struct Sink : drivers::SampleSink {
    std::mutex m;
    std::vector<drivers::Sample> s;
    void push(std::span<const drivers::Sample> x) override {
      std::lock_guard l(m);
      s.insert(s.end(), x.begin(), x.end());
    }
    std::size_t size() {
      std::lock_guard l(m);
      return s.size();
    }
  } sink;
  device->startStream(2000, sink);
  clock_.advanceTo(0.1995);  // samples every 0.5 ms from 0 to 199.5 ms
  for (int i = 0; i < 1000 && sink.size() < 400; ++i) std::this_thread::sleep_for(10ms);
  const auto stats = device->stopStream();
  ASSERT_EQ(sink.s.size(), 400u);
  EXPECT_EQ(stats.lost_samples, 0u);
  for (std::size_t i = 1; i < sink.s.size(); ++i) ASSERT_EQ(sink.s[i].seq, sink.s[i - 1].seq + 1);
}

TEST_F(UsbUmockdev, AWrongSerialOrAbsentDeviceIsATransportError) {
  try {
    registry_.open("usb://1209:c417/OTHER");
    FAIL();
  } catch (const TransportError& e) {
    EXPECT_NE(std::string(e.what()).find("serial OTHER"), std::string::npos) << e.what();
  }
  umockdev_testbed_remove_device(testbed_, "/sys/devices/pci0000:00/0000:00:14.0/usb1/1-2");
  EXPECT_THROW(registry_.open("usb://1209:c417"), TransportError);
}

}  // namespace
}  // namespace mtcal
