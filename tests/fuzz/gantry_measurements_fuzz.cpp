// Fuzz target of the gantry measurement file (docs/gantry.md, `mtcal gantry evaluate
// FILE.json`): any text read as a measurement file, with its tracker_mpe, as
// services::evaluateGantryFile reads it, must give the measurements or throw InputError. What
// it reads must read back from its export (measurementsToJson: `mtcal export`).

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>

#include "fuzz_support.h"
#include "mtcal/acquisition/gantry_measurements.h"
#include "mtcal/acquisition/gantry_plan.h"
#include "mtcal/error.h"

namespace acq = mtcal::acquisition;
using mtcal::InputError;
using mtcal::fuzz::refused;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto j = mtcal::fuzz::json(data, size);
  if (j.is_discarded()) return 0;  // refused with InputError before any parser runs
  refused<InputError>([&] {
    const auto m = acq::measurementsFromJson(j, "fuzz.json");
    if (j.contains("tracker_mpe")) acq::trackerMpeFromJson(j["tracker_mpe"], "fuzz.json", "tracker_mpe");
    try {
      acq::measurementsFromJson(acq::measurementsToJson(m), "export");
    } catch (const InputError& e) {
      std::fprintf(stderr, "measurements that parsed do not read back from their export: %s\n", e.what());
      std::abort();
    }
  });
  return 0;
}
