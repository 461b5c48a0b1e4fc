#pragma once
// The standard output of a shell command (the tools the tests read back: chromium, pdftotext).

#include <cstdio>
#include <string>

namespace mtcal::testing {

/// What `command` printed on stdout; empty when it could not run.
inline std::string commandOutput(const std::string& command) {
  std::string out;
  if (FILE* p = popen(command.c_str(), "r")) {
    char buffer[4096];
    while (const auto n = fread(buffer, 1, sizeof buffer, p)) out.append(buffer, n);
    pclose(p);
  }
  return out;
}

}  // namespace mtcal::testing
