// Runs a fuzz target without libFuzzer, so the suite exercises every target on every build
// (docs/fuzzing.md): every file of the corpus directories, every file of the regressions
// directory (inputs that once failed; the directory may be missing), then seeded mutations of
// all of them (bit flips, byte changes, insertions, truncations, splices of 1..3 inputs).
//
//   TARGET_corpus [--mutations N] [--seed S] [--regressions DIR] CORPUS_DIR...
//
// An input that crashes the target, or makes it throw what it must not, ends the run: the
// input is named on stderr and written to TARGET-failure.bin in the working directory, to be
// replayed (`TARGET_corpus DIR_WITH_IT`) or kept under tests/fuzz/regressions/TARGET/.

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <csignal>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <string>
#include <typeinfo>
#include <vector>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size);

namespace {

namespace fs = std::filesystem;
using Bytes = std::vector<std::uint8_t>;

struct Input {
  std::string origin;  ///< the file, or the mutation's number
  Bytes bytes;
};

// What is running, for the failure handlers (written before each run, read only there).
const Bytes* g_current = nullptr;
std::string g_origin;
std::string g_failure_file;

void saveCurrent() {
  if (g_current == nullptr) return;
  // Only async-signal-safe calls: this also runs from a signal handler.
  const int fd = ::open(g_failure_file.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  if (fd < 0) return;
  std::size_t done = 0;
  while (done < g_current->size()) {
    const auto n = ::write(fd, g_current->data() + done, g_current->size() - done);
    if (n <= 0) break;
    done += static_cast<std::size_t>(n);
  }
  ::close(fd);
}

void say(const char* text) {
  const auto ignored = ::write(STDERR_FILENO, text, std::strlen(text));
  (void)ignored;
}

void onSignal(int sig) {
  say("\nfailing input: ");
  say(g_origin.c_str());
  say("\nwritten to ");
  say(g_failure_file.c_str());
  say("\n");
  saveCurrent();
  g_current = nullptr;
  std::signal(sig, SIG_DFL);
  std::raise(sig);
}

void onTerminate() {
  std::fprintf(stderr, "\nan exception escaped the fuzz target");
  if (const auto e = std::current_exception()) {
    try {
      std::rethrow_exception(e);
    } catch (const std::exception& x) {
      std::fprintf(stderr, " (%s): %s", typeid(x).name(), x.what());
    } catch (...) {
      std::fprintf(stderr, " (not a std::exception)");
    }
  }
  std::fprintf(stderr, "\n");
  std::fflush(stderr);
  std::abort();  // onSignal names and saves the input
}

[[noreturn]] void usage(const char* why) {
  std::fprintf(stderr, "%s\nusage: TARGET_corpus [--mutations N] [--seed S] [--regressions DIR] CORPUS_DIR...\n", why);
  std::exit(2);
}

/// Every regular file of `dir`, sorted by name (the same order on every machine).
std::vector<Input> readDirectory(const fs::path& dir) {
  std::vector<fs::path> paths;
  for (const auto& entry : fs::directory_iterator(dir)) {
    if (entry.is_regular_file() && entry.path().filename().string()[0] != '.') paths.push_back(entry.path());
  }
  std::sort(paths.begin(), paths.end());
  std::vector<Input> out;
  for (const auto& p : paths) {
    std::ifstream in(p, std::ios::binary);
    out.push_back({p.string(), Bytes(std::istreambuf_iterator<char>(in), {})});
    if (!in.good() && !in.eof()) usage(("cannot read " + p.string()).c_str());
  }
  return out;
}

void run(const Input& input) {
  g_origin = input.origin;
  g_current = &input.bytes;
  LLVMFuzzerTestOneInput(input.bytes.data(), input.bytes.size());
  g_current = nullptr;
}

Bytes mutate(const std::vector<Input>& seeds, std::mt19937_64& rng) {
  Bytes input;
  const int pieces = 1 + static_cast<int>(rng() % 3);
  for (int p = 0; p < pieces; ++p) {
    const auto& s = seeds[rng() % seeds.size()].bytes;
    if (pieces == 1 || s.empty()) {
      input.insert(input.end(), s.begin(), s.end());
    } else {  // a splice: a random piece of the seed
      const auto from = static_cast<long>(rng() % s.size());
      const auto to = from + static_cast<long>(rng() % (s.size() - static_cast<std::size_t>(from) + 1));
      input.insert(input.end(), s.begin() + from, s.begin() + to);
    }
  }
  const int mutations = static_cast<int>(rng() % 6);
  for (int m = 0; m < mutations && !input.empty(); ++m) {
    switch (rng() % 4) {
      case 0:
        input[rng() % input.size()] ^= static_cast<std::uint8_t>(1u << (rng() % 8));
        break;
      case 1:
        input.resize(rng() % input.size());
        break;
      case 2:
        input.insert(input.begin() + static_cast<long>(rng() % input.size()), static_cast<std::uint8_t>(rng()));
        break;
      default:
        input[rng() % input.size()] = static_cast<std::uint8_t>(rng());
        break;
    }
  }
  return input;
}

}  // namespace

int main(int argc, char** argv) {
  long mutations = 10000;
  std::uint64_t seed = 20261122;
  std::string regressions;
  std::vector<std::string> corpora;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    const auto value = [&]() -> std::string {
      if (i + 1 >= argc) usage((arg + " needs a value").c_str());
      return argv[++i];
    };
    if (arg == "--mutations") {
      mutations = std::strtol(value().c_str(), nullptr, 10);
    } else if (arg == "--seed") {
      seed = std::strtoull(value().c_str(), nullptr, 10);
    } else if (arg == "--regressions") {
      regressions = value();
    } else if (!arg.empty() && arg[0] == '-') {
      usage(("unknown option " + arg).c_str());
    } else {
      corpora.push_back(arg);
    }
  }
  if (corpora.empty()) usage("no corpus directory");

  const std::string target = fs::path(argv[0]).filename().string();
  g_failure_file = target + "-failure.bin";
  std::set_terminate(onTerminate);
  for (const int sig : {SIGABRT, SIGSEGV, SIGBUS, SIGFPE, SIGILL}) std::signal(sig, onSignal);

  std::vector<Input> seeds;
  for (const auto& dir : corpora) {
    if (!fs::is_directory(dir)) usage(("not a directory: " + dir).c_str());
    auto files = readDirectory(dir);
    seeds.insert(seeds.end(), files.begin(), files.end());
  }
  const std::size_t corpus_files = seeds.size();
  if (corpus_files == 0) usage("the corpus directories hold no file");
  if (!regressions.empty() && fs::is_directory(regressions)) {
    auto files = readDirectory(regressions);
    seeds.insert(seeds.end(), files.begin(), files.end());
  }

  for (const auto& s : seeds) run(s);
  std::mt19937_64 rng(seed);
  for (long i = 0; i < mutations; ++i)
    run({"mutation " + std::to_string(i) + " of seed " + std::to_string(seed), mutate(seeds, rng)});
  std::printf("%s: %zu corpus files, %zu regression inputs and %ld mutations ran without a failure\n", target.c_str(),
              corpus_files, seeds.size() - corpus_files, mutations);
  return 0;
}
