#pragma once
// The measurements of gantry point accuracy runs: read from a stored run (its points and
// its expanded plan, gantry_run.h) and the measurement file exported from it and evaluated
// by `mtcal gantry evaluate` (docs/gantry.md).

#include <nlohmann/json_fwd.hpp>
#include <string>

#include "mtcal/acquisition/gantry_plan.h"
#include "mtcal/processing/gantry_accuracy.h"
#include "mtcal/storage/store.h"

namespace mtcal::acquisition {

/// The plan a stored gantry run was made with (its stored plan without the run's expansion).
/// @throws InputError
GantryPlan gantryPlanOfRun(const storage::RunInfo& run);

/// The measurements of a stored gantry run. @throws InputError when the run is not a gantry run
/// or a feature is missing (named).
processing::GantryMeasurements loadGantryMeasurements(storage::Store& store, storage::Id run_id);

/// The measurement file (docs/gantry.md): tracker coordinates, mm.
nlohmann::json measurementsToJson(const processing::GantryMeasurements& m);
/// @throws InputError "SOURCE: key: why"
processing::GantryMeasurements measurementsFromJson(const nlohmann::json& j, const std::string& source);

}  // namespace mtcal::acquisition
