// Fuzz target of the controllers' compensation table readers (processing/compensation_formats.h,
// `mtcal compensate --existing FILE`, `mtcal run linear --compensation FILE`): the first byte
// chooses the controller, the rest is its file. Any text must give a table or throw InputError;
// a table read must be one the virtual CNC can apply (checkTable) and, when the same controller
// can write it again, must read back from what it writes (the values to the file's resolution).
// The byte after the last controller chooses ISG's volumetric CSV (volumetric_compensation.h):
// a table read must write and read back with its rows and values.

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "fuzz_support.h"
#include "mtcal/error.h"
#include "mtcal/processing/compensation_formats.h"
#include "mtcal/processing/volumetric_compensation.h"

namespace pr = mtcal::processing;
using mtcal::InputError;
using mtcal::fuzz::refused;

namespace {

void mustHold(bool condition, const char* what) {
  if (condition) return;
  std::fprintf(stderr, "%s\n", what);
  std::abort();
}

/// The magnification (parameter 3623) of a FANUC file mtcal wrote.
double fanucMagnification(const std::string& file) {
  const auto at = file.find("N03623A");
  mustHold(at != std::string::npos, "a FANUC file without parameter 3623");
  return std::strtod(file.c_str() + file.find('P', at) + 1, nullptr);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const auto kNames = pr::controllerNames();
  if (size == 0) return 0;
  const auto text = mtcal::fuzz::text(data + 1, size - 1);
  const std::size_t choice = data[0] % (kNames.size() + 1);
  if (choice == kNames.size()) {
    refused<InputError>([&] {
      const auto table = pr::readIsgVolumetricCsv(text, "fuzz");
      std::string written;
      try {
        written = pr::writeIsgVolumetricCsv(table, "");
      } catch (const InputError&) {
        return;  // a name mtcal reads but has no model term for
      }
      const auto again = pr::readIsgVolumetricCsv(written, "fuzz: written");
      mustHold(again.records() == table.records(), "a written volumetric table reads back with other records");
    });
    return 0;
  }
  const auto& format = pr::controllerFormat(kNames[choice]);
  refused<InputError>([&] {
    const auto table = format.read(text, "fuzz");
    pr::checkTable(table, "fuzz: read");
    for (double x : {table.position.front() - 1.0, table.position.back() + 1.0})
      mustHold(std::isfinite(table.correctionUm(x, pr::Direction::kUp, format.rules)), "a correction is not finite");
    std::string written;
    try {
      written = format.write(table, {"X", 0, ""}).text;
    } catch (const InputError&) {
      return;  // a table the controller reads but mtcal would not write (e.g. too coarse for FANUC's +-7)
    }
    const auto again = format.read(written, "fuzz: written");
    mustHold(again.position.size() == table.position.size(), "a written table reads back with other entries");
    for (std::size_t i = 0; i < table.position.size(); ++i) {
      // Written to 1e-6 mm (0.001 um), or 0.1 um (TwinCAT CNC), or FANUC's unit (1 um times the
      // magnification it chose, the negative direction's reference value in 1 um); relative
      // for large values.
      const double resolution_um = format.name == "fanuc" ? fanucMagnification(written) / 2.0 + 0.5 : 0.051;
      const double tolerance = resolution_um + 1e-9 * std::abs(table.up_um[i]) + 1e-9 * std::abs(table.down_um[i]);
      mustHold(std::abs(again.up_um[i] - table.up_um[i]) <= tolerance &&
                   std::abs(again.down_um[i] - table.down_um[i]) <= tolerance,
               "a written table reads back with other values");
    }
  });
  return 0;
}
