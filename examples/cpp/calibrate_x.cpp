// mtcal as a library: open an archive, run the simulated demo plan (the X axis of the demo
// machine, 50 to 600 mm, 9 cycles, both directions) through the mock interferometer, and
// print the ISO 230-2 figures E and M.
//
//   calibrate_x [ARCHIVE.sqlite] [TIME_SCALE]

#include <cstdio>
#include <exception>
#include <string>

#include "mtcal/error.h"
#include "mtcal/services/linear.h"
#include "mtcal/services/logging.h"

int main(int argc, char** argv) {
  using namespace mtcal;
  try {
    services::logToStderr("warn");  // stdout: the figures only
    services::SessionOptions options;
    options.db_path = argc > 1 ? argv[1] : "calibrate_x.sqlite";
    services::Session session(options);
    services::LinearRunRequest request;  // no plan: the demo plan, on the simulated demo machine
    if (argc > 2) request.simulation.time_scale = std::stod(argv[2]);
    const auto campaign = services::runLinear(session, request);
    const auto& run = campaign.runs.front();
    if (!run.iso230_2) {
      std::fprintf(stderr, "run %lld ended %s\n", static_cast<long long>(run.run_id), run.status.c_str());
      return 1;
    }
    const auto& iso = run.iso230_2->result;
    std::printf("run %lld, ISO 230-2: E = %.2f um, M = %.2f um\n", static_cast<long long>(run.run_id),
                iso.E_um.value_or(0.0), iso.M_um.value_or(0.0));
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "calibrate_x: %s\n", e.what());
    return 1;
  }
}
