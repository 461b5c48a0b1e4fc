// HTML to PDF through headless Chromium, in a temporary directory removed after.

#include <fcntl.h>
#include <fmt/format.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <optional>
#include <sstream>
#include <thread>
#include <vector>

#include "mtcal/error.h"
#include "mtcal/services/report.h"
#include "mtcal/services/workshop.h"

extern char** environ;

namespace mtcal::services {
namespace {

namespace fs = std::filesystem;

/// A directory of our own under the system's temporary directory, removed with this object.
class TemporaryDirectory {
 public:
  TemporaryDirectory() {
    std::string pattern = (fs::temp_directory_path() / "mtcal-pdf-XXXXXX").string();
    if (!mkdtemp(pattern.data())) throw InputError("PDF: cannot make a temporary directory: " + pattern);
    path_ = pattern;
  }
  ~TemporaryDirectory() {
    std::error_code ignored;
    fs::remove_all(path_, ignored);
  }
  TemporaryDirectory(const TemporaryDirectory&) = delete;
  TemporaryDirectory& operator=(const TemporaryDirectory&) = delete;
  const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

std::string fileText(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

/// How long Chromium may take for a page: MTCAL_PDF_TIMEOUT_S, else 120 s.
double pdfTimeoutS() {
  const char* configured = std::getenv("MTCAL_PDF_TIMEOUT_S");
  if (!configured || !*configured) return 120.0;
  char* end = nullptr;
  const double seconds = std::strtod(configured, &end);
  if (*end != '\0' || !(seconds > 0.0 && seconds <= 86400.0))
    throw InputError(fmt::format("MTCAL_PDF_TIMEOUT_S='{}': must be seconds, > 0 and at most 86400", configured));
  return seconds;
}

/// The process group of the Chromium now printing (0: none), for stopPdfRendering.
std::atomic<pid_t> g_rendering_group{0};

/// Runs `argv` in a process group of its own with stdout and stderr to `log`, the whole group
/// killed after `timeout_s`, and whatever of it outlives its leader. @return its exit status
/// (-1: did not start; nullopt: killed at the timeout)
std::optional<int> run(const std::vector<std::string>& argv, const fs::path& log, double timeout_s) {
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0600);
  posix_spawn_file_actions_adddup2(&actions, STDOUT_FILENO, STDERR_FILENO);
  posix_spawn_file_actions_addopen(&actions, STDIN_FILENO, "/dev/null", O_RDONLY, 0);
  posix_spawnattr_t attributes;
  posix_spawnattr_init(&attributes);
  posix_spawnattr_setflags(&attributes, POSIX_SPAWN_SETPGROUP);
  posix_spawnattr_setpgroup(&attributes, 0);
  std::vector<char*> args;
  for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  pid_t pid = 0;
  const int started = posix_spawnp(&pid, args[0], &actions, &attributes, args.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  posix_spawnattr_destroy(&attributes);
  if (started != 0) return -1;
  g_rendering_group = pid;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  int status = 0;
  bool timed_out = false, lost = false;
  for (;;) {
    const pid_t done = waitpid(pid, &status, WNOHANG);
    if (done == pid) break;
    lost = done < 0 && errno != EINTR;  // not ours to wait for: stopped as at the timeout
    timed_out = std::chrono::steady_clock::now() >= deadline;
    if (lost || timed_out) {
      kill(-pid, SIGKILL);  // Chromium's helpers with it
      while (waitpid(pid, &status, 0) < 0 && errno == EINTR) {
      }
      break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  kill(-pid, SIGKILL);  // helpers that outlived their leader
  g_rendering_group = 0;
  if (timed_out) return std::nullopt;
  if (lost) return -1;
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

}  // namespace

std::string pdfOf(const std::string& html) {
  const char* configured = std::getenv("MTCAL_CHROMIUM");
  const std::string chromium = configured && *configured ? configured : "chromium";
  TemporaryDirectory dir;
  const fs::path page = dir.path() / "report.html", pdf = dir.path() / "report.pdf", log = dir.path() / "chromium.log";
  writeTextFile(page.string(), html);
  // No sandbox: it needs user namespaces that containers and root lack; the page is ours and
  // self-contained, and the proxy that leads nowhere keeps any request from leaving.
  const double timeout_s = pdfTimeoutS();
  const auto finished = run({chromium, "--headless", "--no-sandbox", "--disable-gpu", "--no-first-run",
                             "--disable-background-networking", "--disable-extensions", "--disable-sync",
                             "--proxy-server=127.0.0.1:9", "--user-data-dir=" + (dir.path() / "profile").string(),
                             "--no-pdf-header-footer", "--print-to-pdf=" + pdf.string(), "file://" + page.string()},
                            log, timeout_s);
  if (!finished) {
    throw InputError(
        fmt::format("PDF: {} made no PDF in {:g} s and was stopped (MTCAL_PDF_TIMEOUT_S gives it "
                    "longer); write .html instead",
                    chromium, timeout_s));
  }
  const int status = *finished;
  if (status == -1) {
    throw InputError(
        fmt::format("PDF: cannot start '{}' (install Debian's chromium, scripts/setup, or name it in "
                    "MTCAL_CHROMIUM); write .html instead",
                    chromium));
  }
  const std::string out = fs::exists(pdf) ? fileText(pdf) : "";
  if (status != 0 || !out.starts_with("%PDF-")) {
    std::string said = fileText(log);
    if (said.size() > 2000) said = said.substr(said.size() - 2000);
    throw InputError(fmt::format("PDF: {} exited with status {} without a PDF; it said:\n{}", chromium, status, said));
  }
  return out;
}

void printPdf(const std::string& html, const std::string& pdf_path) { writeTextFile(pdf_path, pdfOf(html)); }

void stopPdfRendering() noexcept {
  const pid_t group = g_rendering_group.load();
  if (group > 0) kill(-group, SIGKILL);
}

}  // namespace mtcal::services
