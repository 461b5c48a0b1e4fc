// Fuzz target of the CSV table reader every other CSV input goes through
// (acquisition/csv.h): any text read with the column sets the product asks for
// (circle export, probe readings, points to predict, cam profiles, ballbar length readings),
// must give the table or throw InputError.

#include <cstddef>
#include <cstdint>
#include <sstream>
#include <string>
#include <vector>

#include "fuzz_support.h"
#include "mtcal/acquisition/csv.h"
#include "mtcal/error.h"

namespace acq = mtcal::acquisition;
using mtcal::InputError;
using mtcal::fuzz::refused;

namespace {

struct Columns {
  std::vector<std::string> required, optional, text;
};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const std::vector<Columns> kUses = {
      {{"angle_deg", "deviation_um"}, {"time_s"}, {"direction"}},  // import circle
      {{"x_mm", "v1_um", "v2_um"}, {"v3_um"}, {}},                 // est
      {{"x_mm", "y_mm", "z_mm"}, {}, {}},                          // model predict --points
      {{"angle_deg", "radius_mm"}, {}, {}},                        // grind compensate, lift table
      {{"position", "pair", "delta_length_um"}, {}, {}},           // grind identify
  };
  const std::string csv(mtcal::fuzz::text(data, size));
  for (const auto& use : kUses) {
    std::istringstream in(csv);
    refused<InputError>([&] { acq::readColumnTable(in, "fuzz.csv", use.required, use.optional, use.text); });
  }
  return 0;
}
