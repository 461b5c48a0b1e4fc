#include "mtcal/drivers/tcp_transport.h"

#include <fmt/format.h>

#include <atomic>
#include <boost/asio/connect.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/read.hpp>
#include <boost/asio/write.hpp>

#include "asio_timed.h"
#include "mtcal/error.h"
#include "operation_gate.h"

namespace mtcal::drivers {
namespace asio = boost::asio;
using asio::ip::tcp;

struct TcpTransport::Impl {
  std::string host;
  std::uint16_t port = 0;
  asio::io_context io;
  tcp::socket socket{io};
  tcp::resolver resolver{io};
  std::atomic<bool> connected{false};  // read without a turn: a status, not an operation
  OperationGate gate;

  std::string name() const { return fmt::format("tcp://{}:{}", host, port); }

  void connect(milliseconds timeout) {
    boost::system::error_code ec;
    const auto endpoints = resolver.resolve(host, std::to_string(port), ec);
    if (ec) throw TransportError(fmt::format("{}: cannot resolve {}: {}", name(), host, ec.message()));
    socket.close(ec);
    runTimed(
        io, socket,
        [&](auto handler) {
          asio::async_connect(socket, endpoints,
                              [handler](const boost::system::error_code& e, const tcp::endpoint&) { handler(e, 0); });
        },
        timeout, name(), "connect");
    socket.set_option(tcp::no_delay(true), ec);
    connected = true;
  }

  // Runs an operation; an I/O failure other than a timeout marks the link broken.
  template <typename Start>
  std::size_t timed(Start start, milliseconds timeout, const char* what) {
    if (!connected) throw TransportError(fmt::format("{}: {}: not connected (reconnect first)", name(), what));
    try {
      return runTimed(io, socket, start, timeout, name(), what);
    } catch (const TimeoutError&) {
      throw;
    } catch (const TransportError&) {
      connected = false;
      throw;
    }
  }
};

TcpTransport::TcpTransport(std::string host, std::uint16_t port, milliseconds connect_timeout)
    : impl_(std::make_unique<Impl>()) {
  impl_->host = std::move(host);
  impl_->port = port;
  impl_->connect(connect_timeout);
}

TcpTransport::~TcpTransport() {
  boost::system::error_code ignored;
  impl_->socket.shutdown(tcp::socket::shutdown_both, ignored);
  impl_->socket.close(ignored);
}

std::size_t TcpTransport::read(std::span<std::uint8_t> buffer, milliseconds timeout) {
  const OperationGate::Turn turn(impl_->gate, OperationGate::Kind::kRead);
  return impl_->timed(
      [&](auto handler) { impl_->socket.async_read_some(asio::buffer(buffer.data(), buffer.size()), handler); },
      timeout, "read");
}

void TcpTransport::write(std::span<const std::uint8_t> data, milliseconds timeout) {
  const OperationGate::Turn turn(impl_->gate, OperationGate::Kind::kOther);
  impl_->timed([&](auto handler) { asio::async_write(impl_->socket, asio::buffer(data.data(), data.size()), handler); },
               timeout, "write");
}

void TcpTransport::reconnect(milliseconds connect_timeout) {
  const OperationGate::Turn turn(impl_->gate, OperationGate::Kind::kOther);
  impl_->connected = false;
  impl_->connect(connect_timeout);
}

bool TcpTransport::connected() const { return impl_->connected; }

std::string TcpTransport::describe() const { return impl_->name(); }

}  // namespace mtcal::drivers
