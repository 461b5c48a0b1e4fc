#include "mtcal/drivers/serial_transport.h"

#include <fmt/format.h>

#include <boost/asio/io_context.hpp>
#include <boost/asio/read.hpp>
#include <boost/asio/serial_port.hpp>
#include <boost/asio/write.hpp>
#include <mutex>

#include "mtcal/error.h"

namespace mtcal::drivers {
namespace asio = boost::asio;

// A timed operation is an async operation on the port's io_context run for at most the
// timeout, then cancelled (Asio's way to put a deadline on a serial transfer, which has no
// socket timeout option). One operation at a time: the io_context is run by the caller.
struct SerialTransport::Impl {
  std::string path;
  unsigned baud = 0;
  asio::io_context io;
  asio::serial_port port{io};
  std::mutex mutex;

  /// Runs `start` (which begins one async operation on the port) until it completes or the
  /// timeout passes. @return bytes transferred. @throws TimeoutError, TransportError
  template <typename Start>
  std::size_t timed(Start start, milliseconds timeout, const char* what) {
    boost::system::error_code result = asio::error::would_block;
    std::size_t transferred = 0;
    start([&](const boost::system::error_code& ec, std::size_t n) {
      result = ec;
      transferred = n;
    });
    io.restart();
    io.run_for(timeout);
    if (result == asio::error::would_block) {
      port.cancel();
      io.restart();
      io.run();  // let the cancelled handler run
      throw TimeoutError(fmt::format("serial {}: {} timed out after {} ms", path, what, timeout.count()));
    }
    if (result) throw TransportError(fmt::format("serial {}: {} failed: {}", path, what, result.message()));
    return transferred;
  }
};

SerialTransport::SerialTransport(const std::string& path, unsigned baud_rate) : impl_(std::make_unique<Impl>()) {
  impl_->path = path;
  impl_->baud = baud_rate;
  boost::system::error_code ec;
  impl_->port.open(path, ec);
  if (ec) throw TransportError(fmt::format("serial {}: cannot open: {}", path, ec.message()));
  using sp = asio::serial_port_base;
  impl_->port.set_option(sp::baud_rate(baud_rate), ec);
  if (!ec) impl_->port.set_option(sp::character_size(8), ec);
  if (!ec) impl_->port.set_option(sp::parity(sp::parity::none), ec);
  if (!ec) impl_->port.set_option(sp::stop_bits(sp::stop_bits::one), ec);
  if (!ec) impl_->port.set_option(sp::flow_control(sp::flow_control::none), ec);
  if (ec) throw TransportError(fmt::format("serial {}: cannot configure {} baud 8N1: {}", path, baud_rate, ec.message()));
}

SerialTransport::~SerialTransport() {
  boost::system::error_code ignored;
  impl_->port.close(ignored);
}

std::size_t SerialTransport::read(std::span<std::uint8_t> buffer, milliseconds timeout) {
  std::lock_guard lock(impl_->mutex);
  return impl_->timed(
      [&](auto handler) { impl_->port.async_read_some(asio::buffer(buffer.data(), buffer.size()), handler); }, timeout,
      "read");
}

void SerialTransport::write(std::span<const std::uint8_t> data, milliseconds timeout) {
  std::lock_guard lock(impl_->mutex);
  impl_->timed([&](auto handler) { asio::async_write(impl_->port, asio::buffer(data.data(), data.size()), handler); },
               timeout, "write");
}

std::string SerialTransport::describe() const { return fmt::format("serial://{}?baud={}", impl_->path, impl_->baud); }

}  // namespace mtcal::drivers
