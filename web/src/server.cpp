#include "mtcal/web/server.h"

#include <fmt/format.h>

#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>
#include <chrono>
#include <deque>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>
#include <regex>

#include "api.h"
#include "jobs.h"
#include "mtcal/error.h"
#include "mtcal/services/archive.h"
#include "mtcal/services/plant.h"

namespace mtcal::web {
namespace {

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace http = beast::http;
using tcp = asio::ip::tcp;

namespace websocket = beast::websocket;

constexpr auto kIdleTimeout = std::chrono::seconds(30);
/// How often a live page's run is looked at in the archive (a recording in any process
/// commits its captures there).
constexpr auto kLivePoll = std::chrono::milliseconds(250);

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

  /// The plans the dashboard runs (none when read-only); before the io: its jobs end first.
  std::unique_ptr<Jobs> jobs;
  /// On the plant archive: keeps the copy the session reads up to date.
  std::unique_ptr<services::PlantMirrorRefresher> plant_refresher;

  explicit Impl(ServerOptions o)
      : options(plantReadOnly(std::move(o))),
        session(sessionOptions(options)),
        jobs(options.read_only ? nullptr : std::make_unique<Jobs>(options.db_path)) {}

  /// After the session opened the copy (brought up to date at start).
  void refreshPlantCopy() {
    if (services::isPlantAddress(options.db_path) && options.plant_refresh.count() > 0)
      plant_refresher = std::make_unique<services::PlantMirrorRefresher>(options.db_path, options.plant_refresh);
  }

  /// The plant archive is only read: no plans are run into it.
  static ServerOptions plantReadOnly(ServerOptions o) {
    o.read_only = o.read_only || services::isPlantAddress(o.db_path);
    return o;
  }

  static services::SessionOptions sessionOptions(const ServerOptions& o) {
    services::SessionOptions s;
    s.db_path = o.db_path;
    s.read_only = o.read_only;
    s.follow_writers = true;  // the live pages show runs recorded after it opened
    return s;
  }

  /// The response to one parsed request, the token rule applied first.
  Response respond(const http::request<http::string_body>& req) {
    if (auto refused = refusal(req)) return *refused;
    Request request{std::string(req.method_string()), std::string(req.target()), req.body()};
    for (const auto& [name, field] : {std::pair{"host", http::field::host},
                                      {"origin", http::field::origin},
                                      {"content-type", http::field::content_type}}) {
      if (req.count(field)) request.headers[name] = std::string(req[field]);
    }
    if (req.count("X-Mtcal-Request")) request.headers["x-mtcal-request"] = std::string(req["X-Mtcal-Request"]);
    return answer(session, request, jobs.get());
  }

  /// The token rule: a response when the request may not go on.
  std::optional<Response> refusal(const http::request<http::string_body>& req) {
    Request request{std::string(req.method_string()), std::string(req.target()), {}};
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
        // The rest of the query as it was sent (still encoded), without the token.
        std::string rest;
        const auto q = request.target.find('?');
        for (std::size_t at = q + 1; at <= request.target.size();) {
          const auto end = std::min(request.target.find('&', at), request.target.size());
          const auto pair = request.target.substr(at, end - at);
          if (!pair.empty() && !pair.starts_with("token=") && pair != "token")
            rest += (rest.empty() ? "?" : "&") + pair;
          at = end + 1;
        }
        r.headers["Location"] = pathOf(request.target) + rest;
        return r;
      }
      if (!sameToken(given, options.token))
        return errorResponse(403, "this dashboard needs its token (printed when it started): ?token=... once");
    }
    return std::nullopt;
  }

  /// A live page's WebSocket: the run as it is recorded, polled from the archive.
  struct Live : std::enable_shared_from_this<Live> {
    Impl& server;
    websocket::stream<beast::tcp_stream> ws;
    storage::Id run_id;
    asio::steady_timer timer;
    services::ProgressSeen seen;
    std::string last_status;
    std::deque<std::string> outbox;
    bool writing = false, closing = false;
    beast::flat_buffer incoming;
    std::chrono::steady_clock::time_point first_seen{};
    std::size_t captures_at_first_seen = 0;

    Live(Impl& s, tcp::socket socket, storage::Id id) : server(s), ws(std::move(socket)), run_id(id), timer(s.io) {}

    void start(const http::request<http::string_body>& req) {
      ws.set_option(websocket::stream_base::timeout::suggested(beast::role_type::server));
      ws.read_message_max(4096);
      ws.async_accept(req, [self = shared_from_this()](beast::error_code ec) {
        if (ec) return;
        self->listen();
        self->poll();
      });
    }

    /// The page sends nothing yet; reading notices when it goes away.
    void listen() {
      ws.async_read(incoming, [self = shared_from_this()](beast::error_code ec, std::size_t) {
        if (ec) {
          self->closing = true;
          self->timer.cancel();
          return;
        }
        self->incoming.consume(self->incoming.size());
        self->listen();
      });
    }

    void poll() {
      if (closing) return;
      try {
        const auto p = services::runProgress(server.session, run_id, seen);
        if (seen.captures == 0 && seen.events == 0 && last_status.empty())
          send({{"type", "run"}, {"run", services::runDocument(p.run)}, {"planned", p.planned}});
        for (const auto& t : p.new_captures) {
          send({{"type", "capture"},
                {"seq", t.seq},
                {"target_mm", t.target_mm},
                {"direction", t.direction > 0 ? "up" : "down"},
                {"cycle", t.cycle},
                {"deviation", t.deviation_um}});
        }
        for (const auto& e : p.new_events)
          send({{"type", "event"}, {"level", e.level}, {"message", e.message}, {"time", e.created_at}});
        // The newest readings of the stream and of the environment unit, for display.
        if (!p.stream.empty()) {
          nlohmann::json time_s = nlohmann::json::array(), value = nlohmann::json::array();
          for (const auto& sample : p.stream) {
            time_s.push_back(static_cast<double>(sample.device_time_ns) * 1e-9);
            value.push_back(sample.value);
          }
          send({{"type", "stream"},
                {"device_time_s", time_s},
                {"value", value},
                {"signal_pct", p.stream.back().signal_pct}});
        }
        if (!p.new_environment.empty()) {
          const auto& e = p.new_environment.back();
          const auto value = [](const std::optional<double>& v) { return v ? nlohmann::json(*v) : nlohmann::json(); };
          send(
              {{"type", "environment"},
               {"air_temp_c", value(e.air_temp_c)},
               {"air_pressure_pa", value(e.air_pressure_pa)},
               {"humidity_pct", value(e.humidity_pct)},
               {"material_temp_c", {value(e.material_temp1_c), value(e.material_temp2_c), value(e.material_temp3_c)}}});
        }
        seen.captures += p.new_captures.size();
        seen.events += p.new_events.size();
        seen.environment += p.new_environment.size();
        seen.stream_position = p.stream_position;
        const auto now = std::chrono::steady_clock::now();
        if (first_seen == std::chrono::steady_clock::time_point{})
          first_seen = now, captures_at_first_seen = p.captures;
        // The time left at the pace seen since the page opened.
        nlohmann::json eta = nullptr;
        const double elapsed_s = std::chrono::duration<double>(now - first_seen).count();
        if (!p.finished() && p.planned > p.captures && p.captures > captures_at_first_seen && elapsed_s > 0.0) {
          eta = static_cast<double>(p.planned - p.captures) * elapsed_s /
                static_cast<double>(p.captures - captures_at_first_seen);
        }
        const std::string status = p.finished() ? (p.run.stale ? "interrupted" : p.run.status) : p.run.status;
        nlohmann::json progress{
            {"type", "progress"}, {"status", status}, {"captures", p.captures}, {"planned", p.planned}, {"eta_s", eta}};
        if (!p.new_captures.empty() || status != last_status) send(progress);
        last_status = status;
        if (p.finished()) return finish();
      } catch (const Error& e) {
        send({{"type", "error"}, {"error", e.what()}});
        return finish();
      }
      timer.expires_after(kLivePoll);
      timer.async_wait([self = shared_from_this()](beast::error_code ec) {
        if (!ec) self->poll();
      });
    }

    void send(const nlohmann::json& message) {
      outbox.push_back(message.dump());
      if (!writing) writeNext();
    }

    void writeNext() {
      if (outbox.empty()) {
        writing = false;
        if (closing) close();
        return;
      }
      writing = true;
      ws.text(true);
      ws.async_write(asio::buffer(outbox.front()), [self = shared_from_this()](beast::error_code ec, std::size_t) {
        self->outbox.pop_front();
        if (ec) {
          self->closing = true;
          self->outbox.clear();
          self->writing = false;
          return;
        }
        self->writeNext();
      });
    }

    /// After the last message: a normal close once everything queued is written.
    void finish() {
      closing = true;
      if (!writing) close();
    }
    void close() {
      ws.async_close(websocket::close_code::normal, [self = shared_from_this()](beast::error_code) {});
    }
  };

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
      } else if (websocket::is_upgrade(parser->get())) {
        const auto& req = parser->get();
        static const std::regex live_path("/api/live/([0-9]{1,15})");
        std::smatch m;
        const std::string path = pathOf(std::string(req.target()));
        if (auto refused = server.refusal(req)) {
          r = *refused;
        } else if (!std::regex_match(path, m, live_path)) {
          r = errorResponse(404, "no WebSocket at " + path + " (the live pages: /api/live/RUN)");
        } else {
          std::make_shared<Live>(server, stream.release_socket(), std::stoll(m[1]))->start(req);
          return;
        }
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
  impl_->refreshPlantCopy();
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
