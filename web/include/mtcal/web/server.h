#pragma once
// `mtcal serve`: the archive as a web dashboard, over HTTP/1.1 (Boost.Beast), from one thread.
// docs/dashboard.md.

#include <atomic>
#include <chrono>
#include <cstdint>
#include <memory>
#include <string>

namespace mtcal::web {

struct ServerOptions {
  std::string db_path = "mtcal.sqlite";
  std::string bind = "127.0.0.1";
  std::uint16_t port = 8600;  ///< 0: any free port (port() tells which)
  bool read_only = false;     ///< the archive is opened read-only; nothing changes state
  /// On the plant archive (db_path an address): how often its copy is brought up to date
  /// while the server runs; 0: at start only.
  std::chrono::seconds plant_refresh{60};
  /// Required on every request when `bind` is not 127.0.0.1 or ::1 (empty: one is made and
  /// token() tells it): an Authorization: Bearer header, a cookie mtcal_token, or ?token= once
  /// (which sets the cookie).
  std::string token;
  std::size_t max_connections = 32;
  std::size_t max_request_bytes = 64 * 1024;
};

class Server {
 public:
  /// Opens the archive and binds. @throws InputError (a missing archive, an address in use)
  explicit Server(ServerOptions options);
  ~Server();
  Server(const Server&) = delete;
  Server& operator=(const Server&) = delete;

  std::uint16_t port() const;
  /// The token requests need; empty when the server is bound to loopback's 127.0.0.1 or ::1.
  const std::string& token() const;
  /// Serves until stop() or `stop_requested` (checked every 100 ms) is set.
  void run(const std::atomic<bool>* stop_requested = nullptr);
  /// From any thread.
  void stop();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace mtcal::web
