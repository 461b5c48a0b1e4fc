#pragma once
// Runs a reference implementation (a numpy script in bench/) on an input written to a
// temporary file and returns the JSON object it prints (discarded when it did not run).

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

inline nlohmann::json runPython(const std::string& script, const nlohmann::json& input, const std::string& args) {
  const auto path = std::filesystem::temp_directory_path() / ("mtcal_bench_" + script + ".json");
  std::ofstream(path) << input.dump();
  // Debian's interpreter: python3-numpy (scripts/setup) belongs to it, whatever else is on PATH.
  const std::string command =
      std::string("/usr/bin/python3 ") + MTCAL_SOURCE_DIR + "/bench/" + script + " " + path.string() + " " + args;
  std::unique_ptr<FILE, int (*)(FILE*)> pipe(popen(command.c_str(), "r"), pclose);
  std::string out;
  char buffer[4096];
  while (pipe && std::fgets(buffer, sizeof buffer, pipe.get())) out += buffer;
  return nlohmann::json::parse(out, nullptr, false);
}
