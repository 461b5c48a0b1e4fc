#include "mtcal/drivers/serial_transport.h"

#include <fmt/format.h>

#include <boost/asio/io_context.hpp>
#include <boost/asio/read.hpp>
#include <boost/asio/serial_port.hpp>
#include <boost/asio/write.hpp>

#include "asio_timed.h"
#include "mtcal/error.h"
#include "operation_gate.h"

namespace mtcal::drivers {
namespace asio = boost::asio;

// Timed operations by runTimed (asio_timed.h); one operation at a time through the gate.
struct SerialTransport::Impl {
  std::string path;
  unsigned baud = 0;
  asio::io_context io;
  asio::serial_port port{io};
  OperationGate gate;

  template <typename Start>
  std::size_t timed(Start start, milliseconds timeout, const char* what) {
    return runTimed(io, port, start, timeout, "serial " + path, what);
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
  if (ec)
    throw TransportError(fmt::format("serial {}: cannot configure {} baud 8N1: {}", path, baud_rate, ec.message()));
}

SerialTransport::~SerialTransport() {
  boost::system::error_code ignored;
  impl_->port.close(ignored);
}

std::size_t SerialTransport::read(std::span<std::uint8_t> buffer, milliseconds timeout) {
  const OperationGate::Turn turn(impl_->gate, OperationGate::Kind::kRead);
  return impl_->timed(
      [&](auto handler) { impl_->port.async_read_some(asio::buffer(buffer.data(), buffer.size()), handler); }, timeout,
      "read");
}

void SerialTransport::write(std::span<const std::uint8_t> data, milliseconds timeout) {
  const OperationGate::Turn turn(impl_->gate, OperationGate::Kind::kOther);
  impl_->timed([&](auto handler) { asio::async_write(impl_->port, asio::buffer(data.data(), data.size()), handler); },
               timeout, "write");
}

std::string SerialTransport::describe() const { return fmt::format("serial://{}?baud={}", impl_->path, impl_->baud); }

}  // namespace mtcal::drivers
