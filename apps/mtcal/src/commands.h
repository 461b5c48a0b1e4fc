#pragma once
// One function per command of the mtcal command line. Each returns the exit code and
// writes only to the streams it is given.

#include <atomic>
#include <cstdint>
#include <optional>
#include <ostream>
#include <string>

#include "mtcal/acquisition/import_linear.h"
#include "mtcal/storage/store.h"

namespace mtcal::app {

struct Globals {
  std::string db = "mtcal.sqlite";
  bool json = false;
  std::ostream* out = nullptr;
  std::ostream* err = nullptr;
  const std::atomic<bool>* stop = nullptr;
  bool terminal = false;  ///< stderr is a terminal: draw the progress bar in place
};

struct SimulationOptions {
  std::uint64_t seed = 1;
  double time_scale = 50.0;         ///< world seconds per wall second
  std::string machine_file;         ///< virtual machine description (JSON); demo machine when empty
};

struct RunOptions {
  bool triggered = false;           ///< mock devices: the virtual CNC runs the part program
  std::string machine = "unnamed machine";  ///< real devices: the machine measured
};

int demo(const Globals& g, const SimulationOptions& sim);
int listRuns(const Globals& g);
int showRun(const Globals& g, storage::Id run_id);
int importLinear(const Globals& g, const std::string& path, acquisition::LinearImportOptions options);
int analyzeIso230(const Globals& g, storage::Id run_id);
int airIndex(const Globals& g, const std::string& model, double temp_c, double pressure_pa, double humidity_pct,
             double co2_ppm, double wavelength_nm);
int runLinear(const Globals& g, const std::string& plan_path, const std::string& device_uri, const SimulationOptions& sim,
              const RunOptions& run_options);
int resumeRun(const Globals& g, storage::Id run_id, double time_scale);
int planGcode(const Globals& g, const std::string& plan_path, const std::string& output_path);
int listDevices(const Globals& g, const SimulationOptions& sim);

}  // namespace mtcal::app
