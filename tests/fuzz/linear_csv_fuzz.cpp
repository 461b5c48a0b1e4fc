// Fuzz target of the linear import (acquisition/import_linear.h, `mtcal import linear`): any
// text as another program's CSV export, read as compensated positions and as raw laser
// readings (--raw: the air index from the environment columns), must parse or throw
// InputError.

#include <cstddef>
#include <cstdint>
#include <sstream>
#include <string>

#include "fuzz_support.h"
#include "mtcal/acquisition/import_linear.h"
#include "mtcal/error.h"

namespace acq = mtcal::acquisition;
using mtcal::InputError;
using mtcal::fuzz::refused;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string csv(mtcal::fuzz::text(data, size));
  for (const bool raw : {false, true}) {
    acq::LinearImportOptions options;
    options.raw = raw;
    std::istringstream in(csv);
    refused<InputError>([&] { acq::parseLinearCsv(in, "fuzz.csv", options); });
  }
  return 0;
}
