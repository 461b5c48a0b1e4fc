#include "mtcal/acquisition/gcode.h"

#include <fmt/format.h>

#include "mtcal/error.h"

namespace mtcal::acquisition {

std::string gcodeDwell(const std::string& dialect, double seconds) {
  if (dialect == "iso") return fmt::format("G4 P{:.3f}", seconds);
  if (dialect == "fanuc") return fmt::format("G04 X{:.3f}", seconds);
  throw InputError("G-code dialect '" + dialect + "': not known (iso or fanuc)");
}

}  // namespace mtcal::acquisition
