// The dashboard in a real browser: headless Chromium (Debian's chromium) loads the pages from
// `mtcal serve` on loopback, runs their script, and the test reads the DOM it built (and keeps
// a screenshot of each page, for docs/dashboard.md). Skipped, saying why, where Chromium is
// not installed (scripts/setup installs it).
#include <fcntl.h>
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>

#include <atomic>
#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/core/detail/base64.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <thread>

#include "../services/service_support.h"
#include "../support/command_output.h"
#include "../support/serial_thermal_workshop.h"
#include "../support/temp_dir.h"
#include "../support/time_scale.h"
#include "mtcal/services/archive.h"
#include "mtcal/services/linear.h"
#include "mtcal/services/workshop.h"
#include "mtcal/web/server.h"

extern char** environ;

namespace mtcal::web {
namespace {

namespace beast = boost::beast;
using tcp = boost::asio::ip::tcp;

/// Headless Chromium driven over its DevTools protocol (a WebSocket, Beast's client): what a
/// person's browser does with a page, asked while it happens.
class DevTools {
 public:
  DevTools(const std::string& profile, const std::string& log) : log_(log) {
    std::vector<std::string> argv{"chromium",
                                  "--headless",
                                  "--no-sandbox",
                                  "--disable-gpu",
                                  "--no-first-run",
                                  "--disable-background-networking",
                                  "--disable-extensions",
                                  "--proxy-server=127.0.0.1:9",
                                  "--remote-debugging-port=0",
                                  "--user-data-dir=" + profile,
                                  "about:blank"};
    std::vector<char*> args;
    for (auto& a : argv) args.push_back(a.data());
    args.push_back(nullptr);
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, 2, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0600);
    posix_spawn_file_actions_addopen(&actions, 1, "/dev/null", O_WRONLY, 0);
    if (posix_spawnp(&pid_, "chromium", &actions, nullptr, args.data(), environ) != 0) pid_ = 0;
    posix_spawn_file_actions_destroy(&actions);
  }
  ~DevTools() {
    page_.reset();
    if (pid_ > 0) {  // asked to end; killed where it does not within 10 s (a Chromium hung)
      kill(pid_, SIGTERM);
      for (int tries = 0; tries < 100 && waitpid(pid_, nullptr, WNOHANG) == 0; ++tries)
        std::this_thread::sleep_for(std::chrono::milliseconds(100));
      if (waitpid(pid_, nullptr, WNOHANG) == 0) {
        kill(pid_, SIGKILL);
        waitpid(pid_, nullptr, 0);
      }
    }
  }

  /// Connects to the first page (about:blank), trying again while Chromium starts (a cold start
  /// on a fresh machine can refuse or drop the first connections).
  /// @return why not, empty when connected
  std::string connect() {
    if (pid_ <= 0) return "chromium did not start";
    std::string why = "chromium did not say where DevTools listens";
    for (const auto limit = std::chrono::steady_clock::now() + std::chrono::minutes(1);
         std::chrono::steady_clock::now() < limit; std::this_thread::sleep_for(std::chrono::milliseconds(100))) {
      if (!running()) return "chromium exited; " + logEnd();
      // Chromium says where it listens on stderr: "DevTools listening on ws://127.0.0.1:PORT/...".
      const std::string text = logText();
      const auto at = text.find("ws://127.0.0.1:");
      if (at == std::string::npos || text.find('/', at + std::string("ws://").size()) == std::string::npos) continue;
      const auto start = at + std::string("ws://127.0.0.1:").size();
      const std::string port = text.substr(start, text.find('/', start) - start);
      try {
        why = attach(port);
        if (why.empty()) return "";
      } catch (const std::exception& e) {  // refused, dropped, or an answer cut short (its JSON)
        why = std::string("DevTools on port ") + port + ": " + e.what();
        page_.reset();
      }
    }
    return why + "; " + logEnd();
  }

  /// Sends a command and returns its result (events in between are skipped). A connection that
  /// breaks is said with the state of Chromium and the end of its log.
  nlohmann::json call(const std::string& method, const nlohmann::json& params) {
    const int id = ++last_id_;
    try {
      page_->write(boost::asio::buffer(nlohmann::json{{"id", id}, {"method", method}, {"params", params}}.dump()));
      for (;;) {
        const auto m = readMessage();
        if (m.contains("id") && m["id"] == id) return m.value("result", nlohmann::json::object());
      }
    } catch (const boost::system::system_error& e) {
      throw std::runtime_error("DevTools " + method + ": " + e.what() + (running() ? "" : " (chromium exited)") + "; " +
                               logEnd());
    }
  }
  /// A JavaScript expression's value in the page.
  nlohmann::json evaluate(const std::string& expression) {
    return call("Runtime.evaluate", {{"expression", expression}, {"returnByValue", true}})["result"]["value"];
  }
  /// The page as a person sees it now, written to `path` (PNG).
  void screenshot(const std::string& path) {
    call("Emulation.setDeviceMetricsOverride",
         {{"width", 1100}, {"height", 800}, {"deviceScaleFactor", 1}, {"mobile", false}});
    const auto data = call("Page.captureScreenshot", {{"format", "png"}})["data"].get<std::string>();
    std::string png(beast::detail::base64::decoded_size(data.size()), '\0');
    png.resize(beast::detail::base64::decode(png.data(), data.data(), data.size()).first);
    std::ofstream(path, std::ios::binary) << png;
  }

 private:
  /// The page target's WebSocket on `port`, answering. @return why not, empty when attached
  std::string attach(const std::string& port) {
    tcp::resolver resolver(io_);
    beast::tcp_stream stream(io_);
    stream.connect(resolver.resolve("127.0.0.1", port));
    beast::http::request<beast::http::empty_body> req(beast::http::verb::get, "/json/list", 11);
    req.set(beast::http::field::host, "127.0.0.1");
    beast::http::write(stream, req);
    beast::flat_buffer buffer;
    beast::http::response<beast::http::string_body> res;
    beast::http::read(stream, buffer, res);
    std::string target;
    for (const auto& t : nlohmann::json::parse(res.body()))
      if (t["type"] == "page") target = t["webSocketDebuggerUrl"].get<std::string>();
    if (target.empty()) return "DevTools on port " + port + " lists no page";
    const std::string path = target.substr(target.find('/', std::string("ws://").size()));
    page_ = std::make_unique<beast::websocket::stream<beast::tcp_stream>>(io_);
    beast::get_lowest_layer(*page_).connect(resolver.resolve("127.0.0.1", port));
    page_->handshake("127.0.0.1:" + port, path);
    page_->write(boost::asio::buffer(
        nlohmann::json{{"id", ++last_id_}, {"method", "Runtime.evaluate"}, {"params", {{"expression", "1"}}}}.dump()));
    for (;;) {  // the page answers commands: the connection is whole
      const auto m = readMessage();
      if (m.contains("id") && m["id"] == last_id_) return "";
    }
  }
  /// The page's next message. A page that says nothing for a minute fails the read (the socket's
  /// timeout, which holds for asynchronous operations only), so a Chromium that hangs fails the
  /// test with its log instead of at ctest's timeout.
  nlohmann::json readMessage() {
    beast::get_lowest_layer(*page_).expires_after(std::chrono::minutes(1));
    beast::flat_buffer buffer;
    beast::error_code result;
    page_->async_read(buffer, [&](beast::error_code ec, std::size_t) { result = ec; });
    io_.restart();
    io_.run();
    if (result) throw boost::system::system_error(result, "reading the page's answer");
    return nlohmann::json::parse(beast::buffers_to_string(buffer.data()));
  }
  bool running() {
    if (pid_ <= 0) return false;
    if (waitpid(pid_, nullptr, WNOHANG) != pid_) return true;
    pid_ = 0;
    return false;
  }
  std::string logText() const {
    std::ifstream in(log_);
    std::stringstream text;
    text << in.rdbuf();
    return text.str();
  }
  /// The last lines Chromium wrote, for a failure's message.
  std::string logEnd() const {
    const std::string text = logText();
    return "chromium's log ends: " + (text.size() > 2000 ? "..." + text.substr(text.size() - 2000) : text);
  }

  std::string log_;
  pid_t pid_ = 0;
  boost::asio::io_context io_;
  std::unique_ptr<beast::websocket::stream<beast::tcp_stream>> page_;
  int last_id_ = 0;
};

std::size_t count(const std::string& text, const std::string& what) {
  std::size_t n = 0;
  for (auto at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

class BrowserTest : public ::testing::Test {
 protected:
  void SetUp() override {
    if (mtcal::testing::commandOutput("command -v chromium").empty())
      GTEST_SKIP() << "chromium is not installed (scripts/setup installs it)";
    if (::testing::UnitTest::GetInstance()->current_test_info()->name() ==
        std::string("TheLivePageShowsCapturesArrive"))
      return;  // that test records its own run while the page watches
    services::SessionOptions so;
    so.db_path = dir_.file("archive.sqlite");
    services::Session session(so);
    for (const char* axis : {"X", "Y", "Z"})
      services::runLinear(session, mtcal::testing::smallLinearRun(3, 400.0, axis));
    ServerOptions o;
    o.db_path = so.db_path;
    o.port = 0;
    server_ = std::make_unique<Server>(o);
    thread_ = std::thread([this] { server_->run(); });
  }
  void TearDown() override {
    if (!server_) return;
    server_->stop();
    thread_.join();
  }

  /// Chromium's DOM of a page after its script ran (virtual time: it waits for the page's
  /// requests, not for the wall clock), and a screenshot of it as `screenshot`.png.
  std::string dom(const std::string& path, const std::string& screenshot) {
    const std::string url = "http://127.0.0.1:" + std::to_string(server_->port()) + path;
    const std::string flags =
        "--headless --no-sandbox --disable-gpu --no-first-run --disable-background-networking "
        "--disable-extensions --proxy-server=127.0.0.1:9 --virtual-time-budget=5000 "
        "--user-data-dir='" +
        dir_.file("profile") + "'";
    const std::string shot = dir_.file(screenshot + ".png");
    mtcal::testing::commandOutput("chromium " + flags + " --window-size=1100,800 --screenshot='" + shot + "' '" + url +
                                  "' >/dev/null 2>&1");
    keep(shot);
    return mtcal::testing::commandOutput("chromium " + flags + " --dump-dom '" + url + "' 2>/dev/null");
  }

  /// A screenshot made: a PNG, copied to $MTCAL_SCREENSHOTS when set (docs/dashboard).
  static void keep(const std::string& shot) {
    std::ifstream in(shot, std::ios::binary);
    std::string signature(8, '\0');
    in.read(signature.data(), 8);
    EXPECT_EQ(signature, "\x89PNG\r\n\x1a\n") << shot;
    if (const char* folder = std::getenv("MTCAL_SCREENSHOTS"); folder && *folder) {
      std::filesystem::copy_file(shot, std::string(folder) + "/" + std::filesystem::path(shot).filename().string(),
                                 std::filesystem::copy_options::overwrite_existing);
    }
  }
  /// The DevTools browser's page as `name`.png.
  void screenshot(DevTools& browser, const std::string& name) {
    browser.screenshot(dir_.file(name + ".png"));
    keep(dir_.file(name + ".png"));
  }

  mtcal::testing::TempDir dir_;
  std::unique_ptr<Server> server_;
  std::thread thread_;
};

TEST_F(BrowserTest, TheArchiveListsTheRunsAndTheirPagesShowTheReport) {
  auto page = dom("/index.html", "archive");
  EXPECT_EQ(count(page, "<tr data-run="), 3u) << page;
  EXPECT_NE(page.find("3 run(s)"), std::string::npos);
  EXPECT_NE(page.find("href=\"/run.html?id=2\""), std::string::npos);

  // The filter in the address: only the Y run.
  page = dom("/index.html?axis=Y", "archive-y");
  EXPECT_EQ(count(page, "<tr data-run="), 1u);
  EXPECT_NE(page.find("<tr data-run=\"2\">"), std::string::npos);

  page = dom("/run.html?id=1", "run");
  EXPECT_NE(page.find("Run 1: X, 3 targets"), std::string::npos) << page;
  EXPECT_NE(page.find("src=\"/api/runs/1/report.html\""), std::string::npos);
  EXPECT_NE(page.find("download=\"run1_report.html\""), std::string::npos);
  EXPECT_NE(page.find("href=\"/api/runs/1/report.pdf\""), std::string::npos);
  // The export's files to save, a compensation table for a controller, the comparison form.
  EXPECT_EQ(count(page, "href=\"/api/runs/1/files/"), 5u);
  EXPECT_NE(page.find("download=\"run1_targets.csv\""), std::string::npos);
  EXPECT_NE(page.find("id=\"compensation-link\" href=\"/api/runs/1/compensation?controller=csv\""), std::string::npos);
  EXPECT_NE(page.find("<option>linuxcnc</option>"), std::string::npos);
  EXPECT_NE(page.find("<form id=\"compare\" action=\"/compare.html\">"), std::string::npos);  // shown
  // The campaign's report from the archive.
  page = dom("/index.html", "archive");
  EXPECT_NE(page.find("href=\"/api/campaigns/1/report.html\""), std::string::npos);
  EXPECT_NE(page.find("href=\"/index.html?campaign=c2\""), std::string::npos);
  // A campaign's runs: the archive filtered by it.
  page = dom("/index.html?campaign=c3", "archive-campaign");
  EXPECT_EQ(count(page, "<tr data-run="), 1u);
  EXPECT_NE(page.find("<tr data-run=\"3\">"), std::string::npos);

  // Before and after side by side: the comparison's report and each run's.
  page = dom("/compare.html?before=1&after=1", "compare");
  EXPECT_NE(page.find("src=\"/api/runs/1/report.html?after=1\""), std::string::npos) << page;
  EXPECT_EQ(count(page, "<iframe"), 3u);

  // The report the page shows draws every reading: 6 up and 6 down.
  page = dom("/api/runs/1/report.html", "report");
  const auto start = page.find("data-name=\"up\"");
  ASSERT_NE(start, std::string::npos);
  EXPECT_EQ(count(page.substr(start, page.find("</g>", start) - start), "<circle"), 6u);

  // A run that is not there: the page says so.
  page = dom("/run.html?id=99", "run-missing");
  EXPECT_NE(page.find("run 99 does not exist"), std::string::npos) << page;
}

// The live page in the browser while a run records in another thread: the rows of its capture
// table never go back, end at all 12 captures with the status completed. Polled through
// DevTools until the page says the run ended (a minute at most, so that a broken page fails
// instead of hanging); how many intermediate states are seen depends on the pace and is only
// printed.
TEST_F(BrowserTest, TheLivePageShowsCapturesArrive) {
  services::SessionOptions so;
  so.db_path = dir_.file("live.sqlite");
  {
    services::Session seed(so);
    seed.open(services::Access::kCreate);
  }
  ServerOptions o;
  o.db_path = so.db_path;
  o.port = 0;
  server_ = std::make_unique<Server>(o);
  thread_ = std::thread([this] { server_->run(); });
  DevTools browser(dir_.file("devtools-profile"), dir_.file("chromium.log"));
  const auto why = browser.connect();
  ASSERT_TRUE(why.empty()) << why;

  // Joined also when a step below throws (a browser that stops answering): a thread left
  // joinable would abort the whole test program instead of failing this test, as would an
  // exception leaving the thread: the run's failure is kept and said.
  std::string recording_failure;
  std::atomic<bool> recording_ended = false;
  std::jthread recording([&] {
    try {
      services::Session session(so);
      services::runLinear(session, mtcal::testing::smallLinearRun(3, 4.0));
    } catch (const std::exception& e) {
      recording_failure = e.what();
    }
    recording_ended = true;
  });
  const auto base = "http://127.0.0.1:" + std::to_string(server_->port());
  services::Session reader(so);
  while (services::listRuns(reader, {}).empty() && !recording_ended)
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  if (services::listRuns(reader, {}).empty()) {
    recording.join();
    FAIL() << "the run did not start: " << recording_failure;
  }
  browser.call("Page.navigate", {{"url", base + "/live.html?id=1"}});

  std::vector<int> rows;
  std::string status;
  const auto limit = std::chrono::steady_clock::now() + std::chrono::minutes(1);
  while (std::chrono::steady_clock::now() < limit) {
    const auto state = browser.evaluate(
        "JSON.stringify({status: document.body ? (document.body.dataset.status || '') : '', rows: "
        "document.querySelectorAll('#captures tbody tr').length})");
    if (state.is_string()) {
      const auto j = nlohmann::json::parse(state.get<std::string>());
      rows.push_back(j["rows"].get<int>());
      status = j["status"].get<std::string>();
      if (status == "completed" || status == "interrupted" || status == "error") break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  recording.join();
  ASSERT_EQ(recording_failure, "");
  ASSERT_FALSE(rows.empty());
  EXPECT_EQ(status, "completed");
  EXPECT_EQ(rows.back(), 12);
  for (std::size_t i = 1; i < rows.size(); ++i) EXPECT_LE(rows[i - 1], rows[i]);
  const auto progress = browser.evaluate("document.getElementById('progress-text').textContent");
  EXPECT_EQ(progress, "completed: 12 of 12 captures");
  const auto plotted = browser.evaluate("document.querySelectorAll('#plot circle').length");
  EXPECT_EQ(plotted, 12);
  // The reading stream and the environment as the page shows them.
  EXPECT_TRUE(browser.evaluate("/^reading [0-9]+\\.[0-9]{6} mm, signal [0-9]+ %$/.test("
                               "document.getElementById('reading').textContent)") == true)
      << browser.evaluate("document.getElementById('reading').textContent");
  EXPECT_TRUE(browser.evaluate("document.getElementById('environment').textContent.startsWith('air ')") == true);
  EXPECT_EQ(browser.evaluate("document.querySelectorAll('#stream polyline').length"), 1);
  screenshot(browser, "live");
  std::size_t between = 0;
  for (const int r : rows) between += r > 0 && r < 12;
  std::printf("live page: %zu looks, %zu of them between the first and the last capture\n", rows.size(), between);
}

/// Asks the page `expression` every 50 ms until it is true (a minute at most, so that a broken
/// page fails instead of hanging). @return whether it became true
bool waitFor(DevTools& browser, const std::string& expression) {
  for (const auto limit = std::chrono::steady_clock::now() + std::chrono::minutes(1);
       std::chrono::steady_clock::now() < limit; std::this_thread::sleep_for(std::chrono::milliseconds(50))) {
    if (browser.evaluate(expression) == true) return true;
  }
  return false;
}

// A plan started from the page on real instruments (a logger and a probe box on serial ports:
// the pseudo-terminals of a simulated workshop), its operator's request shown on the job's page
// and answered there: the run goes on and records every sample. Then a plan on the simulated
// machine, stopped from the page: the run is interrupted with what it measured.
TEST_F(BrowserTest, APlanStartedFromThePageAsksTheOperatorThereAndStopsThere) {
  // The run waits for the operator's answer on the page once the logger logs.
  mtcal::testing::SerialThermalWorkshop workshop;
  DevTools browser(dir_.file("devtools-profile"), dir_.file("chromium.log"));
  const auto why = browser.connect();
  ASSERT_TRUE(why.empty()) << why;
  const auto base = "http://127.0.0.1:" + std::to_string(server_->port());
  browser.call("Page.navigate", {{"url", base + "/start.html"}});
  ASSERT_TRUE(waitFor(browser, "document.readyState === 'complete' && !!document.getElementById('start')"));
  const auto plan = services::readTextFile(MTCAL_EXAMPLES_DIR "/plans/thermal/quick-2h.json");
  const std::string fill =
      "const f = document.getElementById('start'); f.elements.plan.value = " + nlohmann::json(plan).dump() +
      "; f.elements.plan_name.value = 'quick-2h.json'; " +
      "f.elements.device.value = " + nlohmann::json(workshop.probesUri()).dump() +
      "; f.elements.logger.value = " + nlohmann::json(workshop.loggerUri()).dump() +
      "; f.elements.machine.value = 'grinder 7'; f.requestSubmit(); true";
  browser.evaluate(fill);
  ASSERT_TRUE(waitFor(browser, "location.pathname === '/job.html' && !document.getElementById('prompt').hidden"))
      << browser.evaluate("document.body.innerText");
  EXPECT_EQ(browser.evaluate("document.getElementById('prompt-text').textContent"),
            "Start the spindle program on the CNC now; confirm when it runs");
  screenshot(browser, "job");
  browser.evaluate("document.getElementById('answer').click(); true");
  ASSERT_TRUE(waitFor(browser, "document.body.dataset.status === 'completed'"))
      << browser.evaluate("document.body.innerText");
  EXPECT_TRUE(browser.evaluate("document.getElementById('prompt').hidden") == true);
  EXPECT_EQ(browser.evaluate("document.querySelectorAll('#runs a').length"), 2);  // the run and its live page
  services::SessionOptions so;
  so.db_path = dir_.file("archive.sqlite");
  {
    services::Session session(so);
    const auto runs = services::listRuns(session, {});
    const auto& thermal = runs.back();
    EXPECT_EQ(thermal.kind, "thermal");
    EXPECT_EQ(thermal.machine_name, "grinder 7");
    EXPECT_EQ(thermal.operator_name, "dashboard");
    EXPECT_EQ(services::showRun(session, thermal.id).thermal_samples, 121);
  }

  // A linear plan on the simulated machine, slow enough to be stopped from its live page.
  browser.call("Page.navigate", {{"url", base + "/start.html"}});
  ASSERT_TRUE(waitFor(browser, "document.readyState === 'complete' && !!document.getElementById('start')"));
  browser.evaluate("const f = document.getElementById('start'); f.elements.plan.value = " +
                   nlohmann::json(services::readTextFile(MTCAL_EXAMPLES_DIR "/plans/x_axis_iso230-2.json")).dump() +
                   "; f.elements.time_scale.value = '5'; f.requestSubmit(); true");
  ASSERT_TRUE(waitFor(browser, "location.pathname === '/job.html' && document.querySelectorAll('#runs a').length > 0"));
  browser.evaluate("location.href = document.querySelector('#runs a:nth-child(2)').href; true");
  ASSERT_TRUE(waitFor(browser,
                      "location.pathname === '/live.html' && !document.getElementById('controls').hidden && "
                      "document.querySelectorAll('#captures tbody tr').length > 0"));
  browser.evaluate("document.getElementById('stop').click(); true");
  ASSERT_TRUE(waitFor(browser, "document.body.dataset.status === 'interrupted'"))
      << browser.evaluate("document.body.innerText");
  services::Session session(so);
  const auto linear = services::listRuns(session, {}).back();
  EXPECT_EQ(linear.kind, "linear");
  EXPECT_EQ(linear.status, "interrupted");
  EXPECT_GT(services::showRun(session, linear.id).targets.size(), 0u);
}

// The plots of a run's page zoom about the pointer with the wheel, move when dragged and come
// back whole on a double click; their points keep their values on hover.
TEST_F(BrowserTest, ARunPagesPlotsZoomAndPan) {
  DevTools browser(dir_.file("devtools-profile"), dir_.file("chromium.log"));
  const auto why = browser.connect();
  ASSERT_TRUE(why.empty()) << why;
  browser.call("Page.navigate", {{"url", "http://127.0.0.1:" + std::to_string(server_->port()) + "/run.html?id=1"}});
  const std::string plot = "document.getElementById('report').contentDocument.querySelector('svg')";
  ASSERT_TRUE(waitFor(browser,
                      "!!document.getElementById('report') && !!document.getElementById('report')"
                      ".contentDocument && !!" +
                          plot + " && " + plot + ".style.cursor === 'zoom-in'"));
  // 800 px wide, 420 high and the legend's rows.
  std::istringstream whole(browser.evaluate(plot + ".getAttribute('viewBox')").get<std::string>());
  double whole_x = 1, whole_y = 1, whole_width = 0, whole_height = 0;
  whole >> whole_x >> whole_y >> whole_width >> whole_height;
  EXPECT_EQ(whole_x, 0.0);
  EXPECT_EQ(whole_y, 0.0);
  EXPECT_EQ(whole_width, 800.0);
  EXPECT_GT(whole_height, 420.0);
  // Two notches of the wheel at the plot's centre: 0.8 x 0.8 of the width and height, centred.
  const std::string wheel = "(() => { const s = " + plot +
                            "; const b = s.getBoundingClientRect(); "
                            "s.dispatchEvent(new WheelEvent('wheel', {deltaY: -100, clientX: b.left + b.width / 2, "
                            "clientY: b.top + b.height / 2, bubbles: true, cancelable: true})); "
                            "return s.getAttribute('viewBox'); })()";
  browser.evaluate(wheel);
  std::istringstream view(browser.evaluate(wheel).get<std::string>());
  double x = 0, y = 0, width = 0, height = 0;
  view >> x >> y >> width >> height;
  EXPECT_NEAR(width, 0.64 * whole_width, 0.01);  // 0.8 x 0.8, to the viewBox's 2 decimals
  EXPECT_NEAR(height, 0.64 * whole_height, 0.01);
  EXPECT_NEAR(x, 0.18 * whole_width, 0.5);  // about the centre, to the pixel the pointer is on
  EXPECT_NEAR(y, 0.18 * whole_height, 0.5);
  EXPECT_GT(browser.evaluate(plot + ".querySelectorAll('circle title').length").get<int>(), 0);
  browser.evaluate(plot + ".dispatchEvent(new MouseEvent('dblclick', {bubbles: true}))");
  EXPECT_EQ(browser.evaluate(plot + ".getAttribute('viewBox')"), fmt::format("0.00 0.00 800.00 {:.2f}", whole_height));
}

}  // namespace
}  // namespace mtcal::web
