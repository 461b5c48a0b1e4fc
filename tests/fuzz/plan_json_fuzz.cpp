// Fuzz target of the plan files (docs/plans.md): any text read as a linear, circle, EST,
// gantry and thermal plan must give a plan or throw InputError, in memory (fromJson, as the
// services read a plan file) and through the loaders that read a path (LinearPlan::load,
// EstPlan::load: `run linear`, `run est`), which parse the JSON themselves. A plan that parses
// must read back from its stored form (toJson), as a resumed run reads it.

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "fuzz_support.h"
#include "mtcal/acquisition/circle_plan.h"
#include "mtcal/acquisition/est_run.h"
#include "mtcal/acquisition/gantry_plan.h"
#include "mtcal/acquisition/linear_plan.h"
#include "mtcal/acquisition/thermal_run.h"
#include "mtcal/error.h"

namespace acq = mtcal::acquisition;
using mtcal::InputError;
using mtcal::fuzz::refused;

namespace {

template <typename Plan>
void parseAndReadBack(const nlohmann::json& j, const char* type) {
  refused<InputError>([&] {
    const auto plan = Plan::fromJson(j, "fuzz.json");
    try {
      Plan::fromJson(plan.toJson(), "stored plan");
    } catch (const InputError& e) {
      std::fprintf(stderr, "a parsed %s plan does not read back from its toJson: %s\n", type, e.what());
      std::abort();
    }
  });
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static mtcal::fuzz::ScratchFile file("plan.json");
  const auto j = mtcal::fuzz::json(data, size);
  if (!j.is_discarded()) {
    parseAndReadBack<acq::LinearPlan>(j, "linear");
    parseAndReadBack<acq::CirclePlan>(j, "circle");
    parseAndReadBack<acq::EstPlan>(j, "est");
    parseAndReadBack<acq::GantryPlan>(j, "gantry");
    parseAndReadBack<acq::ThermalPlan>(j, "thermal");
  }
  const auto& path = file.write(data, size);
  refused<InputError>([&] { acq::LinearPlan::load(path); });
  refused<InputError>([&] { acq::EstPlan::load(path); });
  return 0;
}
