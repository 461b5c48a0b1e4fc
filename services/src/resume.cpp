#include "mtcal/services/resume.h"

#include <fmt/format.h>

#include "mtcal/error.h"

namespace mtcal::services {

ResumedRun resumeRun(Session& session, storage::Id run_id, const SimulationOptions& simulation) {
  const auto kind = session.store().run(run_id).kind;
  if (kind == storage::run_kind::kLinear) return resumeLinear(session, run_id, simulation.time_scale);
  if (kind == storage::run_kind::kCircle) return resumeCircle(session, run_id, simulation.time_scale);
  if (kind == storage::run_kind::kEst) return resumeEst(session, run_id, simulation.time_scale);
  if (kind == storage::run_kind::kGantry) return resumeGantry(session, run_id, simulation);
  if (kind == storage::run_kind::kThermal) {
    ThermalRunRequest request;
    request.resume_run = run_id;
    request.simulation = simulation;
    return runThermal(session, request);
  }
  throw InputError(fmt::format("run {} is of kind '{}', which this mtcal cannot resume", run_id, kind));
}

}  // namespace mtcal::services
