#pragma once
// Probe stepping plans for guideway straightness by error separation (docs/est.md): the
// carriage steps along the guideway, the probe box's channels are averaged at each step,
// every step is stored with its channels in one transaction.

#include <atomic>
#include <cstdint>
#include <functional>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "mtcal/acquisition/linear_run.h"
#include "mtcal/drivers/probes/driver.h"
#include "mtcal/processing/diagnosis.h"
#include "mtcal/storage/store.h"

namespace mtcal::acquisition {

struct EstPlan {
  std::string name = "guideway straightness by error separation";
  std::string axis = "X";      ///< the carriage stepped
  std::string measures = "Y";  ///< the direction the probes read (Y or Z)
  double start_mm = 50.0;
  double step_mm = 20.0;
  int points = 21;                                 ///< carriage positions
  double spacing_mm = 20.0;                        ///< between neighbouring probes: step_mm or m * step_mm
  int probes = 2;                                  ///< 2 (two-probe, frequency) or 3 (three-probe: spacing = step)
  double settle_s = 0.5;                           ///< wait after the carriage is in position
  int readings_per_step = 10;                      ///< stream lines averaged per step
  std::uint32_t rate_hz = 50;                      ///< stream rate of the probe box
  double step_timeout_s = 10.0;                    ///< longest wait for a step's readings
  std::map<std::string, double> line_position_mm;  ///< the other axes during the run
  /// How the probes' zeros are measured before the first step: "reference-flat" (the probes
  /// read a reference flat; the default with three probes, whose separation needs the zero
  /// combination z3 - 2 z2 + z1) or "none" (two probes: a zero offset only tilts the profile).
  std::string zeroing;
  int zeroing_readings = 500;  ///< stream lines averaged on the reference flat
  /// Who moves the carriage: "machine" (mtcal commands the controlled machine) or "hand" (the
  /// operator moves it to each step, holds it and confirms; a real machine's carriage).
  std::string stepping = "machine";
  /// Stepped by hand: a step's readings are taken once no probe moves more than this (um)
  /// within them.
  double still_um = 0.5;
  /// Imported readings: the file's name and SHA-256 (empty: measured by mtcal, or not given).
  std::string imported_from, imported_sha256;

  /// The zeroing the plan asks for: its own, or reference-flat with three probes.
  std::string zeroingMethod() const { return !zeroing.empty() ? zeroing : probes == 3 ? "reference-flat" : "none"; }

  /// @throws InputError naming `source`, the key and why
  static EstPlan fromJson(const nlohmann::json& j, const std::string& source);
  static EstPlan load(const std::string& path);
  nlohmann::json toJson() const;
  double positionMm(int k) const { return start_mm + step_mm * k; }
};

struct EstProgress {
  int done = 0, total = 0;
  double position_mm = 0.0;
};

struct EstRunOptions {
  std::function<void(const EstProgress&)> on_progress;
  const std::atomic<bool>* stop_requested = nullptr;  ///< checked between steps
  std::string software_version = "unknown";
  /// The instruments' time (a simulated world runs in lock step with the run); nullptr: real instruments.
  RunClock* run_clock = nullptr;
  /// The zeroing: called with true when the probes are to be set on the reference flat, with
  /// false when back on the guideway (the operator, or the simulated world). Needed by a plan
  /// that zeroes on a reference flat.
  std::function<void(bool on_flat)> reference_flat;
};

/// A carriage moved by the operator: each move is asked for (`ask`: the axis and the position,
/// returning once the carriage holds there); the time it arrives is not known, so a step's
/// readings are the lines streamed after the answer.
class HandStepping final : public MachineController {
 public:
  explicit HandStepping(std::function<void(const std::string& axis, double position_mm)> ask) : ask_(std::move(ask)) {}
  std::optional<double> moveTo(const std::string& axis, double position_mm) override {
    ask_(axis, position_mm);
    return std::nullopt;
  }

 private:
  std::function<void(const std::string&, double)> ask_;
};

/// The zeroing of a run's probes, stored as its result "est-zeroing".
struct EstZeroing {
  std::string method;           ///< reference-flat (measured by the run) or given (with an import)
  std::vector<double> zero_um;  ///< each probe's reading on the reference flat
  std::vector<double> s_um;     ///< their standard deviations (empty when given)
  int readings = 0;             ///< lines averaged
  /// z3 - 2 z2 + z1: what the three-probe combination reads on a straight surface.
  double combinationUm() const { return zero_um.size() == 3 ? zero_um[2] - 2.0 * zero_um[1] + zero_um[0] : 0.0; }
  nlohmann::json toJson() const;
  static EstZeroing fromJson(const nlohmann::json& j);
};
constexpr const char* kEstZeroingProcessor = "est-zeroing";
/// The run's zeroing; nullopt when it has none.
std::optional<EstZeroing> storedZeroing(storage::Store& store, storage::Id run_id);
/// A stored run's steps as the separation and the diagnosis read them: each step's position,
/// every probe's mean reading (probes 1 to 3; v3_um empty for two probes), its scatter over the
/// readings averaged there (NaN where a step read once) and their number; the plan's spacing.
processing::EstRunInput storedEstRun(storage::Store& store, const storage::RunInfo& info);
/// Stores `zeroing` as the run's result "est-zeroing".
void storeZeroing(storage::Store& store, storage::Id run_id, const EstZeroing& zeroing, const std::string& version);

/// Runs a plan with a controlled machine. Steps already stored stay when the run fails or is
/// stopped (status interrupted, the reason in its events).
/// @throws whatever the device or the machine throws, after marking the run
class EstRun {
 public:
  EstRun(storage::Store& store, drivers::probes::ProbeBoxDevice& device, MachineController& controller,
         EstRunOptions options);
  storage::Id start(const EstPlan& plan, storage::Id campaign_id, std::optional<storage::Id> instrument_id);
  /// Continues an interrupted run: the steps it stored are kept, the others measured.
  /// @return the run's plan. @throws InputError when it is not a probe stepping run or its
  /// process still records it
  EstPlan resume(storage::Id run_id);
  RunOutcome outcome() const { return outcome_; }

 private:
  void requireChannels(const EstPlan& plan) const;
  void execute(storage::Id run_id, const EstPlan& plan, const std::set<int>& stored);
  storage::Store& store_;
  drivers::probes::ProbeBoxDevice& device_;
  MachineController& controller_;
  EstRunOptions options_;
  RunOutcome outcome_ = RunOutcome::kCompleted;
};

}  // namespace mtcal::acquisition
