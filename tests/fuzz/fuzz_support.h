#pragma once
// What the fuzz targets share (docs/fuzzing.md): the input as text or JSON, a scratch file for
// the parsers that only read a path, and the one rule of every target: an input parses or is
// refused with the errors the parser documents. Nothing here catches std::exception: an
// exception of another type (nlohmann::json's, std::out_of_range ...) escapes the target and
// is a finding, as are crashes, hangs and sanitizer reports.

#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <string_view>

namespace mtcal::fuzz {

inline std::string_view text(const std::uint8_t* data, std::size_t size) {
  return {reinterpret_cast<const char*>(data), size};
}

/// The input as JSON the way the product reads a file (parse without exceptions): discarded
/// when it is not JSON, which the product refuses with InputError before any parser runs.
inline nlohmann::json json(const std::uint8_t* data, std::size_t size) {
  return nlohmann::json::parse(data, data + size, nullptr, false);
}

/// MTCAL_FUZZ_VERBOSE set: every refusal is printed (why a seed does not parse).
inline bool verbose() {
  static const bool kVerbose = std::getenv("MTCAL_FUZZ_VERBOSE") != nullptr;
  return kVerbose;
}

/// Runs `parse`, letting through only the error types it documents (mtcal error classes):
/// `refused<ProtocolError, DeviceError>([&] { parseX(line); })`. Anything else escapes.
template <typename F>
void refused(F&& parse) {
  parse();
}
template <typename First, typename... Rest, typename F>
void refused(F&& parse) {
  try {
    refused<Rest...>(parse);
  } catch (const First& e) {
    if (verbose()) std::fprintf(stderr, "refused: %s\n", e.what());
  }
}

/// A file in memory (/dev/shm) or else in the temporary directory, one per process (several
/// fuzzing jobs may run at once), rewritten with every input and removed at exit: for parsers
/// that only take a path. (Rewriting a file on disk costs about 1 ms here, 100 times the parse.)
/// A process that crashes leaves it: run_fuzzers.sh removes those of processes gone.
class ScratchFile {
 public:
  explicit ScratchFile(const std::string& name)
      : path_((directory() / ("mtcal-fuzz-" + std::to_string(::getpid()) + "-" + name)).string()) {}
  ~ScratchFile() {
    std::error_code ignored;
    std::filesystem::remove(path_, ignored);
  }
  ScratchFile(const ScratchFile&) = delete;
  ScratchFile& operator=(const ScratchFile&) = delete;

  /// Replaces the file's content. @return its path
  const std::string& write(const std::uint8_t* data, std::size_t size) {
    std::ofstream out(path_, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
    out.close();
    if (!out) std::abort();  // the target cannot run: say so rather than fuzz nothing
    return path_;
  }
  const std::string& path() const { return path_; }

 private:
  static std::filesystem::path directory() {
    if (std::getenv("TMPDIR") == nullptr && ::access("/dev/shm", W_OK) == 0) return "/dev/shm";
    return std::filesystem::temp_directory_path();
  }
  std::string path_;
};

}  // namespace mtcal::fuzz
