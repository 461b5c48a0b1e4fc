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

inline CliRun cli(const std::vector<std::string>& args) {
  std::ostringstream out, err;
  const int code = app::runCli(args, out, err);
  return {code, out.str(), err.str()};
}

}  // namespace mtcal::testing
