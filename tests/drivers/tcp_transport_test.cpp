// The TCP transport against scripted servers on 127.0.0.1 (real sockets, ephemeral ports).

#include "mtcal/drivers/tcp_transport.h"

#include <gtest/gtest-spi.h>
#include <gtest/gtest.h>

#include <string>
#include <thread>

#include "../support/scripted_tcp_server.h"
#include "mtcal/error.h"

namespace mtcal::drivers {
namespace {

using namespace std::chrono_literals;
using Server = mtcal::testing::ScriptedTcpServer;

std::span<const std::uint8_t> bytes(const std::string& s) {
  return {reinterpret_cast<const std::uint8_t*>(s.data()), s.size()};
}

std::string readAll(TcpTransport& t, std::size_t n) {
  std::string out;
  std::uint8_t buffer[256];
  while (out.size() < n) {
    const std::size_t got = t.read(std::span(buffer, sizeof buffer), 2000ms);
    out.append(reinterpret_cast<const char*>(buffer), got);
  }
  return out;
}

TEST(TcpTransport, TalksToAServerAndTimesOutWhenItIsSilent) {
  Server server({Server::accept(), Server::expect("*IDN?\r\n"), Server::send("IDN TRK1\r\n"), Server::silence(),
                 Server::send("late\r\n")});
  TcpTransport t("127.0.0.1", server.port());
  EXPECT_EQ(t.describe(), "tcp://127.0.0.1:" + std::to_string(server.port()));
  t.write(bytes("*IDN?\r\n"), 1000ms);
  EXPECT_EQ(readAll(t, 10), "IDN TRK1\r\n");
  std::uint8_t buffer[16];
  const auto before = std::chrono::steady_clock::now();
  EXPECT_THROW(t.read(std::span(buffer, sizeof buffer), 100ms), TimeoutError);
  EXPECT_GE(std::chrono::steady_clock::now() - before, 100ms);
  EXPECT_TRUE(t.connected());  // a timeout leaves the link up
  server.proceed();            // the server speaks again
  EXPECT_EQ(readAll(t, 6), "late\r\n");
}

TEST(TcpTransport, APeerThatClosesIsATransportErrorAndReconnectRestoresTheLink) {
  Server server({Server::accept(), Server::send("A"), Server::close(), Server::accept(), Server::expect("again"),
                 Server::send("B")});
  TcpTransport t("127.0.0.1", server.port());
  EXPECT_EQ(readAll(t, 1), "A");
  std::uint8_t buffer[4];
  try {
    t.read(std::span(buffer, sizeof buffer), 2000ms);
    FAIL() << "the server closed the connection";
  } catch (const TimeoutError&) {
    FAIL() << "a closed connection is not a timeout";
  } catch (const TransportError& e) {
    EXPECT_NE(std::string(e.what()).find("closed the connection"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(t.connected());
  EXPECT_THROW(t.write(bytes("x"), 100ms), TransportError);  // not until reconnected
  t.reconnect();
  EXPECT_TRUE(t.connected());
  t.write(bytes("again"), 1000ms);
  EXPECT_EQ(readAll(t, 1), "B");
}

TEST(TcpTransport, ARefusedConnectionNamesTheAddress) {
  std::uint16_t port = 0;
  {
    Server probe({});
    port = probe.port();
  }  // a port nobody listens on any more
  try {
    TcpTransport t("127.0.0.1", port, 1000ms);
    FAIL() << "nobody listens";
  } catch (const TransportError& e) {
    EXPECT_NE(std::string(e.what()).find("tcp://127.0.0.1:" + std::to_string(port)), std::string::npos) << e.what();
  }
}

TEST(ScriptedTcpServer, FailsTheTestWhenAStepNeverRan) {
  EXPECT_NONFATAL_FAILURE({ Server unused({Server::accept(), Server::expect("hello")}); }, "never ran");
  EXPECT_NONFATAL_FAILURE(
      {
        Server server({Server::accept(), Server::expect("hello")});
        TcpTransport t("127.0.0.1", server.port());
        t.write(bytes("howdy"), 1000ms);
        while (!server.finished()) std::this_thread::sleep_for(1ms);  // it has read and judged the bytes
      },
      "expected 'hello', got 'howdy'");
}

}  // namespace
}  // namespace mtcal::drivers
