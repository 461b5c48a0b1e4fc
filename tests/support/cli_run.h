#pragma once
// Runs the mtcal command line in-process and keeps what it printed.

#include <sstream>
#include <string>
#include <vector>

#include "mtcal/app/cli.h"

namespace mtcal::testing {

struct CliRun {
  int code;
  std::string out, err;
};

/// `input`: what the operator types at prompts.
inline CliRun cli(const std::vector<std::string>& args, const std::string& input = "") {
  std::ostringstream out, err;
  std::istringstream in(input);
  const int code = app::runCli(args, out, err, nullptr, &in);
  return {code, out.str(), err.str()};
}

}  // namespace mtcal::testing
