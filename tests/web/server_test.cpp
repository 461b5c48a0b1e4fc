// `mtcal serve` on an ephemeral loopback port against a seeded archive, asked by a real HTTP
// client (Boost.Beast): every endpoint's status and JSON, the token rule, read-only mode, paths
// that try to leave the assets, requests too large.
#include "mtcal/web/server.h"

#include <gtest/gtest.h>

#include <boost/asio/connect.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>
#include <nlohmann/json.hpp>
#include <thread>

#include "../services/service_support.h"
#include "../support/http_client.h"
#include "../support/temp_dir.h"
#include "../support/time_scale.h"
#include "mtcal/error.h"
#include "mtcal/services/archive.h"
#include "mtcal/services/compensate.h"
#include "mtcal/services/export.h"
#include "mtcal/services/linear.h"
#include "mtcal/services/workshop.h"
#include "mtcal/storage/store.h"

namespace mtcal::web {
namespace {

using mtcal::testing::ask;
using mtcal::testing::Reply;
using mtcal::testing::Running;

namespace beast = boost::beast;
namespace http = beast::http;
using tcp = boost::asio::ip::tcp;

class ServerTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new mtcal::testing::TempDir;
    db_ = dir_->file("archive.sqlite");
    services::SessionOptions so;
    so.db_path = db_;
    services::Session session(so);
    for (const char* axis : {"X", "Y"}) services::runLinear(session, mtcal::testing::smallLinearRun(3, 400.0, axis));
  }
  static void TearDownTestSuite() { delete dir_; }
  static ServerOptions loopback() {
    ServerOptions o;
    o.db_path = db_;
    o.port = 0;
    return o;
  }
  static mtcal::testing::TempDir* dir_;
  static std::string db_;
};
mtcal::testing::TempDir* ServerTest::dir_ = nullptr;
std::string ServerTest::db_;

TEST_F(ServerTest, EveryEndpointAnswersWithItsStatusAndDocument) {
  Running running(loopback());
  const auto port = running.server().port();
  EXPECT_TRUE(running.server().token().empty());  // 127.0.0.1: no token
  auto get = [&](const std::string& target) { return ask("127.0.0.1", port, http::verb::get, target); };

  auto r = get("/");
  EXPECT_EQ(r.status, 302u);
  EXPECT_EQ(r.location, "/index.html");
  r = get("/index.html");
  EXPECT_EQ(r.status, 200u);
  EXPECT_EQ(r.content_type, "text/html; charset=utf-8");
  EXPECT_NE(r.body.find("<script src=\"/app.js\""), std::string::npos);
  EXPECT_EQ(get("/app.js").content_type, "text/javascript; charset=utf-8");

  r = get("/api/status");
  ASSERT_EQ(r.status, 200u);
  EXPECT_EQ(r.json()["archive"], db_);
  EXPECT_FALSE(r.json()["read_only"].get<bool>());

  r = get("/api/runs");
  ASSERT_EQ(r.status, 200u);
  ASSERT_EQ(r.json()["runs"].size(), 2u);
  EXPECT_EQ(r.json()["runs"][0]["axis"], "X");
  r = get("/api/runs?axis=Y&kind=linear");
  ASSERT_EQ(r.json()["runs"].size(), 1u);
  EXPECT_EQ(r.json()["runs"][0]["id"], 2);
  EXPECT_EQ(get("/api/runs?kind=circle").json()["runs"].size(), 0u);
  // Pages: the total, and the runs after the offset up to the limit.
  r = get("/api/runs?limit=1&offset=1");
  ASSERT_EQ(r.status, 200u);
  EXPECT_EQ(r.json()["total"], 2);
  ASSERT_EQ(r.json()["runs"].size(), 1u);
  EXPECT_EQ(r.json()["runs"][0]["id"], 2);
  EXPECT_EQ(get("/api/runs?offset=5").json()["runs"].size(), 0u);
  EXPECT_EQ(get("/api/runs?limit=-1").status, 422u);
  EXPECT_EQ(get("/api/runs?limit=1x").status, 422u);
  EXPECT_EQ(get("/api/runs?status=bogus").status, 422u);
  EXPECT_EQ(get("/api/runs?kind=bogus").status, 422u);
  // Said in the words of the request, not of the command line's options.
  r = get("/api/runs?sort=bogus");
  EXPECT_EQ(r.status, 422u);
  EXPECT_NE(r.json()["error"].get<std::string>().find("sort 'bogus': sort by one of id"), std::string::npos);
  EXPECT_EQ(r.json()["error"].get<std::string>().find("--"), std::string::npos);
  r = get("/api/runs?since=yesterday");
  EXPECT_EQ(r.status, 422u);
  EXPECT_NE(r.json()["error"].get<std::string>().find("since 'yesterday': not a date or time"), std::string::npos);

  r = get("/api/runs/1");
  ASSERT_EQ(r.status, 200u);
  EXPECT_EQ(r.json()["id"], 1);
  EXPECT_EQ(r.json()["target_values"].size(), 12u);  // 3 targets x 2 cycles x 2 directions
  r = get("/api/runs/1/report.html");
  ASSERT_EQ(r.status, 200u);
  EXPECT_TRUE(r.body.starts_with("<!DOCTYPE html>"));
  EXPECT_NE(r.body.find("axis X calibration"), std::string::npos);
  EXPECT_EQ(get("/api/runs/99").status, 404u);
  EXPECT_EQ(get("/api/runs/99/report.html").status, 404u);
  EXPECT_EQ(get("/api/runs/1/nothing").status, 404u);
  EXPECT_EQ(get("/api/models").json()["models"].size(), 0u);

  // Nothing outside the assets: the path is looked up, never opened.
  EXPECT_EQ(get("/../../etc/passwd").status, 404u);
  EXPECT_EQ(get("/%2e%2e/%2e%2e/etc/passwd").status, 404u);
  EXPECT_EQ(get("/index.html/../../CMakeLists.txt").status, 404u);
  // Nothing changes state yet; a request beyond 64 KiB is refused unread.
  r = ask("127.0.0.1", port, http::verb::post, "/api/runs");
  EXPECT_EQ(r.status, 405u);
  EXPECT_EQ(r.allow, "GET, HEAD");
  EXPECT_EQ(ask("127.0.0.1", port, http::verb::post, "/api/runs", {}, std::string(70000, 'x')).status, 413u);
  // HEAD: the headers of GET, no body.
  r = ask("127.0.0.1", port, http::verb::head, "/api/status");
  EXPECT_EQ(r.status, 200u);
  EXPECT_TRUE(r.body.empty());
}

// What a run page offers to save: its export's files as `mtcal export` writes them, a
// compensation table as `mtcal compensate` writes it, the reports of a campaign and a model.
TEST_F(ServerTest, ARunsFilesTablesAndReportsDownload) {
  Running running(loopback());
  const auto port = running.server().port();
  auto get = [&](const std::string& target) { return ask("127.0.0.1", port, http::verb::get, target); };
  services::SessionOptions so;
  so.db_path = db_;
  so.read_only = true;
  services::Session session(so);

  auto r = get("/api/runs/1/files");
  ASSERT_EQ(r.status, 200u);
  std::vector<std::string> names;
  const auto files = r.json();
  for (const auto& f : files["files"]) names.push_back(f["name"]);
  EXPECT_EQ(names,
            (std::vector<std::string>{"targets.csv", "samples.csv", "environment.csv", "results.json", "run.json"}));
  // The file as the export writes it, to the byte.
  const mtcal::testing::TempDir out;
  const auto exported = services::exportRun(session, 1, out.path().string());
  r = get("/api/runs/1/files/targets.csv");
  ASSERT_EQ(r.status, 200u);
  EXPECT_EQ(r.content_type, "text/csv; charset=utf-8");
  EXPECT_EQ(r.disposition, "attachment; filename=\"run1_targets.csv\"");
  EXPECT_EQ(r.body, services::readTextFile(exported.files.front().path));
  EXPECT_EQ(get("/api/runs/1/files/run.json").content_type, "application/json");
  r = get("/api/runs/1/files/nothing.csv");
  EXPECT_EQ(r.status, 422u);
  EXPECT_NE(r.json()["error"].get<std::string>().find("(its files: targets.csv, samples.csv"), std::string::npos);

  // A compensation table for each controller the status names, as the service writes it.
  r = get("/api/status");
  const auto controllers = r.json()["controllers"];
  ASSERT_GE(controllers.size(), 8u);
  services::CompensateRequest request;
  request.controller = "linuxcnc";
  const auto table = services::compensateRun(session, 1, request);
  r = get("/api/runs/1/compensation?controller=linuxcnc");
  ASSERT_EQ(r.status, 200u);
  EXPECT_EQ(r.body, table.file.text);
  EXPECT_EQ(r.disposition, "attachment; filename=\"run1_X_linuxcnc" + table.file.extension + "\"");
  // Every controller, with the options some need (one table for both directions, even entries).
  for (const auto& c : controllers) {
    r = get("/api/runs/1/compensation?mean&interval=20&controller=" + c.get<std::string>());
    // FANUC counts from the reference position at 0 mm, which this run (50 to 90 mm) lacks.
    EXPECT_EQ(r.status, c == "fanuc" ? 422u : 200u) << c << ": " << r.body;
  }
  r = get("/api/runs/1/compensation?controller=siemens-eec");
  EXPECT_EQ(r.status, 422u);
  EXPECT_NE(r.json()["error"].get<std::string>().find("give --mean"), std::string::npos);
  EXPECT_EQ(get("/api/runs/1/compensation?interval=2x").status, 422u);
  EXPECT_EQ(get("/api/runs/1/compensation?controller=nonesuch").status, 422u);

  // Reports: a campaign's, a comparison, and the reason when there is none.
  r = get("/api/campaigns/1/report.html");
  ASSERT_EQ(r.status, 200u);
  EXPECT_NE(r.body.find("campaign c1"), std::string::npos);
  r = get("/api/runs/1/report.html?after=2");
  ASSERT_EQ(r.status, 422u);  // run 2 measured Y: not the same axis
  EXPECT_EQ(r.content_type, "text/html; charset=utf-8");
  EXPECT_NE(r.body.find("<p>No report: "), std::string::npos);
  EXPECT_EQ(get("/api/campaigns/9/report.html").status, 404u);
  EXPECT_EQ(get("/api/models/9/report.html").status, 404u);
}

// Plans the server runs: started, followed, stopped, only by requests of its own pages (JSON,
// the X-Mtcal-Request header, the same origin), one at a time, never when read-only.
TEST_F(ServerTest, PlansStartOnlyFromTheDashboardsOwnPagesOneAtATime) {
  const mtcal::testing::TempDir dir;
  auto o = loopback();
  o.db_path = dir.file("jobs.sqlite");
  {
    services::SessionOptions so;
    so.db_path = o.db_path;
    services::Session(so).open(services::Access::kCreate);
  }
  Running running(o);
  const auto port = running.server().port();
  const std::string host = "127.0.0.1:" + std::to_string(port);
  const std::map<std::string, std::string> own{
      {"Host", host}, {"Content-Type", "application/json"}, {"X-Mtcal-Request", "1"}, {"Origin", "http://" + host}};
  auto post = [&](const std::string& target, const nlohmann::json& body, std::map<std::string, std::string> headers) {
    return ask("127.0.0.1", port, http::verb::post, target, headers, body.dump());
  };
  auto plan = nlohmann::json::parse(services::readTextFile(MTCAL_EXAMPLES_DIR "/plans/x_axis_iso230-2.json"));
  const nlohmann::json start{{"plan", plan}, {"plan_name", "x.json"}, {"time_scale", 5}};

  // Another site's page, a form, a request without the header: refused, nothing started.
  for (const auto& [name, value] : std::map<std::string, std::string>{
           {"Origin", "http://evil.example"}, {"Content-Type", "application/x-www-form-urlencoded"}}) {
    auto headers = own;
    headers[name] = value;
    EXPECT_EQ(post("/api/jobs", start, headers).status, 403u) << name;
  }
  auto headers = own;
  headers.erase("X-Mtcal-Request");
  EXPECT_EQ(post("/api/jobs", start, headers).status, 403u);
  EXPECT_EQ(ask("127.0.0.1", port, http::verb::get, "/api/jobs").json()["jobs"].size(), 0u);
  // A plan of no known type is refused before anything runs.
  EXPECT_EQ(post("/api/jobs", {{"plan", {{"type", "bogus"}}}}, own).status, 422u);
  EXPECT_EQ(post("/api/jobs", {{"plan", plan}, {"time_scale", -1}}, own).status, 422u);
  EXPECT_EQ(post("/api/jobs", {{"plan", plan}, {"plan_name", 7}}, own).status, 422u);  // JSON of the wrong shape
  EXPECT_EQ(ask("127.0.0.1", port, http::verb::post, "/api/jobs", own, "{not json").status, 422u);

  auto r = post("/api/jobs", start, own);
  ASSERT_EQ(r.status, 201u) << r.body;
  EXPECT_EQ(r.json()["id"], 1);
  EXPECT_EQ(r.json()["type"], "linear");
  EXPECT_EQ(r.location, "/api/jobs/1");
  // One at a time; no prompt waits, so an answer is refused.
  r = post("/api/jobs", start, own);
  EXPECT_EQ(r.status, 409u);
  EXPECT_NE(r.json()["error"].get<std::string>().find("job 1 (x.json) is running"), std::string::npos);
  EXPECT_EQ(post("/api/jobs/1/answer", {{"prompt", 1}}, own).status, 422u);
  EXPECT_EQ(post("/api/jobs/7/stop", nlohmann::json::object(), own).status, 404u);
  EXPECT_EQ(ask("127.0.0.1", port, http::verb::get, "/api/jobs/7").status, 404u);
  EXPECT_EQ(ask("127.0.0.1", port, http::verb::get, "/api/jobs/1/stop").status, 405u);
  EXPECT_EQ(post("/api/jobs", nlohmann::json::object(), own).status, 422u);  // no plan

  // Stopped: the run it recorded is interrupted, what it measured kept.
  EXPECT_EQ(post("/api/jobs/1/stop", nlohmann::json::object(), own).status, 200u);
  nlohmann::json job;
  for (int polls = 0; polls < 6000; ++polls) {  // the job ends within a step of the stop
    job = ask("127.0.0.1", port, http::verb::get, "/api/jobs/1").json();
    if (job["status"] != "running") break;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  EXPECT_EQ(job["status"], "stopped");
  ASSERT_EQ(job["runs"].size(), 1u);
  EXPECT_EQ(job["result"]["status"], "interrupted");
  EXPECT_EQ(ask("127.0.0.1", port, http::verb::get, "/api/runs/" + job["runs"][0].dump()).json()["status"],
            "interrupted");
  // Another may start now; each job names its own runs only.
  EXPECT_EQ(post("/api/jobs", start, own).status, 201u);
  EXPECT_EQ(post("/api/jobs/2/stop", nlohmann::json::object(), own).status, 200u);
  for (int polls = 0; polls < 6000; ++polls) {
    if (ask("127.0.0.1", port, http::verb::get, "/api/jobs/2").json()["status"] != "running") break;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  const auto list = ask("127.0.0.1", port, http::verb::get, "/api/jobs").json()["jobs"];
  ASSERT_EQ(list.size(), 2u);
  EXPECT_EQ(list[0]["id"], 2);  // newest first
  EXPECT_EQ(list[1]["runs"], job["runs"]);
  for (const auto& run : list[0]["runs"]) EXPECT_GT(run.get<int>(), job["runs"][0].get<int>());
}

TEST_F(ServerTest, AnotherAddressNeedsTheToken) {
  auto o = loopback();
  o.bind = "127.0.0.2";  // loopback, but not the default: the rule of any other address
  o.token = "0123456789abcdef0123456789abcdef";
  Running running(o);
  const auto port = running.server().port();
  EXPECT_EQ(running.server().token(), o.token);
  auto r = ask("127.0.0.2", port, http::verb::get, "/api/runs");
  EXPECT_EQ(r.status, 403u);
  EXPECT_NE(r.json()["error"].get<std::string>().find("needs its token"), std::string::npos);
  EXPECT_EQ(ask("127.0.0.2", port, http::verb::get, "/index.html").status, 403u);
  EXPECT_EQ(ask("127.0.0.2", port, http::verb::get, "/api/runs", {{"Authorization", "Bearer wrong"}}).status, 403u);
  EXPECT_EQ(ask("127.0.0.2", port, http::verb::get, "/api/runs", {{"Authorization", "Bearer " + o.token}}).status,
            200u);
  // ?token= once: a cookie only this site sends, and the address again without the token.
  r = ask("127.0.0.2", port, http::verb::get, "/index.html?machine=a%26b&token=" + o.token + "&axis=X");
  EXPECT_EQ(r.status, 303u);
  EXPECT_EQ(r.location, "/index.html?machine=a%26b&axis=X");  // the rest of the query as it was sent
  EXPECT_EQ(r.set_cookie, "mtcal_token=" + o.token + "; HttpOnly; SameSite=Strict; Path=/");
  EXPECT_EQ(ask("127.0.0.2", port, http::verb::get, "/api/runs", {{"Cookie", "a=b; mtcal_token=" + o.token}}).status,
            200u);
  EXPECT_EQ(ask("127.0.0.2", port, http::verb::get, "/api/runs?token=nope").status, 403u);

  // Without a token given, the server makes one (32 hex digits).
  o.token.clear();
  Running made(o);
  EXPECT_EQ(made.server().token().size(), 32u);
}

TEST_F(ServerTest, ReadOnlyOpensTheArchiveReadOnlyAndStoresNothing) {
  auto o = loopback();
  o.read_only = true;
  Running running(o);
  const auto port = running.server().port();
  EXPECT_TRUE(ask("127.0.0.1", port, http::verb::get, "/api/status").json()["read_only"].get<bool>());
  const auto before = ask("127.0.0.1", port, http::verb::get, "/api/runs/2").json()["results"].size();
  EXPECT_EQ(ask("127.0.0.1", port, http::verb::get, "/api/runs/2/report.html").status, 200u);
  // The report's analysis is shown, not stored.
  EXPECT_EQ(ask("127.0.0.1", port, http::verb::get, "/api/runs/2").json()["results"].size(), before);
  auto r = ask("127.0.0.1", port, http::verb::delete_, "/api/runs/2");
  EXPECT_EQ(r.status, 405u);
  EXPECT_NE(r.json()["error"].get<std::string>().find("read-only"), std::string::npos);
  // No plan runs: no state-changing endpoint at all.
  r = ask("127.0.0.1", port, http::verb::post, "/api/jobs",
          {{"Content-Type", "application/json"}, {"X-Mtcal-Request", "1"}}, "{}");
  EXPECT_EQ(r.status, 405u);
  EXPECT_EQ(r.allow, "GET, HEAD");
  EXPECT_EQ(ask("127.0.0.1", port, http::verb::get, "/api/jobs").status, 404u);
}

TEST_F(ServerTest, RefusesAMissingArchiveAndABusyPort) {
  auto o = loopback();
  o.db_path = dir_->file("none.sqlite");
  EXPECT_THROW(Server{o}, InputError);
  Running running(loopback());
  o = loopback();
  o.port = running.server().port();
  try {
    Server second(o);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("cannot listen on 127.0.0.1 port"), std::string::npos) << e.what();
  }
}

// The live page's WebSocket while a run records in another thread (its own connection to the
// archive, as another process would have): the run, then every capture exactly once in order,
// then the final status, whatever the pace (nothing here depends on timing).
TEST(LiveTest, EveryCaptureArrivesOnceAndTheRunsEndCloses) {
  const mtcal::testing::TempDir dir;
  const std::string db = dir.file("live.sqlite");
  services::SessionOptions so;
  so.db_path = db;
  std::thread recording;
  {
    services::Session seed(so);
    seed.open(services::Access::kCreate);
  }
  // A station's read-only dashboard, opened while nobody writes the archive, watching a run
  // another connection records after it opened.
  ServerOptions o;
  o.db_path = db;
  o.port = 0;
  o.read_only = true;
  Running running(o);
  const auto port = running.server().port();
  recording = std::thread([&] {
    services::Session session(so);
    services::runLinear(session, mtcal::testing::smallLinearRun(3, 20.0));
  });
  // Wait until the run exists (whatever it has recorded by then).
  while (ask("127.0.0.1", port, http::verb::get, "/api/runs").json()["runs"].empty())
    std::this_thread::sleep_for(std::chrono::milliseconds(20));

  boost::asio::io_context io;
  tcp::resolver resolver(io);
  beast::websocket::stream<beast::tcp_stream> ws(io);
  beast::get_lowest_layer(ws).connect(resolver.resolve("127.0.0.1", std::to_string(port)));
  ws.handshake("127.0.0.1", "/api/live/1");
  std::vector<nlohmann::json> messages;
  for (;;) {
    beast::flat_buffer buffer;
    beast::error_code ec;
    ws.read(buffer, ec);
    if (ec == beast::websocket::error::closed) break;
    ASSERT_FALSE(ec) << ec.message();
    messages.push_back(nlohmann::json::parse(beast::buffers_to_string(buffer.data())));
  }
  recording.join();
  ASSERT_FALSE(messages.empty());
  EXPECT_EQ(messages.front()["type"], "run");
  EXPECT_EQ(messages.front()["planned"], 12);
  std::vector<int> seqs;
  for (const auto& m : messages)
    if (m["type"] == "capture") seqs.push_back(m["seq"].get<int>());
  ASSERT_EQ(seqs.size(), 12u);  // 3 targets x 2 cycles x 2 directions, each once
  for (std::size_t i = 1; i < seqs.size(); ++i) EXPECT_LT(seqs[i - 1], seqs[i]);
  EXPECT_EQ(messages.back()["type"], "progress");
  EXPECT_EQ(messages.back()["status"], "completed");
  EXPECT_EQ(messages.back()["captures"], 12);
  // The reading stream for display: a few hundred of the newest readings a look, in time
  // order, inside the plan's travel (50 to 90 mm, overrun 5 mm), the last one the run's last
  // reading; the environment unit's readings.
  std::size_t streams = 0, environments = 0;
  double last_reading = NAN;
  for (const auto& m : messages) {
    if (m["type"] == "environment") {
      ++environments;
      EXPECT_GT(m["air_temp_c"].get<double>(), 15.0);
      EXPECT_LT(m["air_temp_c"].get<double>(), 25.0);
      EXPECT_GT(m["air_pressure_pa"].get<double>(), 90000.0);
    }
    if (m["type"] != "stream") continue;
    ++streams;
    const auto& t = m["device_time_s"];
    ASSERT_EQ(t.size(), m["value"].size());
    EXPECT_LE(t.size(), services::RunProgress::kStreamPoints);
    for (std::size_t i = 1; i < t.size(); ++i) EXPECT_LT(t[i - 1].get<double>(), t[i].get<double>());
    for (const auto& v : m["value"]) {
      EXPECT_GT(v.get<double>(), 44.0);
      EXPECT_LT(v.get<double>(), 96.0);
    }
    last_reading = m["value"].back().get<double>();
  }
  EXPECT_GE(streams, 1u);
  EXPECT_GE(environments, 1u);
  storage::Store store(db, storage::Open::kExisting);
  double recorded_last = NAN;
  store.forEachSample(1, [&](const storage::SampleRecord& s) { recorded_last = s.value; });
  EXPECT_EQ(last_reading, recorded_last);

  // A run that does not exist: said, then closed.
  beast::websocket::stream<beast::tcp_stream> missing(io);
  beast::get_lowest_layer(missing).connect(resolver.resolve("127.0.0.1", std::to_string(port)));
  missing.handshake("127.0.0.1", "/api/live/99");
  beast::flat_buffer buffer;
  missing.read(buffer);
  const auto error = nlohmann::json::parse(beast::buffers_to_string(buffer.data()));
  EXPECT_EQ(error["type"], "error");
  EXPECT_NE(error["error"].get<std::string>().find("run 99 does not exist"), std::string::npos);
  // No WebSocket elsewhere.
  beast::websocket::stream<beast::tcp_stream> elsewhere(io);
  beast::get_lowest_layer(elsewhere).connect(resolver.resolve("127.0.0.1", std::to_string(port)));
  beast::error_code ec;
  elsewhere.handshake("127.0.0.1", "/api/runs", ec);
  EXPECT_TRUE(ec);
}

}  // namespace
}  // namespace mtcal::web
