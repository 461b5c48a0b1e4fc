#pragma once
// A deadline on an Asio operation (serial ports and sockets have no timeout option of their
// own): the async operation runs on the transport's io_context for at most the timeout, then
// the I/O object is cancelled and the cancelled handler allowed to run. One operation at a
// time: the caller runs the io_context and serialises calls.

#include <fmt/format.h>

#include <boost/asio/error.hpp>
#include <boost/asio/io_context.hpp>
#include <string>

#include "mtcal/drivers/transport.h"
#include "mtcal/error.h"

namespace mtcal::drivers {

/// Runs `start(handler)`, which begins one async operation on `object`, until it completes or
/// `timeout` passes. @return bytes transferred (what the handler got).
/// @throws TimeoutError "<name>: <what> timed out after N ms"; TransportError with Asio's message
template <typename IoObject, typename Start>
std::size_t runTimed(boost::asio::io_context& io, IoObject& object, Start start, milliseconds timeout,
                     const std::string& name, const char* what) {
  boost::system::error_code result = boost::asio::error::would_block;
  std::size_t transferred = 0;
  start([&](const boost::system::error_code& ec, std::size_t n) {
    result = ec;
    transferred = n;
  });
  io.restart();
  io.run_for(timeout);
  if (result == boost::asio::error::would_block) {
    boost::system::error_code ignored;
    object.cancel(ignored);
    io.restart();
    io.run();  // let the cancelled handler run
    throw TimeoutError(fmt::format("{}: {} timed out after {} ms", name, what, timeout.count()));
  }
  if (result == boost::asio::error::eof || result == boost::asio::error::connection_reset) {
    throw TransportError(fmt::format("{}: {} failed: the peer closed the connection", name, what));
  }
  if (result) throw TransportError(fmt::format("{}: {} failed: {}", name, what, result.message()));
  return transferred;
}

}  // namespace mtcal::drivers
