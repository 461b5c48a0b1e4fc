#pragma once
// A real HTTP client (Boost.Beast) for the dashboard's server, and the server on a thread of
// its own for a test's life.

#include <boost/asio/connect.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>

#include "mtcal/web/server.h"

namespace mtcal::testing {

namespace beast = boost::beast;
namespace http = beast::http;
using tcp = boost::asio::ip::tcp;

struct Reply {
  unsigned status = 0;
  std::string body, content_type, location, set_cookie, allow, disposition;
  nlohmann::json json() const { return nlohmann::json::parse(body); }
};

inline Reply ask(const std::string& host, std::uint16_t port, http::verb method, const std::string& target,
                 const std::map<std::string, std::string>& headers = {}, const std::string& body = "") {
  boost::asio::io_context io;
  tcp::resolver resolver(io);
  beast::tcp_stream stream(io);
  stream.connect(resolver.resolve(host, std::to_string(port)));
  http::request<http::string_body> req(method, target, 11);
  req.set(http::field::host, host);
  for (const auto& [k, v] : headers) req.set(k, v);
  req.body() = body;
  req.prepare_payload();
  http::write(stream, req);
  beast::flat_buffer buffer;
  http::response<http::string_body> res;
  beast::error_code ec;
  http::read(stream, buffer, res, ec);
  beast::error_code ignored;
  stream.socket().shutdown(tcp::socket::shutdown_both, ignored);
  return {res.result_int(),
          res.body(),
          std::string(res[http::field::content_type]),
          std::string(res[http::field::location]),
          std::string(res[http::field::set_cookie]),
          std::string(res[http::field::allow]),
          std::string(res[http::field::content_disposition])};
}

/// A server on its own thread for the test's life.
class Running {
 public:
  explicit Running(web::ServerOptions o) : server_(std::move(o)), thread_([this] { server_.run(); }) {}
  ~Running() {
    server_.stop();
    thread_.join();
  }
  web::Server& server() { return server_; }

 private:
  web::Server server_;
  std::thread thread_;
};

}  // namespace mtcal::testing
