#pragma once
// Continuing an interrupted run of any kind (a stop, a device fault, a full disk, a process
// that died): the run's own plan, instruments and machine, what it stored kept, the rest
// measured. A run whose process still records it is refused; an imported or completed run
// has nothing to resume.

#include <variant>

#include "mtcal/services/circle.h"
#include "mtcal/services/est.h"
#include "mtcal/services/gantry.h"
#include "mtcal/services/linear.h"
#include "mtcal/services/session.h"
#include "mtcal/services/thermal.h"
#include "mtcal/services/workshop.h"

namespace mtcal::services {

/// How a resumed run ended, as its kind's run reports it.
using ResumedRun = std::variant<LinearRunResult, CircleRunResult, EstRunResult, GantryRunResult, ThermalRunResult>;

/// Resumes `run_id`. `simulation`: the world's time scale for simulated runs, and a real gantry's
/// kinematics (machine_file); the machine itself is the run's.
/// @throws InputError saying why a run cannot be resumed and what to do instead
ResumedRun resumeRun(Session& session, storage::Id run_id, const SimulationOptions& simulation);

}  // namespace mtcal::services
