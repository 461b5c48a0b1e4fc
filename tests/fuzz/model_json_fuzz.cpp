// Fuzz target of the model files and stored model parts (docs/multibody-model.md,
// docs/error-model.md): any text read as a machine's kinematic description
// (MultibodyModel::fromJson, `--machine MODEL.json`), as a stored error function
// (ErrorFunction::fromJson, evaluated over its nodes) and as a stored model extension
// (ModelExtension::fromJson, diagnosis) must give what it reads or throw InputError.

#include <cstddef>
#include <cstdint>

#include "fuzz_support.h"
#include "mtcal/error.h"
#include "mtcal/processing/diagnosis.h"
#include "mtcal/processing/error_model.h"
#include "mtcal/processing/multibody.h"

namespace pr = mtcal::processing;
using mtcal::InputError;
using mtcal::fuzz::refused;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto j = mtcal::fuzz::json(data, size);
  if (j.is_discarded()) return 0;  // refused with InputError before any parser runs
  refused<InputError>([&] { pr::MultibodyModel::fromJson(j, "fuzz.json"); });
  refused<InputError>([&] {
    const auto f = pr::ErrorFunction::fromJson("EXX", j);
    for (const double x : f.nodes()) {
      f.value(x);
      f.sigma(x);
    }
  });
  refused<InputError>([&] { pr::ModelExtension::fromJson(j); });
  return 0;
}
