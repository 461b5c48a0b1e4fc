#include "mtcal/drivers/serial_transport.h"

#include <fcntl.h>
#include <gtest/gtest.h>
#include <pty.h>
#include <unistd.h>

#include <array>
#include <atomic>
#include <string>
#include <thread>

#include "mtcal/error.h"

namespace mtcal::drivers {
namespace {

// A reader thread takes the port again as soon as its read returns, as a device's stream
// reader does. A command's write must not wait behind read after read: once it waits, no read
// begins; it waits for the read in progress only. On a pseudo-terminal nobody writes to, every
// read times out after 200 ms. The reader counts the reads it begins after the write was asked
// for: the one it may begin before the write waits and the one the write then lets it begin,
// whatever the load (the write has a read's 200 ms to reach the port). A plain mutex let the
// reader take the port back for seconds on a virtual machine (240 to 500 reads of 20 ms): the
// probe box's STREAM OFF went unanswered.
TEST(SerialTransport, AWriteWaitsForTheReadInProgressOnly) {
  int master = -1, slave = -1;
  std::array<char, 256> name{};
  ASSERT_EQ(openpty(&master, &slave, name.data(), nullptr, nullptr), 0);
  SerialTransport port(name.data(), 115200);
  std::atomic<bool> asked{false}, written{false};
  std::atomic<int> reads_after_asked{0};
  constexpr int kGiveUp = 50;  // 10 s of reads: the write starved
  std::thread reader([&] {
    std::array<std::uint8_t, 64> buffer{};
    while (!written && reads_after_asked < kGiveUp) {
      if (asked) ++reads_after_asked;
      try {
        port.read(buffer, std::chrono::milliseconds(200));
      } catch (const TimeoutError&) {
      }
    }
  });
  std::this_thread::sleep_for(std::chrono::milliseconds(300));  // the reader loops first
  asked = true;
  const std::string command = "STREAM OFF\r\n";
  std::string failure;
  try {
    port.write({reinterpret_cast<const std::uint8_t*>(command.data()), command.size()},
               std::chrono::milliseconds(1000));
  } catch (const std::exception& e) {
    failure = e.what();
  }
  written = true;
  reader.join();
  ASSERT_EQ(failure, "");
  EXPECT_LE(reads_after_asked.load(), 2);
  // The bytes went out.
  std::array<char, 64> got{};
  EXPECT_EQ(::read(master, got.data(), got.size()), static_cast<ssize_t>(command.size()));
  EXPECT_EQ(std::string(got.data(), command.size()), command);
  close(master);
  close(slave);
}

}  // namespace
}  // namespace mtcal::drivers
