#include "mtcal/acquisition/gcode.h"

#include <fmt/format.h>

#include "mtcal/error.h"

namespace mtcal::acquisition {

std::string gcodeDwell(const std::string& dialect, double seconds) {
  if (dialect == "iso") return fmt::format("G4 P{:.3f}", seconds);
  if (dialect == "fanuc") return fmt::format("G04 X{:.3f}", seconds);
  throw InputError("G-code dialect '" + dialect + "': not known (iso or fanuc)");
}

std::string gcodeCommentText(std::string text) {
  for (char& c : text) {
    if (c == '(') c = '[';
    if (c == ')') c = ']';
    if (c == '\n' || c == '\r') c = ' ';
  }
  return text;
}

std::string gcodeDwellComment(const std::string& dialect) {
  if (dialect == "fanuc") return "(dwells are G04 X in seconds)\n";
  gcodeDwell(dialect, 0.0);  // a dialect not known is refused
  return "(dwells are G4 P in seconds, as LinuxCNC reads them; a control that reads G4 P in milliseconds, "
         "Fanuc-style, dwells a thousandth of that: run it there as G04 X in seconds)\n";
}

}  // namespace mtcal::acquisition
