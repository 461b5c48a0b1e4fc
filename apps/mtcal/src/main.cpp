#include <atomic>
#include <csignal>
#include <cstdlib>
#include <iostream>

#include "mtcal/app/cli.h"
#include "mtcal/services/memory.h"
#include "mtcal/services/report.h"

namespace {
std::atomic<bool> g_stop{false};
std::atomic<bool> g_stop_awaited{false};  // the command ends cleanly on g_stop (a run)
// A run ends cleanly after the current target; any other command (an import waiting for a FIFO's
// writer, a diagnosis) ends at once, as does a second signal during a run.
extern "C" void onSignal(int signal) {
  if (g_stop_awaited && !g_stop.exchange(true)) return;
  mtcal::services::stopPdfRendering();  // Chromium prints in a process group of its own
  std::_Exit(128 + signal);
}
}  // namespace

int main(int argc, char** argv) {
  mtcal::services::keepFreedMemoryForReuse();
  // Ctrl-C (or SIGTERM, SIGHUP) ends a run cleanly after the current target: it is stored and
  // marked interrupted (a second one ends it at once). Any other command it ends at once.
  std::signal(SIGINT, onSignal);
  std::signal(SIGTERM, onSignal);
  std::signal(SIGHUP, onSignal);  // the terminal went away (a dropped SSH session)
  std::vector<std::string> args(argv + 1, argv + argc);
  return mtcal::app::runCli(args, std::cout, std::cerr, &g_stop, &std::cin, &g_stop_awaited);
}
