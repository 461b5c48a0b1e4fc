// Fuzz target of the thermal import (acquisition/thermal_data.h, `mtcal import thermal`): any
// text as a data logger's CSV export, read with the default options and with a displacement
// column named by --target, must parse or throw InputError.

#include <cstddef>
#include <cstdint>
#include <sstream>
#include <string>

#include "fuzz_support.h"
#include "mtcal/acquisition/thermal_data.h"
#include "mtcal/error.h"

namespace acq = mtcal::acquisition;
using mtcal::InputError;
using mtcal::fuzz::refused;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string csv(mtcal::fuzz::text(data, size));
  for (const char* target : {"", "drift"}) {
    acq::ThermalImportOptions options;
    options.target = target;
    std::istringstream in(csv);
    refused<InputError>([&] { acq::parseThermalCsv(in, "fuzz.csv", options); });
  }
  return 0;
}
