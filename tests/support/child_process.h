#pragma once
// Runs test code in a child process: what another station, a killed acquisition or a quality
// engineer without write permission does, done for real. The child reports what went wrong in
// words through a pipe (gtest's assertions do not cross processes); the parent asserts on it.

#include <pwd.h>
#include <sys/wait.h>
#include <unistd.h>

#include <functional>
#include <string>

namespace mtcal::testing {

/// Who the child runs as.
enum class ChildUser {
  kSame,          ///< this test's user
  kUnprivileged,  ///< nobody when the tests run as root, so that file permissions apply
};

/// Runs `body` in a child and waits for it. @return what body returned (empty: all was well),
/// or why the child failed (an exception, a crash).
inline std::string inChildProcess(const std::function<std::string()>& body, ChildUser user = ChildUser::kSame) {
  int pipe_fds[2];
  if (::pipe(pipe_fds) != 0) return "pipe failed";
  const pid_t pid = ::fork();
  if (pid < 0) return "fork failed";
  if (pid == 0) {
    ::close(pipe_fds[0]);
    std::string message;
    try {
      if (user == ChildUser::kUnprivileged && ::geteuid() == 0) {
        const passwd* nobody = ::getpwnam("nobody");
        if (!nobody || ::setgid(nobody->pw_gid) != 0 || ::setuid(nobody->pw_uid) != 0)
          throw std::runtime_error("cannot become nobody");
      }
      message = body();
    } catch (const std::exception& e) {
      message = std::string("exception: ") + e.what();
    }
    const char* p = message.data();
    std::size_t left = message.size();
    while (left > 0) {
      const auto n = ::write(pipe_fds[1], p, left);
      if (n <= 0) break;
      p += n;
      left -= static_cast<std::size_t>(n);
    }
    ::_exit(0);
  }
  ::close(pipe_fds[1]);
  std::string message;
  char buffer[512];
  for (ssize_t n; (n = ::read(pipe_fds[0], buffer, sizeof buffer)) > 0;)
    message.append(buffer, static_cast<std::size_t>(n));
  ::close(pipe_fds[0]);
  int status = 0;
  ::waitpid(pid, &status, 0);
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) message += " (child ended abnormally)";
  return message;
}

}  // namespace mtcal::testing
