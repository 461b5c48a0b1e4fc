#include "mtcal/mocks/gcode_player.h"

#include <cctype>
#include <charconv>
#include <cmath>
#include <memory>
#include <numbers>
#include <optional>
#include <sstream>
#include <thread>
#include <utility>

#include "mtcal/error.h"

namespace mtcal::mocks {
namespace {

struct Word {
  char letter;
  double number;
};

std::vector<Word> words(const std::string& text, int line) {
  std::vector<Word> out;
  std::size_t i = 0;
  while (i < text.size()) {
    const char c = static_cast<char>(std::toupper(static_cast<unsigned char>(text[i])));
    if (std::isspace(static_cast<unsigned char>(c))) {
      ++i;
      continue;
    }
    if (!std::isalpha(static_cast<unsigned char>(c))) {
      throw InputError("line " + std::to_string(line) + ": unexpected '" + std::string(1, text[i]) + "'");
    }
    std::size_t j = i + 1;
    while (j < text.size() &&
           (std::isdigit(static_cast<unsigned char>(text[j])) || text[j] == '.' || text[j] == '-' || text[j] == '+')) {
      ++j;
    }
    double value = 0.0;
    const char* begin = text.data() + i + 1;
    if (*begin == '+') ++begin;
    auto [ptr, ec] = std::from_chars(begin, text.data() + j, value);
    if (ec != std::errc() || ptr != text.data() + j) {
      throw InputError("line " + std::to_string(line) + ": '" + text.substr(i, j - i) +
                       "' is not a word with a number");
    }
    out.push_back({c, value});
    i = j;
  }
  return out;
}

/// Waits until the world reaches `world_s` or `stop` is set. @return reached
bool reach(const WorldClock& clock, double world_s, const std::atomic<bool>* stop) {
  while (!clock.waitUntil(world_s, std::chrono::steady_clock::now() + std::chrono::milliseconds(5))) {
    if (stop && stop->load()) return false;
  }
  return true;
}

/// Executes the blocks from `start_s`, holding the world at each block until it is executed
/// (`hold` is at `start_s` already).
void execute(VirtualMachine& machine, const std::vector<GcodeBlock>& blocks, double start_s, WorldClock::Hold& hold,
             const std::atomic<bool>* stop) {
  double block_s = start_s;  // world time of the next block
  for (const auto& b : blocks) {
    if (!reach(machine.clock(), block_s, stop)) return;
    switch (b.kind) {
      case GcodeBlock::Kind::kMove:
        block_s = machine.moveTo(b.axis, b.value);
        break;  // now is block_s: the world waited here
      case GcodeBlock::Kind::kDwell:
        block_s += b.value;
        break;
      case GcodeBlock::Kind::kContour:
        block_s = machine.followPath(*b.path).second;
        break;
      case GcodeBlock::Kind::kEnd:
        return;
    }
    hold.moveTo(block_s);
  }
  reach(machine.clock(), block_s, stop);  // the last block done
}

}  // namespace

std::vector<GcodeBlock> parseGcode(const std::string& program) {
  std::vector<GcodeBlock> blocks;
  std::istringstream in(program);
  std::string raw;
  int line = 0;
  std::optional<double> position[3];  // where the program has put each axis so far
  std::optional<double> feed;         // F, modal
  processing::Plane plane = processing::Plane::kXY;
  bool contour_open = false;  // the last block is a contour the next arc continues
  while (std::getline(in, raw)) {
    ++line;
    std::string text;
    int depth = 0;
    for (char c : raw) {
      if (c == ';') break;
      if (c == '(') ++depth;
      if (depth == 0 && c != '%') text += c;
      if (c == ')' && depth > 0) --depth;
    }
    const auto ws = words(text, line);
    if (ws.empty()) continue;
    const int code = static_cast<int>(ws[0].number);
    const std::string where = "line " + std::to_string(line) + ": ";
    for (const auto& w : ws)
      if (w.letter == 'F') feed = w.number;
    if (ws[0].letter == 'G' && (code == 0 || code == 1)) {
      contour_open = false;
      for (std::size_t k = 1; k < ws.size(); ++k) {
        const char l = ws[k].letter;
        if (l == 'X' || l == 'Y' || l == 'Z') {
          const Axis axis = parseAxis(std::string(1, l));
          blocks.push_back({line, GcodeBlock::Kind::kMove, axis, ws[k].number, nullptr});
          position[static_cast<int>(axis)] = ws[k].number;
        } else if (l != 'F') {
          throw InputError(where + "word " + std::string(1, l) + " is not supported in a move");
        }
      }
    } else if (ws[0].letter == 'G' && (code == 2 || code == 3)) {
      const auto a = processing::planeAxes(plane);
      if (!position[0] || !position[1] || !position[2])
        throw InputError(where + "an arc needs the position of X, Y and Z before it (a G0 to them first)");
      if (!feed || !(*feed > 0.0)) throw InputError(where + "an arc needs a feed (F > 0)");
      const Eigen::Vector3d start(*position[0], *position[1], *position[2]);
      Eigen::Vector3d end = start, centre = start;
      for (std::size_t k = 1; k < ws.size(); ++k) {
        const char l = ws[k].letter;
        if (l == 'X' || l == 'Y' || l == 'Z') {
          end(l - 'X') = ws[k].number;
        } else if (l == 'I' || l == 'J' || l == 'K') {
          centre(l - 'I') += ws[k].number;
        } else if (l != 'F') {
          throw InputError(where + "word " + std::string(1, l) + " is not supported in an arc");
        }
      }
      if (end(a.normal) != start(a.normal) || centre(a.normal) != start(a.normal))
        throw InputError(where + "a helix (a move across the arc's plane) is not supported");
      const double r0 = std::hypot(start(a.first) - centre(a.first), start(a.second) - centre(a.second));
      const double r1 = std::hypot(end(a.first) - centre(a.first), end(a.second) - centre(a.second));
      if (!(r0 > 1e-6) || std::abs(r0 - r1) > 1e-3)
        throw InputError(where + "the arc's start and end are not on one circle about its centre (I, J, K)");
      const double angle0 = std::atan2(start(a.second) - centre(a.second), start(a.first) - centre(a.first));
      const double angle1 = std::atan2(end(a.second) - centre(a.second), end(a.first) - centre(a.first));
      // G3 turns counter-clockwise seen from the plane's normal, G2 clockwise; a full turn when
      // the end is the start.
      double sweep = code == 3 ? angle1 - angle0 : angle0 - angle1;
      while (sweep <= 1e-9) sweep += 2.0 * std::numbers::pi;
      if (code == 2) sweep = -sweep;
      if (!contour_open) {
        blocks.push_back(
            {line, GcodeBlock::Kind::kContour, Axis::kX, 0.0, std::make_shared<processing::ContourPath>(start)});
      }
      blocks.back().path->arc(centre, plane, sweep, *feed);
      contour_open = true;
      for (int i = 0; i < 3; ++i) position[i] = blocks.back().path->end()(i);
    } else if (ws[0].letter == 'G' && code == 4) {
      contour_open = false;
      if (ws.size() != 2 || (ws[1].letter != 'P' && ws[1].letter != 'X') || ws[1].number < 0) {
        throw InputError(where + "a dwell is G4 P<seconds> or G04 X<seconds>");
      }
      blocks.push_back({line, GcodeBlock::Kind::kDwell, Axis::kX, ws[1].number, nullptr});
    } else if (ws[0].letter == 'M' && (code == 30 || code == 2)) {
      blocks.push_back({line, GcodeBlock::Kind::kEnd, Axis::kX, 0.0, nullptr});
    } else if (ws[0].letter == 'G' &&
               (code == 17 || code == 18 || code == 19 || code == 21 || code == 90 || code == 94)) {
      for (const auto& w : ws) {
        const int c = static_cast<int>(w.number);
        if (w.letter != 'G' || (c != 17 && c != 18 && c != 19 && c != 21 && c != 90 && c != 94)) {
          throw InputError(where + "only G17, G18, G19, G21, G90 and G94 may share a block");
        }
        if (c == 17) plane = processing::Plane::kXY;
        if (c == 18) plane = processing::Plane::kZX;
        if (c == 19) plane = processing::Plane::kYZ;
      }
    } else {
      throw InputError(where + std::string(1, ws[0].letter) + std::to_string(code) +
                       " is not supported (G0, G1, G2, G3, G4, G17, G18, G19, G21, G90, G94, M30)");
    }
  }
  return blocks;
}

void runGcode(VirtualMachine& machine, const std::vector<GcodeBlock>& blocks, const std::atomic<bool>* stop) {
  const double start_s = machine.clock().nowS();
  WorldClock::Hold hold(machine.clock(), start_s);
  execute(machine, blocks, start_s, hold, stop);
}

CncProgramRun::CncProgramRun(VirtualMachine& machine, std::vector<GcodeBlock> program) {
  // The hold is placed here, at cycle start, before the caller goes on: the world cannot
  // pass the program's start while its thread gets going.
  const double start_s = machine.clock().nowS();
  auto hold = std::make_unique<WorldClock::Hold>(machine.clock(), start_s);
  thread_ = std::thread([this, &machine, program = std::move(program), start_s, hold = std::move(hold)] {
    try {
      execute(machine, program, start_s, *hold, &stop_);
    } catch (...) {
      error_ = std::current_exception();
    }
  });
}

CncProgramRun::~CncProgramRun() {
  stop_ = true;
  if (thread_.joinable()) thread_.join();
}

void CncProgramRun::finish() {
  stop_ = true;
  if (thread_.joinable()) thread_.join();
  if (error_) std::rethrow_exception(std::exchange(error_, nullptr));
}

}  // namespace mtcal::mocks
