#include <csignal>
#include <iostream>

#include "mtcal/app/cli.h"
#include "mtcal/services/memory.h"

namespace {
std::atomic<bool> g_stop{false};
extern "C" void onSignal(int) { g_stop = true; }
}  // namespace

int main(int argc, char** argv) {
  mtcal::services::keepFreedMemoryForReuse();
  // Ctrl-C (or SIGTERM, SIGHUP) ends a run cleanly after the current target: it is stored and marked interrupted.
  std::signal(SIGINT, onSignal);
  std::signal(SIGTERM, onSignal);
  std::signal(SIGHUP, onSignal);  // the terminal went away (a dropped SSH session)
  std::vector<std::string> args(argv + 1, argv + argc);
  return mtcal::app::runCli(args, std::cout, std::cerr, &g_stop, &std::cin);
}
