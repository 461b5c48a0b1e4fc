#pragma once
// TCP transport on Boost.Asio: connect, read and write each with a deadline (asynchronous
// operations run for at most their timeout, then cancelled), reconnect after the link
// broke. Asio codes become TransportError / TimeoutError here. For instruments on a
// network (the laser tracker); tests use servers on 127.0.0.1.
//
// Thread-safety: any threads may call it; one operation runs at a time, so a write waits
// for a pending read, at most its timeout (no read begins while it waits).

#include <cstdint>
#include <memory>
#include <string>

#include "mtcal/drivers/transport.h"

namespace mtcal::drivers {

class TcpTransport final : public Transport {
 public:
  /// Connects to host:port within `connect_timeout`.
  /// @throws TransportError naming host:port and why (refused, unreachable), TimeoutError
  TcpTransport(std::string host, std::uint16_t port, milliseconds connect_timeout = milliseconds(3000));
  ~TcpTransport() override;

  std::size_t read(std::span<std::uint8_t> buffer, milliseconds timeout) override;
  void write(std::span<const std::uint8_t> data, milliseconds timeout) override;
  std::string describe() const override;

  /// Closes the connection (whatever state it is in) and connects again.
  /// @throws TransportError, TimeoutError
  void reconnect(milliseconds connect_timeout = milliseconds(3000));
  /// Whether the last operation left the connection usable (false after the peer closed it
  /// or an I/O error; a timeout leaves it connected).
  bool connected() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace mtcal::drivers
