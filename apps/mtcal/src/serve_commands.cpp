// mtcal serve: the archive as a web dashboard (docs/dashboard.md).

#include <fmt/format.h>

#include <memory>

#include "commands.h"
#include "mtcal/error.h"
#include "mtcal/services/plant.h"
#include "mtcal/services/workshop.h"
#include "mtcal/web/server.h"

namespace mtcal::app {
namespace {

struct ServeOptions {
  web::ServerOptions server;
  std::string token_file;
  int refresh_s = 60;
};

int serve(const Globals& g, ServeOptions o) {
  o.server.db_path = g.db;
  o.server.plant_refresh = std::chrono::seconds(o.refresh_s);
  if (!o.token_file.empty()) {
    o.server.token = readTextFile(o.token_file);
    while (!o.server.token.empty() && std::isspace(static_cast<unsigned char>(o.server.token.back())))
      o.server.token.pop_back();
    if (o.server.token.size() < 16)
      throw InputError(fmt::format("--token-file {}: a token of at least 16 characters", o.token_file));
  }
  o.server.read_only = o.server.read_only || services::isPlantAddress(g.db);  // the plant archive is only read
  web::Server server(o.server);
  const std::string host = o.server.bind.find(':') != std::string::npos ? "[" + o.server.bind + "]" : o.server.bind;
  *g.err << fmt::format("mtcal serves {}{} at http://{}:{}/ (Ctrl-C stops)\n", g.db,
                        o.server.read_only ? " read-only" : "", host, server.port());
  if (!server.token().empty()) {
    *g.err << fmt::format("token (needed on {}): open http://{}:{}/index.html?token={}\n", o.server.bind, host,
                          server.port(), server.token());
  }
  g.err->flush();
  server.run(g.stop);
  *g.err << "stopped\n";
  return 0;
}

}  // namespace

void registerServeCommands(CliContext& c) {
  auto o = std::make_shared<ServeOptions>();
  auto* cmd = c.app->add_subcommand("serve", "the store (or the plant archive) as a web dashboard in a browser");
  cmd->add_option("--bind", o->server.bind, "address to listen on (other than 127.0.0.1 or ::1: a token is needed)")
      ->capture_default_str();
  cmd->add_option("--port", o->server.port, "port, 1 to 65535 (0: any free one)")
      ->transform(wholeBetween(0, 65535))
      ->capture_default_str();
  cmd->add_flag("--read-only", o->server.read_only, "open the store read-only; nothing changes state");
  cmd->add_option("--token-file", o->token_file, "the token, from a file (default: a new one, printed)");
  cmd->add_option("--refresh-s", o->refresh_s,
                  "on the plant archive (--db ADDRESS): seconds between updates of its copy while serving; 0: at "
                  "start only")
      ->transform(wholeBetween(0, 86400))
      ->capture_default_str();
  c.on(
      cmd, [&c, o] { return serve(c.g, *o); }, OnSignal::kStopAndWait);
}

}  // namespace mtcal::app
