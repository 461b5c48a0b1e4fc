#pragma once
// Thermal monitoring: the plan (a spindle speed program of warm-up, steady and
// cool-down phases, a sample every interval for hours) and its run: the temperature logger
// logs on its own clock, the spindle program starts at the first record, each record is
// stored with the displacement the probe reads then, one transaction per sample. A sensor
// that is out is stored as missing (NULL), never as 0; a probe over range likewise. A run
// that stops (the operator, a lost link) keeps every finished sample and can be resumed:
// the samples continue where it stopped and the program with the phase it was in.

#include <atomic>
#include <cstdint>
#include <functional>
#include <nlohmann/json_fwd.hpp>
#include <string>
#include <vector>

#include "mtcal/acquisition/run_clock.h"
#include "mtcal/drivers/interferometer/driver.h"
#include "mtcal/drivers/logger/driver.h"
#include "mtcal/drivers/probes/driver.h"
#include "mtcal/storage/store.h"

namespace mtcal::acquisition {

struct ThermalPhase {
  std::string name;
  double duration_s = 0.0;
  double speed_rpm = 0.0;
};

struct ThermalPlan {
  std::string name = "thermal";
  std::uint32_t interval_s = 60;
  std::vector<ThermalPhase> phases;
  std::vector<std::string> sensors;  ///< names of logger channels 1..n recorded (empty: all, T1..Tn)
  std::string displacement_name = "drift_z_um";
  std::string displacement_device =
      "probes";                         ///< probes, or interferometer (linear optics along the axis, air-compensated)
  int displacement_channel = 1;         ///< of the probe box
  std::string displacement_axis = "Z";  ///< what the probe reads (Y or Z; the simulated probe's direction)
  double displacement_sign =
      -1.0;  ///< um of drift per um of probe reading (the probe on the table: the gap closes as the tool drifts down)
  /// The probe box latches on the logger's record output (its trigger input wired to it): the
  /// displacement of each record is read at the record's instant. Otherwise it is read when
  /// the record has arrived.
  bool displacement_trigger = false;
  /// Also record the interferometer's environment unit: air temperature and material sensors
  /// (temperature channels air_temp_c, material_temp_1..).
  bool environment = false;

  /// @throws InputError naming the key and why
  static ThermalPlan fromJson(const nlohmann::json& j, const std::string& source);
  nlohmann::json toJson() const;
  double durationS() const;
  std::int64_t sampleCount() const;  ///< one at the start, then every interval to the end
  double speedAt(double t_s) const;  ///< rpm the program runs at t since its start
  /// The phases from time `offset_s` on (a resumed program).
  std::vector<ThermalPhase> phasesFrom(double offset_s) const;
};

/// The machine side: the CNC runs the spindle program (a real machine: the operator starts the
/// plan's NC program; the virtual machine: its thermal state).
class SpindleController {
 public:
  virtual ~SpindleController() = default;
  /// Starts `phases` at `start_s` of the logger's clock (the first record's time).
  virtual void startProgram(const std::vector<ThermalPhase>& phases, double start_s) = 0;
};

struct ThermalRunOptions {
  const std::atomic<bool>* stop_requested = nullptr;
  std::function<void(std::int64_t done, std::int64_t total, double drift_um)> on_progress;
  std::chrono::milliseconds record_timeout{120'000};  ///< wall time a record may be late
  /// The instruments' time (a simulated world runs in lock step with the run); nullptr: real instruments.
  RunClock* run_clock = nullptr;
};

struct ThermalRunSummary {
  std::int64_t samples = 0;         ///< in the run after this session
  std::int64_t missing_values = 0;  ///< of this session
  bool complete = false;
  std::string stopped_because;  ///< when not complete
};

/// The instruments of a thermal run: the logger always; the probe box or the interferometer
/// for the displacement, as the plan says; the interferometer for the environment.
struct ThermalInstruments {
  drivers::logger::TemperatureLoggerDevice& logger;
  drivers::probes::ProbeBoxDevice* probes = nullptr;
  drivers::interferometer::InterferometerDevice* interferometer = nullptr;
};

/// Runs (or resumes: the run's samples so far are kept) a thermal plan into `run_id`, whose
/// status it sets. Errors of the devices stop the run (interrupted, the reason returned).
/// @throws InputError when the plan needs an instrument that is not given
ThermalRunSummary runThermalMonitoring(const ThermalPlan& plan, const ThermalInstruments& instruments,
                                       SpindleController& spindle, storage::Store& store, storage::Id run_id,
                                       const ThermalRunOptions& options);

/// The NC program of the plan's spindle phases (M3 S.. G4 P.. per phase, M5), for a real machine.
std::string thermalGcode(const ThermalPlan& plan);

}  // namespace mtcal::acquisition
