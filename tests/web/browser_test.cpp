// The dashboard in a real browser: headless Chromium (Debian's chromium) loads the pages from
// `mtcal serve` on loopback, runs their script, and the test reads the DOM it built (and keeps
// a screenshot of each page, for docs/dashboard.md). Skipped, saying why, where Chromium is
// not installed (scripts/setup installs it).
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <thread>

#include "../support/temp_dir.h"
#include "../support/time_scale.h"
#include "mtcal/services/linear.h"
#include "mtcal/web/server.h"

namespace mtcal::web {
namespace {

std::string commandOutput(const std::string& command) {
  std::string out;
  if (FILE* p = popen(command.c_str(), "r")) {
    char buffer[4096];
    while (const auto n = fread(buffer, 1, sizeof buffer, p)) out.append(buffer, n);
    pclose(p);
  }
  return out;
}

std::size_t count(const std::string& text, const std::string& what) {
  std::size_t n = 0;
  for (auto at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

class BrowserTest : public ::testing::Test {
 protected:
  void SetUp() override {
    if (commandOutput("command -v chromium").empty())
      GTEST_SKIP() << "chromium is not installed (scripts/setup installs it)";
    services::SessionOptions so;
    so.db_path = dir_.file("archive.sqlite");
    services::Session session(so);
    services::LinearRunRequest r;
    acquisition::LinearPlan plan;
    plan.name = "X, 3 targets";
    plan.start_mm = 50, plan.end_mm = 90, plan.step_mm = 20, plan.repeats = 2, plan.datum_mm = 50;
    plan.dwell_s = 0.5, plan.window_s = 0.05;
    r.plans = {plan};
    r.simulation.seed = 3;
    r.simulation.time_scale = mtcal::testing::timeScale(400.0);
    for (const char* axis : {"X", "Y", "Z"}) {
      r.plans.front().axis = axis;
      services::runLinear(session, r);
    }
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
    commandOutput("chromium " + flags + " --window-size=1100,800 --screenshot='" + shot + "' '" + url +
                  "' >/dev/null 2>&1");
    EXPECT_TRUE(std::filesystem::exists(shot)) << screenshot;
    if (const char* keep = std::getenv("MTCAL_SCREENSHOTS"); keep && *keep) {
      std::filesystem::copy_file(shot, std::string(keep) + "/" + screenshot + ".png",
                                 std::filesystem::copy_options::overwrite_existing);
    }
    return commandOutput("chromium " + flags + " --dump-dom '" + url + "' 2>/dev/null");
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
  EXPECT_NE(page.find("download=\"run-1-report.html\""), std::string::npos);

  // The report the page shows draws every reading: 6 up and 6 down.
  page = dom("/api/runs/1/report.html", "report");
  const auto start = page.find("data-name=\"up\"");
  ASSERT_NE(start, std::string::npos);
  EXPECT_EQ(count(page.substr(start, page.find("</g>", start) - start), "<circle"), 6u);

  // A run that is not there: the page says so.
  page = dom("/run.html?id=99", "run-missing");
  EXPECT_NE(page.find("run 99 does not exist"), std::string::npos) << page;
}

}  // namespace
}  // namespace mtcal::web
