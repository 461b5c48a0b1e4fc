#pragma once
// A real TCP server on 127.0.0.1 (an ephemeral port) that plays a script step by step:
// accept a connection, expect bytes, send bytes, keep silent until the test says go on,
// close. A step that never ran, or bytes that differ from what was expected, fail the test
// when the server is destroyed (after the code under test is done with it). Silence lasts
// until the test calls proceed(), not for a wall-clock time: a loaded machine cannot make the
// server speak before the test has seen its silence.

#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdint>
#include <string>
#include <thread>
#include <vector>

namespace mtcal::testing {

class ScriptedTcpServer {
 public:
  struct Step {
    enum class Kind { kAccept, kExpect, kSend, kSilence, kClose } kind;
    std::string bytes;
  };
  static Step accept() { return {Step::Kind::kAccept, {}}; }
  static Step expect(std::string bytes) { return {Step::Kind::kExpect, std::move(bytes)}; }
  static Step send(std::string bytes) { return {Step::Kind::kSend, std::move(bytes)}; }
  /// Silent until proceed() (or the end of the test).
  static Step silence() { return {Step::Kind::kSilence, {}}; }
  static Step close() { return {Step::Kind::kClose, {}}; }

  explicit ScriptedTcpServer(std::vector<Step> script) : script_(std::move(script)) {
    listener_ = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in addr{};
    addr.sin_family = AF_INET;
    addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    addr.sin_port = 0;
    if (::bind(listener_, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0 || ::listen(listener_, 4) != 0) {
      ADD_FAILURE() << "scripted server: cannot listen on 127.0.0.1";
    }
    socklen_t len = sizeof addr;
    ::getsockname(listener_, reinterpret_cast<sockaddr*>(&addr), &len);
    port_ = ntohs(addr.sin_port);
    thread_ = std::thread([this] {
      play();
      finished_ = true;
    });
  }
  ~ScriptedTcpServer() {
    stop_ = true;
    thread_.join();
    if (connection_ >= 0) ::close(connection_);
    ::close(listener_);
    if (!failure_.empty()) {
      ADD_FAILURE() << "scripted server: step " << steps_run_.load() + 1 << failure_;
    } else if (steps_run_.load() != script_.size()) {
      ADD_FAILURE() << "scripted server: step " << steps_run_.load() + 1 << " of " << script_.size() << " never ran";
    }
  }
  std::uint16_t port() const { return port_; }
  /// Ends the current (or next) silence.
  void proceed() { proceed_ = true; }
  std::size_t stepsRun() const { return steps_run_; }
  /// The script has ended: every step ran, or one failed.
  bool finished() const { return finished_; }

 private:
  // Waits for `fd` to be readable, up to 10 s, giving up when the server is stopped.
  bool readable(int fd) {
    for (int waited = 0; waited < 10000 && !stop_; waited += 20) {
      pollfd p{fd, POLLIN, 0};
      if (::poll(&p, 1, 20) > 0) return true;
    }
    return false;
  }
  void play() {
    for (const auto& step : script_) {
      switch (step.kind) {
        case Step::Kind::kAccept:
          if (!readable(listener_)) return;
          if (connection_ >= 0) ::close(connection_);
          connection_ = ::accept(listener_, nullptr, nullptr);
          break;
        case Step::Kind::kExpect: {
          std::string got;
          while (got.size() < step.bytes.size()) {
            if (!readable(connection_)) return;
            char buffer[512];
            const auto n = ::recv(connection_, buffer, std::min(sizeof buffer, step.bytes.size() - got.size()), 0);
            if (n <= 0) {
              failure_ = ": the client closed while '" + step.bytes + "' was expected";
              return;
            }
            got.append(buffer, static_cast<std::size_t>(n));
          }
          if (got != step.bytes) {
            failure_ = ": expected '" + step.bytes + "', got '" + got + "'";
            return;
          }
          break;
        }
        case Step::Kind::kSend:
          ::send(connection_, step.bytes.data(), step.bytes.size(), MSG_NOSIGNAL);
          break;
        case Step::Kind::kSilence:
          while (!proceed_.exchange(false) && !stop_) std::this_thread::sleep_for(std::chrono::milliseconds(2));
          break;
        case Step::Kind::kClose:
          ::close(connection_);
          connection_ = -1;
          break;
      }
      ++steps_run_;
    }
  }

  std::vector<Step> script_;
  int listener_ = -1, connection_ = -1;
  std::uint16_t port_ = 0;
  std::atomic<bool> stop_{false}, proceed_{false}, finished_{false};
  std::atomic<std::size_t> steps_run_{0};
  std::string failure_;
  std::thread thread_;
};

}  // namespace mtcal::testing
