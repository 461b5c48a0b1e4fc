// Fuzz target of the virtual machine descriptions (examples/machines/*.json, docs in
// examples/machines/README.md): any text read as a machine file (services::simulatedMachine,
// with and without --seed; services::machineKinematics, which also takes a kinematic
// description) and as a stored machine description (services::simulationFromDescription, the
// input alone and wrapped as {"simulation": ...}) must give a machine or throw InputError.
// The file readers only read a path: the input goes through a scratch file.

#include <cstddef>
#include <cstdint>
#include <string>

#include "fuzz_support.h"
#include "mtcal/error.h"
#include "mtcal/services/workshop.h"

namespace sv = mtcal::services;
using mtcal::InputError;
using mtcal::fuzz::refused;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static mtcal::fuzz::ScratchFile file("machine.json");
  const auto& path = file.write(data, size);
  for (const bool seeded : {false, true}) {
    sv::SimulationOptions options;
    options.machine_file = path;
    if (seeded) options.seed = 7;
    refused<InputError>([&] {
      const auto machine = sv::simulatedMachine(options);
      machine.name();
      machine.description();
    });
  }
  refused<InputError>([&] { sv::machineKinematics(path); });
  const std::string text(mtcal::fuzz::text(data, size));
  refused<InputError>([&] { sv::simulationFromDescription(text); });
  refused<InputError>([&] { sv::simulationFromDescription("{\"simulation\": " + text + "}"); });
  return 0;
}
