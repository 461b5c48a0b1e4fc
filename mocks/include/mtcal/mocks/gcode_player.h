#pragma once
// A CNC control for the virtual machine: executes a part program (the subset mtcal writes)
// in world time, so plans that a real machine runs by itself can be rehearsed and tested.
// Supported: G0/G1 with X/Y/Z (absolute mm, feed ignored: the machine's own rapid is used),
// G2/G3 arcs with I/J/K centre offsets in the plane of G17/G18/G19 at their F feed (a run of
// arcs is interpolated as one contour, as a CNC's look-ahead does, with the machine's servo
// dynamics), G4 P<s> and G04 X<s> dwells, G21, G90, G94, M30, comments in parentheses or after ';'.

#include <atomic>
#include <exception>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "mtcal/mocks/virtual_machine.h"

namespace mtcal::mocks {

struct GcodeBlock {
  int line = 0;
  enum class Kind { kMove, kDwell, kEnd, kContour } kind = Kind::kMove;
  Axis axis = Axis::kX;
  double value = 0.0;                             ///< position (mm) or dwell (s)
  std::shared_ptr<processing::ContourPath> path;  ///< a contour: consecutive arcs
};

/// Parses a program. @throws InputError "line N: why" for anything outside the subset.
std::vector<GcodeBlock> parseGcode(const std::string& program);

/// Runs the blocks on the machine from now on its world clock; returns at M30, at the end of
/// the program or when `stop` becomes true. Each block is executed at its world time (the
/// world waits there for it), so the program's moves fall at the times the program gives
/// whatever the host's load. @throws InputError for a move outside the travel.
void runGcode(VirtualMachine& machine, const std::vector<GcodeBlock>& blocks, const std::atomic<bool>* stop = nullptr);

/// The virtual CNC running a part program in a thread of its own, as a real CNC runs it
/// beside mtcal. Construction is cycle start: the program starts at the world time of that
/// moment. Destruction stops the program and waits for its thread.
class CncProgramRun {
 public:
  CncProgramRun(VirtualMachine& machine, std::vector<GcodeBlock> program);
  ~CncProgramRun();
  CncProgramRun(const CncProgramRun&) = delete;
  CncProgramRun& operator=(const CncProgramRun&) = delete;
  /// Stops the program where it is, waits for its thread. @throws what the program threw
  void finish();

 private:
  std::atomic<bool> stop_{false};
  std::exception_ptr error_;
  std::thread thread_;
};

}  // namespace mtcal::mocks
