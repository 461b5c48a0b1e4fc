#include "mtcal/web/server.h"

#include <fmt/format.h>

#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <chrono>
#include <fstream>
#include <random>

#include "api.h"
#include "mtcal/error.h"

namespace mtcal::web {
namespace {

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace http = beast::http;
using tcp = asio::ip::tcp;

constexpr auto kIdleTimeout = std::chrono::seconds(30);

/// 32 hex digits from the system's random device.
std::string newToken() {
  std::random_device random;
  std::string token;
  for (int i = 0; i < 4; ++i) token += fmt::format("{:08x}", random());
  return token;
}

/// The value of cookie `name` in a Cookie header.
std::string cookie(std::string_view header, std::string_view name) {
  std::size_t at = 0;
  while (at < header.size()) {
    const auto end = std::min(header.find(';', at), header.size());
    auto pair = header.substr(at, end - at);
    while (!pair.empty() && pair.front() == ' ') pair.remove_prefix(1);
    if (pair.starts_with(name) && pair.size() > name.size() && pair[name.size()] == '=')
      return std::string(pair.substr(name.size() + 1));
    at = end + 1;
  }
  return "";
}

/// Compares without leaking how much of a guess was right through the time it takes.
bool sameToken(const std::string& given, const std::string& token) {
  if (given.size() != token.size()) return false;
  unsigned char difference = 0;
  for (std::size_t i = 0; i < token.size(); ++i) difference |= static_cast<unsigned char>(given[i] ^ token[i]);
  return difference == 0;
}

}  // namespace

struct Server::Impl {
  ServerOptions options;
  services::Session session;
  std::size_t connections = 0;  ///< before io: the connections io still holds end before it
  asio::io_context io{1};
  tcp::acceptor acceptor{io};
  asio::steady_timer stop_timer{io};

  explicit Impl(ServerOptions o) : options(std::move(o)), session(sessionOptions(options)) {}

  static services::SessionOptions sessionOptions(const ServerOptions& o) {
    services::SessionOptions s;
    s.db_path = o.db_path;
    s.read_only = o.read_only;
    return s;
  }

  /// The response to one parsed request, the token rule applied first.
  Response respond(const http::request<http::string_body>& req) {
    Request request{std::string(req.method_string()), std::string(req.target())};
    if (!options.token.empty()) {
      std::string given;
      const std::string auth(req[http::field::authorization]);
      if (auth.starts_with("Bearer ")) given = auth.substr(7);
      if (given.empty()) given = cookie(std::string(req[http::field::cookie]), "mtcal_token");
      const auto query = queryOf(request.target);
      const auto in_query = query.find("token");
      if (given.empty() && in_query != query.end()) {
        if (!sameToken(in_query->second, options.token)) return errorResponse(403, "wrong token");
        // Once in the address, then a cookie only this site sends: the address can be shared
        // without it. The page is asked again without the token.
        Response r{303, "text/plain", "", {}};
        r.headers["Set-Cookie"] = "mtcal_token=" + options.token + "; HttpOnly; SameSite=Strict; Path=/";
        std::string rest;
        for (const auto& [k, v] : query) {
          if (k != "token") rest += (rest.empty() ? "?" : "&") + k + "=" + v;
        }
        r.headers["Location"] = pathOf(request.target) + rest;
        return r;
      }
      if (!sameToken(given, options.token))
        return errorResponse(403, "this dashboard needs its token (printed when it started): ?token=... once");
    }
    return answer(session, request, options.read_only);
  }

  void accept() {
    acceptor.async_accept([this](beast::error_code ec, tcp::socket socket) {
      if (ec) {
        if (ec != asio::error::operation_aborted) accept();
        return;
      }
      serve(std::move(socket));
      accept();
    });
  }

  /// One connection: requests answered in turn while the client keeps it alive.
  struct Connection : std::enable_shared_from_this<Connection> {
    Impl& server;
    beast::tcp_stream stream;
    beast::flat_buffer buffer;
    std::optional<http::request_parser<http::string_body>> parser;
    http::response<http::string_body> response;
    bool refuse = false;  ///< too many connections: answer 503 and close

    Connection(Impl& s, tcp::socket socket) : server(s), stream(std::move(socket)) {}
    ~Connection() { --server.connections; }

    void read() {
      parser.emplace();
      parser->header_limit(static_cast<std::uint32_t>(server.options.max_request_bytes));
      parser->body_limit(server.options.max_request_bytes);
      stream.expires_after(kIdleTimeout);
      http::async_read(stream, buffer, *parser,
                       [self = shared_from_this()](beast::error_code ec, std::size_t) { self->onRead(ec); });
    }

    void onRead(beast::error_code ec) {
      if (ec == http::error::end_of_stream || ec == beast::error::timeout || ec == asio::error::operation_aborted)
        return close();
      Response r;
      bool keep_alive = false;
      if (ec == http::error::body_limit || ec == http::error::header_limit) {
        r = errorResponse(413, fmt::format("a request of more than {} bytes", server.options.max_request_bytes));
      } else if (ec) {
        r = errorResponse(400, "not an HTTP request: " + ec.message());
      } else if (refuse) {
        r = errorResponse(503, fmt::format("more than {} connections", server.options.max_connections));
      } else {
        const auto& req = parser->get();
        keep_alive = req.keep_alive();
        r = server.respond(req);
        if (req.method() == http::verb::head) r.body.clear();
      }
      write(r, keep_alive, parser && !ec ? parser->get().version() : 11);
    }

    void write(const Response& r, bool keep_alive, unsigned version) {
      response = {};
      response.version(version);
      response.result(r.status);
      response.set(http::field::server, "mtcal");
      response.set(http::field::content_type, r.media_type);
      response.set(http::field::cache_control, "no-store");
      response.set("X-Content-Type-Options", "nosniff");
      response.set("X-Frame-Options", "SAMEORIGIN");
      response.set("Content-Security-Policy",
                   "default-src 'self'; style-src 'self' 'unsafe-inline'; img-src 'self' data:");
      for (const auto& [k, v] : r.headers) response.set(k, v);
      response.body() = r.body;
      response.keep_alive(keep_alive);
      response.prepare_payload();
      http::async_write(stream, response, [self = shared_from_this(), keep_alive](beast::error_code ec, std::size_t) {
        if (ec || !keep_alive) return self->close();
        self->read();
      });
    }

    void close() {
      beast::error_code ignored;
      stream.socket().shutdown(tcp::socket::shutdown_send, ignored);
    }
  };

  void serve(tcp::socket socket) {
    ++connections;
    auto c = std::make_shared<Connection>(*this, std::move(socket));
    c->refuse = connections > options.max_connections;
    c->read();
  }

  void watch(const std::atomic<bool>* stop_requested) {
    stop_timer.expires_after(std::chrono::milliseconds(100));
    stop_timer.async_wait([this, stop_requested](beast::error_code ec) {
      if (ec) return;
      if (stop_requested && stop_requested->load()) return io.stop();
      watch(stop_requested);
    });
  }
};

Server::Server(ServerOptions options) {
  const bool loopback = options.bind == "127.0.0.1" || options.bind == "::1";
  if (!loopback && options.token.empty()) options.token = newToken();
  if (loopback) options.token.clear();
  impl_ = std::make_unique<Impl>(std::move(options));
  auto& o = impl_->options;
  impl_->session.open();  // a missing archive is said now, not at the first request
  beast::error_code ec;
  const auto address = asio::ip::make_address(o.bind, ec);
  if (ec) throw InputError(fmt::format("--bind {}: not an IP address ({})", o.bind, ec.message()));
  const tcp::endpoint endpoint(address, o.port);
  auto& a = impl_->acceptor;
  a.open(endpoint.protocol(), ec);
  if (!ec) a.set_option(asio::socket_base::reuse_address(true), ec);
  if (!ec) a.bind(endpoint, ec);
  if (!ec) a.listen(asio::socket_base::max_listen_connections, ec);
  if (ec) throw InputError(fmt::format("cannot listen on {} port {}: {}", o.bind, o.port, ec.message()));
}

Server::~Server() = default;

std::uint16_t Server::port() const { return impl_->acceptor.local_endpoint().port(); }
const std::string& Server::token() const { return impl_->options.token; }

void Server::run(const std::atomic<bool>* stop_requested) {
  impl_->accept();
  impl_->watch(stop_requested);
  impl_->io.run();
}

void Server::stop() {
  asio::post(impl_->io, [this] { impl_->io.stop(); });
}

}  // namespace mtcal::web
