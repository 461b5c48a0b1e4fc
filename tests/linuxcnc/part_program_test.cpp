// Every kind of part program mtcal writes, read to its end by LinuxCNC's own interpreter (rs274,
// Debian linuxcnc-uspace; no running LinuxCNC needed): the example plans of a linear run, a
// circular test, a thermal run and a gantry, and a plan whose name holds parentheses, which a
// comment may not (RS274/NGC, NIST IR 6556, 3.3.4: "Nested comment found").
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cstdlib>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "../support/temp_dir.h"
#include "mtcal/acquisition/csv.h"
#include "mtcal/services/plans.h"

namespace mtcal {
namespace {

struct Interpreted {
  int exit_code = -1;
  std::string output;
};

/// rs274 -g: the canonical machine calls of a program, or the interpreter's error.
Interpreted interpret(const std::string& program_path) {
  const std::string output_path = program_path + ".rs274";
  const std::string command = "rs274 -g '" + program_path + "' < /dev/null > '" + output_path + "' 2>&1";
  const int status = std::system(command.c_str());
  std::stringstream output;
  output << std::ifstream(output_path).rdbuf();
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, output.str()};
}

TEST(PartPrograms, LinuxCncsInterpreterReadsEachToItsEnd) {
  const mtcal::testing::TempDir dir;
  const std::string examples = MTCAL_EXAMPLES_DIR;
  auto named = acquisition::readJsonFile(examples + "/plans/x_axis_iso230-2.json");
  named["name"] = "X (after repair)";
  const std::string named_path = dir.file("named.json");
  std::ofstream(named_path) << named.dump();
  const std::vector<std::pair<std::string, std::string>> plans = {
      {examples + "/plans/x_axis_iso230-2.json", ""},
      {named_path, ""},
      {examples + "/plans/ballbar/circle_xy_100.json", ""},
      {examples + "/plans/thermal/quick-2h.json", ""},  // its name holds parentheses too
      {examples + "/plans/gantry/quick-6x2.json", examples + "/machines/gantry-drilling.json"}};
  int k = 0;
  for (const auto& [plan, machine] : plans) {
    const std::string program_path = dir.file("program" + std::to_string(++k) + ".ngc");
    std::ofstream(program_path) << services::partProgram(plan, machine).program;
    const auto read = interpret(program_path);
    EXPECT_EQ(read.exit_code, 0) << plan << ":\n" << read.output;
    EXPECT_NE(read.output.find("PROGRAM_END()"), std::string::npos) << plan << ":\n" << read.output;
    EXPECT_EQ(read.output.find("comment"), std::string::npos) << plan << ":\n" << read.output;
  }
}

}  // namespace
}  // namespace mtcal
