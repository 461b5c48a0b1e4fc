// Fuzz target of the probe readings file (services/est.h readProbeCsv, `mtcal est FILE.csv`):
// any text read as two- and three-probe readings, and what it reads separated as the command
// does (two-probe, three-probe), must give a result or throw InputError. readProbeCsv only
// reads a path: the input goes through a scratch file.

#include <cstddef>
#include <cstdint>

#include "fuzz_support.h"
#include "mtcal/error.h"
#include "mtcal/services/est.h"

namespace sv = mtcal::services;
using mtcal::InputError;
using mtcal::fuzz::refused;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static mtcal::fuzz::ScratchFile file("est.csv");
  const auto& path = file.write(data, size);
  for (const bool three : {false, true}) {
    refused<InputError>([&] {
      const auto readings = sv::readProbeCsv(path, three);
      sv::EstMethod method;
      method.method = three ? "three-probe" : "two-probe";
      method.spacing_mm = 20.0;
      sv::separate(readings, method);
    });
  }
  return 0;
}
