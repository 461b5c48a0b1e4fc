// The real hidapi (hidraw backend) code path of the ballbar driver against a hidraw node
// emulated by umockdev: enumeration through udev/sysfs (VID:PID, serial and product from the
// HID device's uevent), hid_open_path (HIDIOCGRDESCSIZE), feature reports (HIDIOCSFEATURE /
// HIDIOCGFEATURE ioctls) and input reports (read()), all answered by our device emulator.
// The test runs under umockdev-wrapper (umockdev's documentation: umockdev-wrapper(1) and the
// UMockdevIoctlBase class, https://github.com/martinpitt/umockdev).
//
// Two things umockdev 0.17 does not do, supplied here:
// - real sysfs has hidraw0/device -> the hid device; hidapi reads VID:PID through it when
//   enumerating with a filter. The test bed gets that link.
// - umockdev's preload library does not intercept poll(), and hid_read_timeout() polls the
//   node before reading it. This executable defines poll() (it takes precedence over libc's
//   for hidapi) and answers it for the emulated node from the emulator's input queue; every
//   other poll() goes to libc. open()/close() are wrapped only to learn which descriptor
//   is the node.

#include <dlfcn.h>
#include <fcntl.h>
#include <gtest/gtest.h>
#include <linux/hidraw.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <umockdev.h>
#include <unistd.h>

#include <atomic>
#include <cstdarg>
#include <cstring>
#include <mutex>
#include <thread>

#include "mtcal/drivers/ballbar/driver.h"
#include "mtcal/drivers/hid_transport.h"
#include "mtcal/drivers/registry.h"
#include "mtcal/error.h"
#include "mtcal/mocks/ballbar_emulator.h"

namespace {

std::atomic<int> g_node_fd{-1};
mtcal::mocks::BallbarEmulator* g_device = nullptr;  // set while a test runs

template <typename F>
F next(const char* name) {
  return reinterpret_cast<F>(dlsym(RTLD_NEXT, name));
}

}  // namespace

extern "C" {

int open(const char* path, int flags, ...) {  // NOLINT: interposes libc's open
  mode_t mode = 0;
  if (flags & (O_CREAT | O_TMPFILE)) {
    va_list ap;
    va_start(ap, flags);
    mode = va_arg(ap, mode_t);
    va_end(ap);
  }
  static auto real = next<int (*)(const char*, int, ...)>("open");
  const int fd = real(path, flags, mode);
  if (fd >= 0 && std::strncmp(path, "/dev/hidraw", 11) == 0) g_node_fd = fd;
  return fd;
}

int close(int fd) {  // NOLINT: interposes libc's close
  static auto real = next<int (*)(int)>("close");
  if (fd == g_node_fd) g_node_fd = -1;
  return real(fd);
}

int poll(struct pollfd* fds, nfds_t n, int timeout_ms) {  // NOLINT: interposes libc's poll
  static auto real = next<int (*)(struct pollfd*, nfds_t, int)>("poll");
  if (n == 1 && fds[0].fd >= 0 && fds[0].fd == g_node_fd && g_device != nullptr) {
    const auto wait = timeout_ms < 0 ? std::chrono::hours(1) : std::chrono::milliseconds(timeout_ms);
    try {
      fds[0].revents = g_device->waitInput(wait) ? POLLIN : 0;
    } catch (const mtcal::TransportError&) {
      fds[0].revents = POLLERR | POLLHUP;  // unplugged
    }
    return fds[0].revents != 0 ? 1 : 0;
  }
  return real(fds, n, timeout_ms);
}

}  // extern "C"

namespace mtcal {
namespace {

using namespace std::chrono_literals;
namespace bb = drivers::ballbar;

constexpr const char* kHidPath = "/devices/pci0000:00/0000:00:14.0/usb1/1-3/1-3:1.0/0003:1209:C418.0001";
// The USB device, its interface, the HID device (uevent: HID_ID bus:vendor:product, name,
// serial) and its hidraw node. The report descriptor: vendor page 0xFF00, input report 1 of
// 63 bytes, feature reports 0x10..0x14 of 31 bytes.
constexpr const char* kDeviceDescription =
    "P: /devices/pci0000:00/0000:00:14.0/usb1/1-3\n"
    "N: bus/usb/001/003\n"
    "E: SUBSYSTEM=usb\n"
    "E: DEVTYPE=usb_device\n"
    "E: BUSNUM=001\n"
    "E: DEVNUM=003\n"
    "A: idVendor=1209\\n\n"
    "A: idProduct=c418\\n\n"
    "A: manufacturer=mtcal\\n\n"
    "A: product=MTCAL-BB ballbar (emulated)\\n\n"
    "A: serial=BB0001\\n\n"
    "A: bcdDevice=0120\\n\n"
    "\n"
    "P: /devices/pci0000:00/0000:00:14.0/usb1/1-3/1-3:1.0\n"
    "E: SUBSYSTEM=usb\n"
    "E: DEVTYPE=usb_interface\n"
    "A: bInterfaceNumber=00\\n\n"
    "\n"
    "P: /devices/pci0000:00/0000:00:14.0/usb1/1-3/1-3:1.0/0003:1209:C418.0001\n"
    "E: SUBSYSTEM=hid\n"
    "E: HID_ID=0003:00001209:0000C418\n"
    "E: HID_NAME=mtcal MTCAL-BB ballbar (emulated)\n"
    "E: HID_UNIQ=BB0001\n"
    "E: HID_PHYS=usb-0000:00:14.0-3/input0\n"
    "\n"
    "P: /devices/pci0000:00/0000:00:14.0/usb1/1-3/1-3:1.0/0003:1209:C418.0001/hidraw/hidraw0\n"
    "N: hidraw0\n"
    "E: SUBSYSTEM=hidraw\n"
    "E: DEVNAME=/dev/hidraw0\n";
constexpr const char* kNode = "/dev/hidraw0";
const std::vector<std::uint8_t> kReportDescriptor{
    0x06, 0x00, 0xFF,                                // usage page (vendor 0xFF00)
    0x09, 0x01,                                      // usage 1
    0xA1, 0x01,                                      // collection (application)
    0x15, 0x00, 0x26, 0xFF, 0x00, 0x75, 0x08,        // logical 0..255, 8 bits
    0x85, 0x01, 0x95, 0x3F, 0x09, 0x01, 0x81, 0x02,  // report 1: 63 bytes input
    0x85, 0x10, 0x95, 0x1F, 0x09, 0x02, 0xB1, 0x02,  // report 0x10: 31 bytes feature (one shown)
    0xC0};

// The hidraw node as seen by hidapi, backed by the emulator. Runs on umockdev's thread.
class HidrawModel {
 public:
  explicit HidrawModel(mocks::BallbarEmulator& device) : device_(device) {}
  static gboolean onIoctl(UMockdevIoctlBase*, UMockdevIoctlClient* client, gpointer self) {
    return static_cast<HidrawModel*>(self)->ioctl(client);
  }
  static gboolean onRead(UMockdevIoctlBase*, UMockdevIoctlClient* client, gpointer self) {
    return static_cast<HidrawModel*>(self)->read(client);
  }
  std::atomic<int> feature_sets{0}, feature_gets{0}, reads{0}, descriptor_reads{0};

 private:
  gboolean ioctl(UMockdevIoctlClient* client) {
    const gulong request = umockdev_ioctl_client_get_request(client);
    UMockdevIoctlData* arg = umockdev_ioctl_client_get_arg(client);
    if (request == HIDIOCGRDESCSIZE) {
      UMockdevIoctlData* size = umockdev_ioctl_data_resolve(arg, 0, sizeof(int), nullptr);
      *reinterpret_cast<int*>(size->data) = static_cast<int>(kReportDescriptor.size());
      g_object_unref(size);
      ++descriptor_reads;
      umockdev_ioctl_client_complete(client, 0, 0);
      return TRUE;
    }
    if (request == HIDIOCGRDESC) {
      UMockdevIoctlData* d = umockdev_ioctl_data_resolve(arg, 0, sizeof(hidraw_report_descriptor), nullptr);
      auto* desc = reinterpret_cast<hidraw_report_descriptor*>(d->data);
      desc->size = static_cast<__u32>(kReportDescriptor.size());
      std::memcpy(desc->value, kReportDescriptor.data(), kReportDescriptor.size());
      g_object_unref(d);
      umockdev_ioctl_client_complete(client, 0, 0);
      return TRUE;
    }
    // HIDIOCSFEATURE(len) / HIDIOCGFEATURE(len): the length is in the request's size field.
    const auto type = _IOC_TYPE(request), nr = _IOC_NR(request);
    const auto len = static_cast<gsize>(_IOC_SIZE(request));
    if (type == 'H' && (nr == 0x06 || nr == 0x07)) {
      UMockdevIoctlData* buffer = umockdev_ioctl_data_resolve(arg, 0, len, nullptr);
      auto* bytes = reinterpret_cast<std::uint8_t*>(buffer->data);
      long result = -1;
      int error = 0;
      try {
        if (nr == 0x06) {
          device_.setFeature({bytes, len});
          ++feature_sets;
          result = static_cast<long>(len);
        } else {
          result = static_cast<long>(device_.getFeature({bytes, len}));
          ++feature_gets;
        }
      } catch (const Error&) {
        error = EPIPE;  // what hidraw answers when the device stalls the request
      }
      g_object_unref(buffer);
      umockdev_ioctl_client_complete(client, error ? -1 : result, error);
      return TRUE;
    }
    return FALSE;
  }

  gboolean read(UMockdevIoctlClient* client) {
    UMockdevIoctlData* arg = umockdev_ioctl_client_get_arg(client);
    std::size_t n = 0;
    int error = 0;
    try {
      n = device_.readInput({reinterpret_cast<std::uint8_t*>(arg->data), static_cast<std::size_t>(arg->data_len)},
                            std::chrono::nanoseconds(0));
      if (n == 0) error = EAGAIN;
    } catch (const TransportError&) {
      error = ENODEV;
    }
    ++reads;
    umockdev_ioctl_client_complete(client, error ? -1 : static_cast<long>(n), error);
    return TRUE;
  }

  mocks::BallbarEmulator& device_;
};

class HidUmockdev : public ::testing::Test {
 protected:
  void SetUp() override {
    mocks::BallbarEmulatorConfig config;
    config.noise_um = 0.0;
    device_ = std::make_shared<mocks::BallbarEmulator>(machine_, config);
    g_device = device_.get();
    model_ = std::make_unique<HidrawModel>(*device_);
    testbed_ = umockdev_testbed_new();
    ASSERT_TRUE(umockdev_in_mock_environment()) << "run this test under umockdev-wrapper (LD_PRELOAD)";
    handler_ = umockdev_ioctl_base_new();
    g_signal_connect(handler_, "handle-ioctl", G_CALLBACK(HidrawModel::onIoctl), model_.get());
    g_signal_connect(handler_, "handle-read", G_CALLBACK(HidrawModel::onRead), model_.get());
    GError* error = nullptr;
    ASSERT_TRUE(umockdev_testbed_attach_ioctl(testbed_, kNode, handler_, &error)) << error->message;
    ASSERT_TRUE(umockdev_testbed_add_from_string(testbed_, kDeviceDescription, &error)) << error->message;
    gchar* sys = umockdev_testbed_get_sys_dir(testbed_);
    const std::string link = std::string(sys) + kHidPath + "/hidraw/hidraw0/device";
    g_free(sys);
    ASSERT_EQ(symlink("../../../0003:1209:C418.0001", link.c_str()), 0) << link;
    drivers::registerBuiltInDrivers(registry_);
  }
  void TearDown() override {
    g_device = nullptr;
    if (testbed_) umockdev_testbed_detach_ioctl(testbed_, kNode, nullptr);
    g_clear_object(&handler_);
    g_clear_object(&testbed_);
  }

  mocks::WorldClock clock_{1.0, mocks::WorldClock::Mode::kLockStep};  // the world runs as far as the test lets it
  mocks::VirtualMachine machine_{mocks::VirtualMachineConfig::demo(2), clock_};
  std::shared_ptr<mocks::BallbarEmulator> device_;
  std::unique_ptr<HidrawModel> model_;
  UMockdevTestbed* testbed_ = nullptr;
  UMockdevIoctlBase* handler_ = nullptr;
  drivers::Registry registry_;
};

TEST_F(HidUmockdev, HidapiEnumeratesTheBarWithItsSerialAndTheRegistryScansIt) {
  const auto found = drivers::enumerateHid(bb::kUsbVendorId, bb::kUsbProductId);
  ASSERT_EQ(found.size(), 1u);
  EXPECT_EQ(found[0].path, "/dev/hidraw0");
  EXPECT_EQ(found[0].serial, "BB0001");
  EXPECT_EQ(found[0].product, "MTCAL-BB ballbar (emulated)");
  EXPECT_TRUE(drivers::enumerateHid(0x1209, 0xc417).empty());  // the interferometer's PID: not this
  const auto scanned = registry_.scan();
  ASSERT_EQ(scanned.size(), 1u);
  EXPECT_EQ(scanned[0].uri, "hid://1209:c418/BB0001");
  EXPECT_EQ(scanned[0].driver, "ballbar-hid");
}

TEST_F(HidUmockdev, TheDriverTalksFeatureAndInputReportsThroughHidapi) {
  auto bar = registry_.openAs<bb::BallbarDevice>("hid://1209:c418/BB0001");
  EXPECT_GT(model_->descriptor_reads.load(), 0);
  EXPECT_EQ(bar->identity().serial, "BB0001");
  bar->zero(100.0);
  EXPECT_DOUBLE_EQ(bar->status().reference_length_mm, 100.0);
  class Collect : public drivers::SampleSink {
   public:
    void push(std::span<const drivers::Sample> s) override {
      std::lock_guard lock(mutex);
      samples.insert(samples.end(), s.begin(), s.end());
    }
    std::size_t size() {
      std::lock_guard lock(mutex);
      return samples.size();
    }
    std::mutex mutex;
    std::vector<drivers::Sample> samples;
  } sink;
  bar->startStream(1000, sink);
  clock_.advanceTo(0.199);  // samples at 0, 1, ... 199 ms
  const auto deadline = std::chrono::steady_clock::now() + 10s;
  while (sink.size() < 200 && std::chrono::steady_clock::now() < deadline) std::this_thread::sleep_for(5ms);
  const auto stats = bar->stopStream();
  ASSERT_EQ(sink.size(), 200u);
  EXPECT_EQ(stats.lost_samples, 0u);
  EXPECT_EQ(stats.crc_errors, 0u);
  for (std::size_t i = 1; i < sink.samples.size(); ++i) ASSERT_EQ(sink.samples[i].seq, sink.samples[i - 1].seq + 1);
  for (const auto& s : sink.samples) EXPECT_NEAR(s.value, 0.0, 1e-7);  // zeroed in its calibrator, no noise
  EXPECT_GE(model_->reads.load(), 20);
  EXPECT_GE(model_->feature_sets.load(), 4);  // zero, rate, start, stop
}

TEST_F(HidUmockdev, AFeatureTheDeviceStallsIsATransportErrorNamingTheReport) {
  drivers::HidapiTransport transport(bb::kUsbVendorId, bb::kUsbProductId, std::string("BB0001"));
  std::vector<std::uint8_t> unknown(bb::kFeatureReportSize, 0);
  unknown[0] = 0x42;
  try {
    transport.setFeature(unknown);
    FAIL() << "an unknown feature report must fail";
  } catch (const TransportError& e) {
    EXPECT_NE(std::string(e.what()).find("0x42"), std::string::npos) << e.what();
  }
  EXPECT_THROW(drivers::HidapiTransport(bb::kUsbVendorId, bb::kUsbProductId, std::string("OTHER")), TransportError);
}

}  // namespace
}  // namespace mtcal
