// Fuzz target of the circle import (acquisition/circle_measurements.h, `mtcal import
// circle`): any text as another program's circular test export, imported into an in-memory
// archive, must be stored or refused with InputError. The import only reads a path: the input
// goes through a scratch file.

#include <spdlog/spdlog.h>

#include <cstddef>
#include <cstdint>
#include <memory>

#include "fuzz_support.h"
#include "mtcal/acquisition/circle_measurements.h"
#include "mtcal/error.h"
#include "mtcal/storage/store.h"

namespace acq = mtcal::acquisition;
using mtcal::InputError;
using mtcal::fuzz::refused;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static mtcal::fuzz::ScratchFile file("circle.csv");
  static std::unique_ptr<mtcal::storage::Store> store;
  static int inputs = 0;
  if (inputs == 0) spdlog::set_level(spdlog::level::off);  // the archive's migration messages
  // A fresh archive now and then, so that what was imported does not pile up in memory.
  if (inputs++ % 1000 == 0) store = std::make_unique<mtcal::storage::Store>(":memory:");
  acq::CircleImportOptions options;
  options.radius_mm = 100.0;
  const auto& path = file.write(data, size);
  refused<InputError>([&] { acq::importCircleCsv(*store, path, options); });
  return 0;
}
