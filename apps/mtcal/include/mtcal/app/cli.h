#pragma once
// Entry point of the mtcal command line, callable in-process (tests use it exactly as the
// executable does). Exit codes: 0 ok, 1 runtime failure (device, storage), 2 bad input.

#include <atomic>
#include <istream>
#include <ostream>
#include <string>
#include <vector>

namespace mtcal::app {

/// Runs `mtcal ARGS...` (args exclude the program name). Writes results to `out` and
/// errors and progress to `err`. `stop` is set by the SIGINT handler of the executable.
/// `in`: the operator's answers to prompts (real-machine gantry runs); none: no prompts possible.
/// `stop_awaited` is set where the command ends cleanly on `stop` (a run, `resume`, `demo`,
/// `serve`, `gantry run`) or must not be cut short (`backup`): the executable's handler then
/// waits for it; any other command it ends at once.
int runCli(const std::vector<std::string>& args, std::ostream& out, std::ostream& err,
           const std::atomic<bool>* stop = nullptr, std::istream* in = nullptr,
           std::atomic<bool>* stop_awaited = nullptr);

}  // namespace mtcal::app
