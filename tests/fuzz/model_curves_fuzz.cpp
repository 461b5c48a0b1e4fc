// Fuzz target of the error curves import (acquisition/error_models.h parseErrorCurvesCsv,
// `mtcal model import CURVES.csv`): any text read as error curves, each curve fitted and the
// model built on the demo machine's kinematics as the import does, must give a model or throw
// InputError. A model it gives must read back from its stored form (modelOf: the functions'
// JSON), or `mtcal model predict` could not load what `model import` stored.

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "fuzz_support.h"
#include "mtcal/acquisition/error_models.h"
#include "mtcal/error.h"
#include "mtcal/mocks/virtual_machine.h"
#include "mtcal/processing/error_model.h"

namespace acq = mtcal::acquisition;
namespace pr = mtcal::processing;
using mtcal::InputError;
using mtcal::fuzz::refused;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const pr::MultibodyModel kMachine = mtcal::mocks::VirtualMachineConfig{}.kinematics();
  std::istringstream in{std::string(mtcal::fuzz::text(data, size))};
  refused<InputError>([&] {
    const auto curves = acq::parseErrorCurvesCsv(in, "fuzz.csv");
    std::vector<pr::ErrorFunction> functions;
    for (const auto& curve : curves) functions.push_back(pr::ErrorFunction::fit(curve, pr::ErrorFitOptions{}));
    const pr::ErrorModel model(kMachine, std::move(functions));
    model.workspaceCentre();
    for (const auto& f : model.functions()) {
      try {
        pr::ErrorFunction::fromJson(f.name(), nlohmann::json::parse(f.toJson().dump()));
      } catch (const InputError& e) {
        std::fprintf(stderr, "an imported error function does not read back: %s\n", e.what());
        std::abort();
      }
    }
  });
  return 0;
}
