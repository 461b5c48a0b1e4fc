#pragma once
// Campaigns with hidden effects: linear positioning runs of the virtual
// machine's X axis in which one effect, two or none is hidden, each with a random magnitude,
// so that a test can require the diagnosis to name the effect without being told which.
//
// The machine is the demo machine of the seed (smooth geometric errors, pitch enlarged so an
// Abbe offset is visible) without backlash; the plan is the ISO 230-2 grid (every 20 mm over
// 0..400 mm, 5 bidirectional cycles) or a dense plan of random positions (the patent's
// validation, ~4 mm apart, 3 cycles), chosen at random. Every target takes 6 s; the
// environment unit's air temperature swings, the pressure and the machine's temperature wander.
// Readings carry a positioning scatter (0.5 um per approach) and the optics' noise (0.05 um).
// A coolant temperature wanders as an AR(1) process in every campaign (an auxiliary channel).
//
// Effects and their true parameters (the names the diagnosis reports):
//   backlash                  reversal (um): the drive's lost motion, from the virtual machine
//   cyclic_error              amplitude (um), period (mm): a lead error added to EXX
//   thermal_drift             amplitude (um), time_constant (s): first-order drift with time
//   environment_compensation  air_temp_coefficient (ppm/K): position x the air's change
//   scale_error               scale (ppm): the axis' scale changed since the model (with a model only)
//   abbe_error                offset (mm): the optics 20..80 mm off where the model assumes (with a model only)
//   channel_dependence        sensitivity (um/K), or peak_to_valley (um) with smooth = 1: the reading
//                             follows the coolant's temperature (an auxiliary channel wandering as an
//                             AR(1) process, present in every campaign), linearly or along a parabola
//   thermal_growth            growth (ppm), amplitude (um), time_constant (s): the axis grows along its
//                             travel with a first-order response in time, its datum drifting with it
//                             (never hidden together with thermal_drift)
// Every effect's truth also gives size_rms (um): the RMS over the run of what it adds, about
// its mean.
// With a model (half of the campaigns) the run comes with the prediction of an earlier
// calibration: the error curve (B-spline, knots 20 mm apart) identified from an effect-free
// run of the machine before the hidden effects (20 mm grid, 5 bidirectional cycles, the same
// scatter), so the model has its own error; its pitch and yaw are the machine's.

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "mtcal/processing/diagnosis.h"

namespace mtcal::mocks {

struct HiddenEffect {
  std::string effect;
  std::map<std::string, double> parameters;
};

struct HiddenEffectCampaign {
  std::uint64_t seed = 0;
  processing::LinearRunInput run;
  std::vector<HiddenEffect> truth;  ///< empty: effect-free
  bool with_model = false;
  bool grid_plan = false;  ///< the 20 mm grid (cyclic errors aliased)
  /// What each hidden effect adds to each reading (um), by effect: its exact shape, for a study
  /// that asks what a test told the shape could see.
  std::map<std::string, std::vector<double>> added_um;
  /// The part of an effect's addition that is another, simpler cause (um), by effect: a growth's
  /// datum drift (a drift named for a growth is not the growth).
  std::map<std::string, std::vector<double>> simpler_part_um;
  /// The standard deviation of a reading's noise (um): the positioning scatter and the optics'.
  double reading_noise_um = 0.0;
  /// With a model: the covariance of the model's own error at the readings (um^2), from the
  /// earlier run's scatter through the curve's fit (empty without a model).
  Eigen::MatrixXd model_error_covariance_um2;
};

/// What to hide; empty `effects` with `random` false: none.
struct CampaignRequest {
  std::uint64_t seed = 1;
  bool random = true;                ///< draw 0 (30 %), 1 (50 %) or 2 (20 %) effects, the model and the plan
  std::vector<std::string> effects;  ///< when not random
  int with_model = -1;               ///< when not random: 1 / 0; -1: as the effects need
  int grid_plan = -1;                ///< when not random: 1 / 0; -1: at random
  /// When not random: an effect's size given instead of drawn, keyed by the effect's name
  /// (it must be one of `effects`). What is set, in the unit of the truth's parameter:
  ///   backlash                  the drive's lost motion (um; the truth's reversal follows from it)
  ///   cyclic_error              amplitude (um); the period is still drawn
  ///   thermal_drift             amplitude (um); the time constant is still drawn
  ///   environment_compensation  air_temp_coefficient (ppm/K, signed)
  ///   scale_error               scale (ppm, signed)
  ///   abbe_error                the optics' offset from the model's line (mm, signed; the truth's
  ///                             offset is what the readings show per urad of pitch, ~ this)
  ///   channel_dependence        sensitivity (um/K, signed); linear or smooth is still drawn
  ///   thermal_growth            growth (ppm, signed); the datum's drift and the time constant are still drawn
  /// The draw is made all the same, so the rest of the campaign (plan, environment, noise,
  /// machine) is the one the seed gives without the option.
  std::map<std::string, double> sizes;
};

/// @throws InputError for an unknown effect name, a size for an effect not hidden, or thermal_drift
///         and thermal_growth together
HiddenEffectCampaign makeLinearCampaign(const CampaignRequest& request);

/// The campaign's run in the CSV format `mtcal import linear` reads: target_mm, direction,
/// cycle, deviation_um, time_s and the environment channels (the model's prediction is not
/// part of it).
std::string linearCampaignCsv(const HiddenEffectCampaign& campaign);

/// The effects the generator can hide.
const std::vector<std::string>& hiddenEffectNames();

/// Three-probe stepping runs (error separation, docs/est.md) with hidden effects: a guideway
/// (a smooth profile of 1..5 um over a few hundred mm on a line tilted by 0.05..0.2 um/mm)
/// stepped 20..40 times by the probes' spacing d (20..30 mm); the carriage moves by 1 um per
/// step at random; every probe reads with 0.02..0.05 um of noise (a step's mean of 10 readings,
/// whose scatter the run states: EstRunInput::scatter_um). Effects (the names the
/// diagnosis reports) and their truths:
///   probe_offset   zero_combination (um): the probes' zeros c1 - 2 c2 + c3 of 0.1..1 um
///   scale_error    spacing_error (mm): probe 3 sits 0.2..1 mm off twice the spacing;
///                  constant_um: the constant it adds to probe 3 (the profile's mean slope times
///                  it: what the zeros' combination adds too)
///   carriage_yaw   amplitude (urad), wavelength (mm): the carriage yaws as a sine along the
///                  run, long (0.5..1.5 of the run, 5..30 urad) or short (2.5..6 steps, 20..60
///                  urad: yaw following the rail's short waviness), `short` = 1;
///                  yaw_peak_to_valley (urad) about its line over the steps; constant_um:
///                  the constant its mean rate adds to probe 3 (what the zeros' combination
///                  adds too: three probes cannot tell them apart), a long yaw's beside a
///                  spacing error with their product's
/// Every truth also gives size_rms (um): the RMS about its mean of what the effect adds to
/// probe 3's reading less the two-probe prediction (for the zeros, the constant they add), and
/// noise_rms (um), that residual's noise (twice a probe's).
struct EstCampaign {
  std::uint64_t seed = 0;
  processing::EstRunInput run;
  std::vector<HiddenEffect> truth;
  /// What each hidden effect adds to probe 3's reading less the two-probe prediction (um), step
  /// by step, beside the effects before it in `truth` (a spacing error and a yaw together add
  /// their product too, the later's), so that together they are what the readings carry; and the
  /// part of it that is the zeros' constant (a long yaw's, a spacing error's), as
  /// HiddenEffectCampaign's.
  std::map<std::string, std::vector<double>> added_um, simpler_part_um;
  double probe_noise_um = 0.0;  ///< the standard deviation of a probe's noise
};
/// `effects` from probe_offset, scale_error, carriage_yaw, carriage_yaw_short (the last two
/// both hide carriage_yaw).
/// @throws InputError for an unknown effect name
EstCampaign makeEstCampaign(std::uint64_t seed, const std::vector<std::string>& effects);

}  // namespace mtcal::mocks
