// Sessions that survive, through the command line: an acquisition killed with SIGKILL (the
// mtcal executable in a process of its own), the run refused while its process lives, shown
// as interrupted once it has died and resumed to completion; an archive nobody may write,
// read by a user without write permission; an analysis stored once.

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "../support/child_process.h"
#include "../support/cli_run.h"
#include "../support/temp_dir.h"
#include "../support/time_scale.h"

namespace mtcal::app {
namespace {

using mtcal::testing::cli;

/// Starts the mtcal executable with `args` (output to /dev/null). @return its pid
pid_t startMtcal(const std::vector<std::string>& args) {
  const pid_t pid = ::fork();
  if (pid == 0) {
    std::vector<char*> argv{const_cast<char*>(MTCAL_BINARY)};
    for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    std::freopen("/dev/null", "w", stdout);
    std::freopen("/dev/null", "w", stderr);
    ::execv(MTCAL_BINARY, argv.data());
    ::_exit(127);
  }
  return pid;
}

nlohmann::json runOf(const std::string& db, int id) {
  const auto r = cli({"--db", db, "--json", "show", std::to_string(id)});
  EXPECT_EQ(r.code, 0) << r.err;
  return r.code == 0 ? nlohmann::json::parse(r.out) : nlohmann::json{};
}

/// The targets run 1 of `db` has captured, waited for (on the store, not on the clock) until
/// `wanted` or a minute has passed.
std::int64_t capturedTargets(const std::string& db, std::int64_t wanted) {
  std::int64_t captured = 0;
  for (int polls = 0; polls < 1200 && captured < wanted; ++polls) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    if (!std::filesystem::exists(db)) continue;
    const auto r = cli({"--db", db, "--json", "runs"});
    if (r.code != 0) continue;
    const auto runs = nlohmann::json::parse(r.out)["runs"];
    if (!runs.empty()) captured = runs[0]["measured"].get<std::int64_t>();
  }
  return captured;
}

/// The demo campaign started in real time at 50x (minutes long: surely under way when signalled or
/// killed), and the targets it has captured once 5 are (or a minute has passed).
std::pair<pid_t, std::int64_t> demoUnderWay(const std::string& db) {
  const pid_t pid = startMtcal({"--db", db, "demo", "--time-scale", "50"});
  return {pid, pid > 0 ? capturedTargets(db, 5) : 0};
}

TEST(SurviveCli, AKilledAcquisitionIsInterruptedRefusedWhileAliveAndResumed) {
  const mtcal::testing::TempDir dir;
  const std::string db = dir.file("kill.sqlite");
  const auto [pid, captured] = demoUnderWay(db);
  ASSERT_GE(captured, 5) << "the acquisition did not start";
  auto live = runOf(db, 1);
  EXPECT_EQ(live["status"], "running");
  EXPECT_EQ(live["owner"]["pid"], pid);
  auto r = cli({"--db", db, "resume", "1"});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("is being recorded by process " + std::to_string(pid)), std::string::npos) << r.err;

  ::kill(pid, SIGKILL);
  int status = 0;
  ::waitpid(pid, &status, 0);
  ASSERT_TRUE(WIFSIGNALED(status));
  const auto dead = runOf(db, 1);
  EXPECT_EQ(dead["status"], "interrupted");
  EXPECT_TRUE(dead["stale"].get<bool>());
  const auto kept = dead["target_values"];
  ASSERT_GE(kept.size(), 5u);
  r = cli({"--db", db, "show", "1"});
  EXPECT_NE(r.out.find("process " + std::to_string(pid)), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("ended without closing the run: resume it with mtcal resume 1"), std::string::npos) << r.out;

  r = cli({"--db", db, "--json", "resume", "1", "--time-scale", mtcal::testing::timeScaleArg(400)});
  ASSERT_EQ(r.code, 0) << r.err;
  const auto resumed = nlohmann::json::parse(r.out);
  EXPECT_EQ(resumed["status"], "completed");
  EXPECT_EQ(resumed["iso230_2"]["min_cycles"], 9);
  const auto after = runOf(db, 1);
  EXPECT_EQ(after["measured"], 522);
  for (std::size_t k = 0; k < kept.size(); ++k)  // what was committed before the kill is kept as it was
    EXPECT_EQ(after["target_values"][k]["deviation_um"], kept[k]["deviation_um"]) << k;
  std::vector<std::string> events;
  for (const auto& e : after["events"]) events.push_back(e["message"].get<std::string>());
  const auto has = [&](const std::string& text) {
    for (const auto& e : events) {
      if (e.find(text) != std::string::npos) return true;
    }
    return false;
  };
  EXPECT_TRUE(has("run started"));
  EXPECT_TRUE(has("interrupted: process " + std::to_string(pid) + " on"));
  EXPECT_TRUE(has("resumed by process"));
  EXPECT_TRUE(has("run completed"));
}

/// The process' end: its exit code, or 128 + the signal that ended it; -1 if it has not ended
/// within a minute (it is then killed).
int endOf(pid_t pid) {
  int status = 0;
  for (int polls = 0; polls < 1200; ++polls) {
    if (::waitpid(pid, &status, WNOHANG) == pid)
      return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  ::kill(pid, SIGKILL);
  ::waitpid(pid, &status, 0);
  return -1;
}

/// Whether the process is (within a minute) asleep opening a FIFO that has no writer: its kernel
/// wait channel (Linux: wait_for_partner, or a fifo_ function); where the kernel does not show it
/// ("0"), the mtcal executable asleep.
bool blockedOpeningAFifo(pid_t pid) {
  const std::string proc = "/proc/" + std::to_string(pid);
  for (int polls = 0; polls < 1200; ++polls) {
    std::string where, comm, stat;
    std::getline(std::ifstream(proc + "/wchan"), where);
    std::getline(std::ifstream(proc + "/comm"), comm);
    std::getline(std::ifstream(proc + "/stat"), stat);
    if (where.find("partner") != std::string::npos || where.find("fifo") != std::string::npos) return true;
    const auto state = stat.rfind(") ");  // "pid (comm) S ..."
    if ((where.empty() || where == "0") && comm == "mtcal" && state != std::string::npos &&
        stat.substr(state + 2, 1) == "S")
      return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  return false;
}

// Ctrl-C (SIGINT) ends a run cleanly after the current target: stored, interrupted, resumable.
// Any other command it ends at once: an import waiting for a FIFO's writer (blocked in open(),
// which the signal does not interrupt) used to wait for ever, SIGTERM and Ctrl-C ignored.
TEST(SurviveCli, ASignalEndsARunCleanlyAndAnyOtherCommandAtOnce) {
  const mtcal::testing::TempDir dir;
  const std::string db = dir.file("signal.sqlite");
  const auto [run, captured] = demoUnderWay(db);
  ASSERT_GE(captured, 5) << "the acquisition did not start";
  ::kill(run, SIGINT);
  EXPECT_EQ(endOf(run), 1);  // exit code 1: interrupted
  const auto stopped = runOf(db, 1);
  EXPECT_EQ(stopped["status"], "interrupted");
  EXPECT_FALSE(stopped["stale"].get<bool>());  // closed by its own process, not found dead
  EXPECT_GE(stopped["measured"].get<std::int64_t>(), captured);

  const std::string fifo = dir.file("no_writer.csv");
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  for (const int signal : {SIGTERM, SIGINT}) {
    SCOPED_TRACE(signal);
    const pid_t import = startMtcal({"--db", db, "import", "linear", fifo});
    ASSERT_GT(import, 0);
    ASSERT_TRUE(blockedOpeningAFifo(import));  // its handler set up long before
    ::kill(import, signal);
    EXPECT_EQ(endOf(import), 128 + signal);
  }
  EXPECT_EQ(cli({"--db", db, "--json", "runs"}).out.find("no_writer"), std::string::npos);
}

// Which commands a first signal asks to stop and waits for, as each says where it is registered:
// every run, its resumption, the demo, the dashboard and a backup; nothing else. Each is given
// what makes it fail at once (a missing plan, a store in no folder): the choice is made when the
// line is parsed, before the command runs.
TEST(SurviveCli, EveryRunWaitsForItsCurrentTargetOnASignalAndNothingElseDoes) {
  const mtcal::testing::TempDir dir;
  const std::string nowhere = dir.file("no/such/folder/store.sqlite"), plan = dir.file("missing.json");
  const std::vector<std::pair<std::vector<std::string>, bool>> commands = {
      {{"run", "linear", plan}, true},
      {{"run", "ballbar", plan}, true},
      {{"run", "est", plan}, true},
      {{"run", "gantry", plan}, true},
      {{"gantry", "run", plan}, true},
      {{"run", "thermal", plan}, true},
      {{"resume", "1"}, true},
      {{"demo"}, true},
      {{"serve", "--token-file", dir.file("missing.token")}, true},
      {{"backup", dir.file("copy.sqlite")}, true},
      {{"runs"}, false},
      {{"show", "1"}, false},
      {{"import", "linear", plan}, false},
      {{"diagnose", "1"}, false},
      {{"gantry", "evaluate", plan}, false},
      {{"thermal", "fit", "1", "--target", "spindle_z_um"}, false},
  };
  for (const auto& [command, waits] : commands) {
    std::vector<std::string> args = {"--db", nowhere};
    args.insert(args.end(), command.begin(), command.end());
    SCOPED_TRACE(fmt::format("{}", fmt::join(args, " ")));
    std::ostringstream out, err;
    std::istringstream in;
    std::atomic<bool> stop{false}, stop_awaited{!waits};  // the opposite, so that it must be set
    // Each fails at once, past the parsing (were it to run, the demo would run whole here).
    EXPECT_NE(app::runCli(args, out, err, &stop, &in, &stop_awaited), 0);
    EXPECT_EQ(err.str().find("(mtcal help"), std::string::npos) << "not past the parsing: " << err.str();
    EXPECT_EQ(stop_awaited.load(), waits) << err.str();
  }
}

TEST(SurviveCli, AReadOnlyArchiveIsListedShownAndAnalysedButNotWritten) {
  const mtcal::testing::TempDir dir;
  const auto folder = dir.path() / "quality";
  std::filesystem::create_directories(folder);
  const std::string db = (folder / "archive.sqlite").string();
  const std::string csv = std::string(MTCAL_TEST_DATA_DIR) + "/linear_deviation.csv";
  auto r = cli({"--db", db, "import", "linear", csv});
  ASSERT_EQ(r.code, 0) << r.err;
  // Analysed twice: one stored result.
  ASSERT_EQ(cli({"--db", db, "analyze", "iso230-2", "1"}).code, 0);
  ASSERT_EQ(cli({"--db", db, "analyze", "iso230-2", "1"}).code, 0);
  EXPECT_EQ(runOf(db, 1)["results"].size(), 1u);
  ASSERT_EQ(::chmod(db.c_str(), 0444), 0);
  ASSERT_EQ(::chmod(folder.c_str(), 0555), 0);
  const std::string problem = mtcal::testing::inChildProcess(
      [&]() -> std::string {
        auto c = cli({"--db", db, "runs"});
        if (c.code != 0 || c.out.find("linear") == std::string::npos) return "runs: " + c.err;
        c = cli({"--db", db, "show", "1"});
        if (c.code != 0 || c.out.find("iso230-2") == std::string::npos) return "show: " + c.err + c.out;
        c = cli({"--db", db, "--json", "analyze", "iso230-2", "1"});
        if (c.code != 0 || nlohmann::json::parse(c.out)["targets"] < 1) return "analyze: " + c.err;
        // Stored already: no warning that it is not. Another analysis: shown, said not stored.
        if (c.err.find("not stored") != std::string::npos) return "analyze, stored already: " + c.err;
        c = cli({"--db", db, "analyze", "linear", "1", "--standard", "vdi3441"});
        if (c.code != 0 || c.err.find("is shown, not stored") == std::string::npos) return "analyze vdi3441: " + c.err;
        c = cli({"--db", db, "import", "linear", csv});
        if (c.code == 0 || c.err.find("is read-only") == std::string::npos) return "import: " + c.err;
        return {};
      },
      mtcal::testing::ChildUser::kUnprivileged);
  EXPECT_EQ(problem, "");
  std::vector<std::string> files;
  for (const auto& f : std::filesystem::directory_iterator(folder)) files.push_back(f.path().filename().string());
  EXPECT_EQ(files, std::vector<std::string>{"archive.sqlite"});
  ASSERT_EQ(::chmod(folder.c_str(), 0755), 0);
}

}  // namespace
}  // namespace mtcal::app
