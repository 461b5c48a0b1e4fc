#pragma once
// What the simulation gets wrong: the residual of measured data against the
// current model, the evidence that something is missing, named physical causes fitted as
// model extensions, and the gain they give on held-out data.
//
// The pipeline (docs/diagnosis.md):
// 1. Every measured value y_i has a prediction s_i (the current model; zero when none) and a
//    baseline: free columns B fitted to y - s (the line's zero, or for a single linear run
//    without a model the run's own error curve averaged over both directions, a B-spline with
//    knots no closer than 20 mm). Every point carries its explaining variables (position,
//    direction, cycle, time, environment channels, angle, step ...).
// 2. Evidence: residualEvidence() of the baseline's residual against every variable.
// 3. Candidate extensions: named causes, each a shape (columns computed from the variables)
//    with parameters in physical units; nonlinear parameters (a period, a time constant) are
//    searched on a grid. A candidate is accepted when (a) its F test against the current model,
//    corrected for the search and for the number of candidates tried (Bonferroni), is below
//    `alpha`, (b) it lowers BIC, and (c) it lowers the RMS of held-out residuals (cross-
//    validation over the data's folds: repeats, or contiguous blocks of time or angle; never
//    random points of one repeat) by at least `min_gain`; its parameters are physically
//    plausible. Accepted candidates join the model one at a time, the
//    strongest first; a cause that none of the named ones explains is reported as "generic"
//    with its driving variable.
// 4. The result: per finding its parameters, evidence (delta BIC, p value), held-out RMS
//    before and after and the relative gain; the extension's stored form re-evaluates it on
//    other data (extensionValues) so later diagnoses and predictions use it.
//
// Units: um for the values unless the data say otherwise. Pure numerics.

#include <Eigen/Core>
#include <array>
#include <functional>
#include <limits>
#include <map>
#include <nlohmann/json_fwd.hpp>
#include <optional>
#include <string>
#include <vector>

#include "mtcal/processing/evidence.h"

namespace mtcal::processing {

/// A variable attached to every point (NaN: unknown at that point).
struct DiagnosisVariable {
  std::string name;  ///< position_mm, direction, cycle, time_s, air_temp_c, angle_deg, ...
  std::string unit;
  /// NaN where unknown: the rows of another run in a fit of runs of different kinds, where a
  /// shape of the variable adds nothing (0).
  Eigen::VectorXd values;
  /// A run's copy of a variable the fit has for every run, for that run's own causes only (a fit
  /// of runs of one kind): no evidence nor generic candidate of its own.
  bool own_causes_only = false;
};

/// How an extension's columns follow from the variables (its stored form, with the
/// coefficients, is a ModelExtension).
struct ExtensionShape {
  /// linear: v0 - reference; quadratic: u and u^2, u = v0 - reference with v0 held within
  /// `range` (a curve fitted over a channel's range does not extrapolate beyond it on another
  /// run); product: v0 (v1 - reference); first_order: 1 - exp(-v0 / searched);
  /// sin, cos: of 2 pi v0 / searched; harmonic: sin and cos of 2 pi v0 / searched (2 columns);
  /// harmonic_difference: the harmonic's change from v0 to v1 (2 columns, times `scale`);
  /// harmonic_difference_about_mean: the same about their means (a constant is not seen);
  /// a "*NAME" suffix ("sin*direction"): multiplied by the variable NAME;
  /// sign_sin_cos / sign_cos_sin (circle reversals): sign(sin v0) cos v0, sign(cos v0) sin v0
  /// (v0 in degrees) times direction, 0 within `reference` degrees after the axis reverses in its
  /// direction of travel (the play being taken up; 0: none); step_difference: d (B_j(v1) - B_j(v0)) about their mean
  /// for a cubic B-spline of `spans` spans over `range` (d = `scale`), the first two basis
  /// functions left out (a constant and a straight line are not seen); spline: B-spline basis
  /// of v0 of `spans` spans over `range` (the last column left out: the baseline has the
  /// constant).
  std::string kind;
  std::vector<std::string> variables;
  double reference = 0.0;
  double searched = 0.0;  ///< period (units of v0) or time constant (s)
  double scale = 1.0;
  int spans = 0;
  std::pair<double, double> range{0.0, 0.0};
  /// -1: the shape's columns go beside the candidate's others; k >= 0: its one column is added
  /// into the candidate's column k (one quantity read through the shapes of runs of different
  /// kinds pooled in one fit: a drive's lost motion in a positioning run and in a circle).
  int into = -1;
  nlohmann::json toJson() const;
  static ExtensionShape fromJson(const nlohmann::json& j);
};

struct ParameterValue {
  std::string name, unit;
  double value = 0.0, standard_error = 0.0;
};

/// A named cause: its shape and what its coefficients mean.
struct Candidate {
  std::string effect;                  ///< thermal_drift, backlash, cyclic_error, abbe_error, scale_error, ...
  std::string cause;                   ///< in plain words
  std::string variable;                ///< the driving variable
  std::vector<ExtensionShape> shapes;  ///< their columns side by side
  struct Parameter {
    std::string name, unit;
    double per_coefficient = 1.0;  ///< parameter = coefficient * per_coefficient
    double max_abs = 0.0;          ///< physically plausible limit of |parameter| (0: none)
    /// The physical quantity the parameter measures, the same whatever kind of data reads it
    /// ("lost_motion_X": the X drive's lost motion, um); runs of different kinds pooled in one
    /// fit share it. Empty: the parameter is this kind's own.
    std::string quantity = {};
    double per_quantity = 1.0;  ///< parameter = quantity * per_quantity
  };
  std::vector<Parameter> parameters;  ///< one per column
  /// Values of shape.searched tried (empty: nothing searched) and how many independent
  /// tries they amount to (the p value is corrected for that many).
  /// (the first shape's `searched`).
  std::vector<double> search;
  /// The least and the greatest value searched, kept when the search is fixed to the value found;
  /// the searched value is refined within them (0, 0: the search's own).
  std::pair<double, double> search_limits{0.0, 0.0};
  double independent_tries = 1.0;
  std::string searched_name, searched_unit;
  /// What the data could equally say with another variable: the candidate is tested with
  /// these columns in the model too, so it is named only for what they cannot explain (a
  /// channel that follows a smooth course in time is tested beyond a smooth function of time,
  /// else a drift would be named after it).
  std::vector<ExtensionShape> confounders;
  /// A property of the measurement's set-up, not of the machine (a circle's centre off the bar's
  /// pivot, the probes' zeros): named, never part of a model nor applied to another run.
  bool of_setup = false;
};

struct DiagnosisData {
  std::string kind;    ///< linear, circle, thermal, est
  std::string source;  ///< for messages and the report, e.g. "run 12"
  /// The error the run measures, where its kind measures several (a linear run: EXX, EYY, EYX
  /// ...; empty: not said, or a kind with one). Runs of one kind share their causes in one fit
  /// where they measure one error; runs measuring others keep their own, as runs of different
  /// kinds do (poolDiagnosisData).
  std::string measures;
  std::string value_name = "deviation", value_unit = "um";
  Eigen::VectorXd measured;
  Eigen::VectorXd simulated;      ///< the current model's prediction (zeros: none)
  std::string model_description;  ///< what simulated is
  /// Whether `simulated` is a model's prediction (not zeros).
  bool hasModel() const { return simulated.size() > 0 && (simulated.array() != 0.0).any(); }
  Eigen::MatrixXd baseline;  ///< free columns fitted with every model (may have none)
  std::string baseline_description;
  Eigen::VectorXi fold;  ///< held-out unit of every point, 0..folds-1
  /// Repeated sites (linear runs: the position, 0..sites-1; empty: none; -1: a point that is
  /// not repeated, the rows of a circle pooled with a linear run): a term that is the same at
  /// every repeat of a site is tested on the sites' means (lack of fit).
  Eigen::VectorXi site;
  /// The model's own error at the sites as the model states it (its identification's scatter
  /// through its fit): one row per site, the covariance of its error at two sites the product
  /// of their rows (in the value's unit). Empty: not stated; the sites' means then estimate it
  /// (a variance and a correlation between neighbours). Where the readings disagree with it,
  /// the diagnosis says so and estimates it instead.
  Eigen::MatrixXd model_error_factor;
  /// The noise of every point as its readings' own scatter states it (EST: each probe's scatter
  /// over the readings averaged at a step, through probe 3's residual): a variance in the value's
  /// unit squared and its degrees of freedom (0: not stated), and what states it, for the notes.
  /// Points without repeated sites or weights only. Where the residuals of the diagnosis made
  /// without it do not scatter more than it says, in all or from one point to the next (what
  /// they hold beyond it then changes slowly along the points, as a missed effect does), the
  /// diagnosis is made again with it: the tests and standard errors pool it with the residuals'
  /// scatter, as pure error is pooled with lack of fit (both sums of squares over both degrees
  /// of freedom). Where they scatter more both ways, the diagnosis made without it stands, and a
  /// note says so.
  double stated_noise_variance = 0.0, stated_noise_dof = 0.0;
  std::string stated_noise_description;
  std::string fold_description;
  /// Parameters already fitted to make `measured` a residual (a rigid motion per hole, a
  /// circle's plane): the tests' degrees of freedom are reduced by them.
  int absorbed_dof = 0;
  /// The correlation of neighbouring points' noise, in the points' order (0: independent). A
  /// residual that shares a reading with its neighbour (EST: probe 2 of the next step; 1/4 for
  /// equal probes, or as the probes' stated scatter gives it) is correlated so: the fits and
  /// tests are generalised least squares, whitened by it.
  double lag1_correlation = 0.0;
  /// Each point's weight in the fits and tests (empty: all 1): in a fit of runs of different
  /// kinds, whose scatter differs, the inverse of its run's (a precise circle's many points must
  /// not make a linear run's noise look significant, nor a noisy run hide a precise one's).
  Eigen::VectorXd weight;
  std::vector<DiagnosisVariable> variables;
  std::string main_variable;  ///< what plots put on the horizontal axis
  /// Every variable the residual is plotted against (empty: the main variable and time; runs of
  /// different kinds in one fit: each run's own).
  std::vector<std::string> plot_variables;
  std::vector<Candidate> candidates;
  std::vector<std::string> warnings, notes;
  /// Runs pooled in one fit (poolDiagnosisData), in the order of their rows: each run's source
  /// and number of points. Empty: one run. A cause they share is also fitted run by run, to say
  /// where the runs disagree on it.
  struct PooledRun {
    std::string source;
    Eigen::Index points = 0;
  };
  std::vector<PooledRun> pooled_runs;
  /// Rows where a reading may depart from every smooth cause over a few points (empty: none):
  /// a circle's readings within a few degrees of an axis's reversal, and after it by the angle
  /// turned in a servo lag, where the axis takes up its lost motion or its friction (a reversal
  /// spike): which reversal, 0 to 3 (at 0, 90, 180, 270 deg), or -1 for none.
  std::vector<int> reversal_at;
  const DiagnosisVariable* variable(const std::string& name) const;
};

/// Most causes a diagnosis names by default (of one run; services give runs of several kinds or
/// errors in one fit as many for each).
constexpr int kDefaultMaxFindings = 6;

struct DiagnosisOptions {
  double alpha = 0.01;  ///< family-wise: the chance that effect-free data get any finding
  int max_findings = kDefaultMaxFindings;
  /// A finding must lower the held-out RMS by at least this fraction: an extension that
  /// predicts no better is not worth the model's complexity.
  double min_gain = 0.02;
  /// Called after each candidate is tested: `done` of at most `total` tests (every candidate in
  /// every round; the last call has done == total, also when the search ends early). On the
  /// calling thread.
  std::function<void(std::size_t done, std::size_t total)> on_progress;
};

struct Finding {
  Candidate candidate;
  std::vector<ParameterValue> parameters;  ///< the fitted ones, then the searched one
  Eigen::VectorXd coefficients;
  double delta_bic = 0.0;  ///< BIC of the model without the term minus with it (> 0: better)
  double p_value = 1.0;    ///< F test, corrected for the search and the candidates tried
  /// Against a model, for a term the same at every repeat of a position: its test with the
  /// model's own error at the positions fitted both with and without it (likelihood ratio),
  /// corrected alike; NaN where not made. Above the diagnosis' alpha, that error would do as well.
  double p_value_model_error_refitted = std::numeric_limits<double>::quiet_NaN();
  double rms_before_um = 0.0, rms_after_um = 0.0;    ///< held-out
  double peak_before_um = 0.0, peak_after_um = 0.0;  ///< held-out
  double gain = 0.0;                                 ///< 1 - after / before
  /// In a fit of runs of different kinds, the runs whose points the held-out figures are of
  /// where not every run's (a circle's own eccentricity: the circle's); empty: every point.
  std::vector<std::string> heldout_runs;
  std::vector<std::string> alternatives;  ///< other causes within 2 of its delta BIC
  /// The cause's other forms with a parameter of the finding's and an Akaike weight of 1 % or
  /// more (a growth steady in time beside a first-order one): their spread about that parameter
  /// is in its standard error.
  struct OtherForm {
    std::string cause;
    double delta_bic = 0.0;  ///< its BIC less the finding's, both tested against the other findings (> 0: worse)
    double delta_aic = 0.0;  ///< the same with Akaike's criterion
    double weight = 0.0;     ///< its Akaike weight among the finding's form and every other form tested
    std::vector<ParameterValue> parameters;  ///< the finding's parameters it has, as it gives them (its own errors)
  };
  std::vector<OtherForm> other_forms;
  /// The richer cause it was found as (a growth with its datum's drift) when the backward check
  /// made it the simpler one: the test of the richer cause's further terms given every other
  /// finding (what the run could not tell).
  struct ReplacedForm {
    std::string cause;       ///< "effect (variable)"
    double delta_bic = 0.0;  ///< of its further terms (> 0: they lower the BIC)
    double p_value = 1.0;    ///< of its further terms, one test (no family correction)
  };
  std::optional<ReplacedForm> replaced_form;
  bool two_forms = false;  ///< two forms of its cause named, made one finding with both time courses
  std::pair<Eigen::Index, Eigen::Index> columns_in_design{0, 0};  ///< first column and count in the final design
};

/// Every candidate tried, round by round, and what became of it.
struct Considered {
  int round = 0;
  std::string effect, variable;
  std::string cause;  ///< the form's plain words: two forms of a cause share its effect and variable
  double delta_bic = 0.0, p_value = 1.0;
  double heldout_rms_um = 0.0;  ///< NaN when it did not get that far
  std::string verdict;          ///< "passes", "passes: named" (the round's finding), or why not
};

/// Runs pooled in one fit that disagree on a cause they share: the finding fitted run by run,
/// its one size tested against that (its warning says the same in words).
struct RunDisagreement {
  std::string effect, variable;  ///< the finding's
  double f = 0.0, dof1 = 0.0, dof2 = 0.0;
  double p_value = 1.0;  ///< corrected for the findings tested
  struct Run {
    std::string source;
    std::vector<ParameterValue> parameters;  ///< the ones it reads, fitted run by run (least squares)
  };
  std::vector<Run> runs;  ///< empty where the fit run by run does not determine them all
};

struct Diagnosis {
  double rms_um = 0.0;                                 ///< of the baseline's residual (fitted)
  double heldout_rms_um = 0.0, heldout_peak_um = 0.0;  ///< baseline, held out
  double final_heldout_rms_um = 0.0, final_heldout_peak_um = 0.0;
  double gain = 0.0;  ///< 1 - final / baseline, held out
  std::vector<Finding> findings;
  std::map<std::string, ResidualEvidence> evidence;  ///< baseline residual against each variable
  Eigen::VectorXd residual_before, residual_after;   ///< fitted, per point
  Eigen::VectorXd heldout_before, heldout_after;     ///< held out, per point
  int candidates_tried = 0;
  std::vector<Considered> considered;
  std::vector<std::string> warnings, notes;
  std::vector<RunDisagreement> runs_disagree;  ///< runs pooled in one fit only
  /// Readings far off the fit (more than 8 times the residuals' robust scatter), run by run:
  /// gross errors, or a circle's reversal spikes (DiagnosisData::reversal_at).
  struct ReadingsOffFit {
    std::string source;
    std::vector<Eigen::Index> points;  ///< within the run, from 1
    bool reversal_spikes = false;
  };
  std::vector<ReadingsOffFit> readings_off_fit;
  /// What the data stated of their own error (DiagnosisData::model_error_factor, or
  /// stated_noise_variance) and what became of it (the notes say it in words).
  struct StatedError {
    std::string what;     ///< "model_error" or "noise"; empty: the data state neither
    std::string outcome;  ///< "taken" (the readings agree), "refused" (estimated instead), "not used"
    double p_value = std::numeric_limits<double>::quiet_NaN();                     ///< the check's; NaN: not made
    double noise_rms = std::numeric_limits<double>::quiet_NaN(), noise_dof = 0.0;  ///< the noise as stated
    /// p of the residuals' scatter from one point to the next against a stated noise, weighed
    /// where they scatter more than it in all; NaN: not weighed
    double p_value_point_to_point = std::numeric_limits<double>::quiet_NaN();
  } stated_error;
};

/// @throws InputError when the data are inconsistent (sizes, folds) or too few
Diagnosis diagnose(const DiagnosisData& data, const DiagnosisOptions& options = {});

/// How many times diagnose() expects to make the diagnosis: 2 where the data state their noise
/// (with the noise estimated, then, where the residuals agree, as stated), else 1 (a second pass
/// where a model's stated error is refused is not foreseen). Its progress total counts them all.
int expectedDiagnosisPasses(const DiagnosisData& data);

/// The columns of shapes on the data's variables, side by side. @throws InputError for an
/// unknown kind or a variable the data lack
Eigen::MatrixXd extensionColumns(const std::vector<ExtensionShape>& shapes, const DiagnosisData& data);

/// An accepted extension in its stored form: re-evaluated on other data of the same kind.
struct ModelExtension {
  std::string effect, cause, variable;
  std::vector<ExtensionShape> shapes;
  std::vector<double> coefficients;
  std::vector<ParameterValue> parameters;
  nlohmann::json toJson() const;
  static ModelExtension fromJson(const nlohmann::json& j);
};
ModelExtension extensionOf(const Finding& finding);
/// What the extensions add to the prediction of every point of `data`.
Eigen::VectorXd extensionValues(const std::vector<ModelExtension>& extensions, const DiagnosisData& data);

/// What those of `extensions` whose variables the data have add to every point; the others
/// are left out, each with why.
struct AppliedExtensions {
  Eigen::VectorXd values;
  std::vector<std::string> applied, left_out, why;  ///< effects; why: one per left out
};
AppliedExtensions applyExtensions(const std::vector<ModelExtension>& extensions, const DiagnosisData& data);

/// Extensions found in one run applied, coefficients fixed, to another run of the same kind
/// (other positions or other times): the RMS and peak of that run's residual about its own
/// baseline without and with them. Extensions needing a variable the run lacks are left out.
struct Validation {
  std::string source;
  Eigen::Index points = 0;
  double rms_before_um = 0.0, rms_after_um = 0.0, peak_before_um = 0.0, peak_after_um = 0.0;
  double gain = 0.0;                           ///< 1 - after / before
  std::vector<std::string> applied, left_out;  ///< effects
};
Validation validateExtensions(const std::vector<ModelExtension>& extensions, const DiagnosisData& other);

// ---- Data of each kind, with its baseline, folds and candidate library ----

/// The run's own error curve's smallest knot spacing unless told otherwise (mm).
constexpr double kDefaultKnotSpacingMm = 20.0;
/// A B-spline's knot spacing (mm; a model's, a run's own curve), from the finest a curve along a
/// machine's travel has any use for (1e-300 was taken) to a travel's length.
constexpr double kFinestKnotSpacingMm = 0.1;
constexpr double kCoarsestKnotSpacingMm = 1e5;

/// A linear positioning run (or any reading along one moving axis): ISO 230-2 targets.
struct LinearRunInput {
  std::string source;
  std::vector<double> position_mm, deviation_um;
  std::vector<int> direction, cycle;  ///< +1 / -1; repeat index
  std::vector<double> time_s;         ///< empty: unknown; NaN where a point's is unknown
  std::vector<DiagnosisVariable>
      channels;  ///< environment and auxiliary (air_temp_c, air_pressure_pa, material_temp_c, ...)
  /// The current model's prediction of every reading (empty: none; the baseline is then the
  /// run's own error curve) and the angular errors it knows at every point (urad, for Abbe).
  std::vector<double> simulated_um;
  std::string model_description;
  /// The model's own error as it states it (ErrorFunction::fitErrorFactor), one row per reading:
  /// the covariance of the prediction's errors at two readings is the product of their rows
  /// (um^2). Empty: not stated.
  Eigen::MatrixXd simulated_error_factor_um;
  std::vector<DiagnosisVariable> model_angles_urad;
  double min_knot_spacing_mm = kDefaultKnotSpacingMm;
  /// The error the run reads (ISO 230-1: EXX, EYX, ECX ...); empty: a positioning error of an
  /// axis not said. A positioning error's reversal (EXX) is that drive's lost motion, which a
  /// circle of the axis reads too. A straightness (um) or an angle (urad: `deviation_um` holds
  /// urad) is not tried for the causes of a positioning reading (an air compensation, an Abbe
  /// offset, a scale, a growth along the travel), and its reversal is not a drive's lost motion.
  std::string measures;
};
/// @throws InputError for mismatched sizes or fewer than 8 points
DiagnosisData linearDiagnosisData(const LinearRunInput& input);

/// An error of a linear axis as ISO 230-1 names it (EXX, EYX, ECX ...): whether it is the axis'
/// positioning error (along itself) and whether it is an angle (EA., EB., EC.: urad).
struct LinearErrorKind {
  bool positioning = false, angle = false;
};
/// @throws InputError for a name that is not E, one of XYZABC, one of XYZ
LinearErrorKind linearErrorKind(const std::string& measures);

/// A circular test (ballbar): radial deviation per angle and direction.
struct CircleRunInput {
  std::string source;
  std::vector<double> angle_deg, deviation_um;
  std::vector<int> direction;  ///< +1 counter-clockwise, -1 clockwise
  std::vector<double> time_s;  ///< empty: unknown
  double radius_mm = 100.0, feed_mm_per_min = 1000.0;
  /// "XY", "YZ" or "ZX": angles from the first axis towards the second (plane.h); names the
  /// axes whose lost motion the reversal steps are. Empty: unknown.
  std::string plane;
};
DiagnosisData circleDiagnosisData(const CircleRunInput& input);

/// A thermal monitoring series: one displacement and the temperatures, in time order.
struct ThermalRunInput {
  std::string source;
  std::vector<double> time_s, displacement_um;
  std::vector<DiagnosisVariable> temperatures_c;
  /// The segment of each sample (a resumed run): each has a level of its own. Empty: one.
  std::vector<int> segment;
  int folds = 5;  ///< contiguous blocks of time
};
DiagnosisData thermalDiagnosisData(const ThermalRunInput& input);

/// A probe stepping run with three probes at 0, d, 2d: the two-probe separation of probes 1
/// and 2 (the method's assumption: no carriage yaw, exact zeros and spacing) predicts probe 3.
struct EstRunInput {
  std::string source;
  std::vector<double> position_mm;  ///< one per step, steps of the probe spacing
  std::vector<double> v1_um, v2_um, v3_um;
  double spacing_mm = 0.0;
  /// Each probe's scatter (um, the standard deviation of one reading) over the readings averaged
  /// at each step, and how many were averaged, one per step: the noise of the steps' readings as
  /// the readings themselves state it (NaN where a step read once). Empty: not known (a file
  /// without them).
  std::array<std::vector<double>, 3> scatter_um;
  std::vector<int> readings;
  /// Probe p's readings (0: v1_um, 1: v2_um, 2: v3_um).
  std::vector<double>& probeUm(std::size_t p) { return p == 0 ? v1_um : p == 1 ? v2_um : v3_um; }
  const std::vector<double>& probeUm(std::size_t p) const { return p == 0 ? v1_um : p == 1 ? v2_um : v3_um; }
};
DiagnosisData estDiagnosisData(const EstRunInput& input);

/// Each probe's variance of one reading (um^2) pooled over the steps that read it more than
/// once, with its degrees of freedom (n - 1 per such step); 0 and 0 where not known.
struct ProbeScatter {
  std::array<double, 3> variance_um2{}, dof{};
  /// Whether any probe's scatter is known (at a step that averaged several readings).
  bool known() const { return dof[0] + dof[1] + dof[2] > 0.0; }
};
/// @throws InputError naming the run and step where the scatter or counts are not given for every
/// step, a step averaged no reading, or a scatter is negative or not finite
ProbeScatter pooledProbeScatter(const EstRunInput& input);

/// A gantry test with a laser tracker (docs/gantry.md): the targets on the head in the initial
/// state and at every hole, and one target's sweeps while C, then A, turns; points in the
/// tracker's frame (the tracker at the origin), mm. The targets' rigid motion per hole and the
/// sweeps' circles are fitted first; their residuals are diagnosed: an SMR whose optical
/// centre is off its sphere's centre reads every point shifted along the line of sight
/// (target_offset), an axis whose tilt changes twice per turn moves the sweep out of its
/// plane (wobble).
struct TrackerRunInput {
  std::string source;
  std::vector<Eigen::Vector3d> initial_targets;
  std::vector<std::vector<Eigen::Vector3d>> hole_targets;
  std::vector<Eigen::Vector3d> c_sweep, a_sweep;
};
DiagnosisData trackerDiagnosisData(const TrackerRunInput& input);

/// Several runs as one set of data, so that a cause common to them is estimated once; each run
/// keeps its own baseline (columns of its own) and the same fold of every run is held out
/// together, and the runs' notes are kept, prefixed with their source.
/// - Runs of one kind and error (DiagnosisData::measures): the variables and candidate causes
///   every run has are shared (one coefficient for all), as the first run in the order of their
///   sources has them ("run 2" before "run 10": one fit whatever order they are given in), a
///   shape's range widened to every run's.
/// - Runs of different kinds or errors (linear runs and circles, a campaign's X and Y runs; not
///   three-probe runs, whose readings are correlated): the runs of each kind and error are one
///   fit of their own first (as above), named after their runs ("run 1, run 2"); each such part's
///   variables and causes are its own ("run 3: time_s", NaN in the other parts' rows), but for
///   the physical quantities two or more parts read (Candidate::Parameter::quantity: a drive's
///   lost motion in a positioning run and in a circle) one cause has one column per quantity,
///   added from each part's own shape.
/// @throws InputError for fewer than two runs, runs of two units, or three-probe runs with runs
///         of another kind
DiagnosisData poolDiagnosisData(const std::vector<DiagnosisData>& runs);

/// Whether one run is the other's copy (runs of one kind and unit): every reading the same within
/// 0.001 of the value's unit,
/// or the other's times a factor plus a constant (re-zeroed, converted), or a block of 3 or more
/// of the other's readings in a row (cut short). The words that say so ("run 3 reads what run 2
/// reads, every one of its 210 readings within 0.001 um"); empty where neither is.
std::string copyRelation(const DiagnosisData& a, const DiagnosisData& b);

/// A part of a finding: the runs it is of (their sources) and the extension on their own variables.
struct RunsExtension {
  std::vector<std::string> runs;  ///< empty: the finding as it is (of one run, or of runs of one kind)
  ModelExtension extension;
};
/// A finding of runs of different kinds pooled in one fit (its shapes on variables of several
/// runs, "run 3: direction"), as each part's own extension: the runs of the part (one run, or the
/// runs of one error fitted as one beside the others) and the extension on their own variables,
/// with the coefficients of the quantities it shares. A finding of one run or of runs of one kind
/// is returned as it is, with no runs; a cause of one run only in a fit of runs of one kind, with
/// that run.
std::vector<RunsExtension> extensionsByRun(const ModelExtension& extension);

/// Periods of a cyclic error a plan cannot see: when every position is on a grid of spacing
/// s, a cycle of period s / k (k = 1..) reads the same at every node. Empty when the
/// positions are not on one grid.
std::vector<double> aliasedPeriods(const std::vector<double>& positions_mm, double shortest_mm = 1.0);

}  // namespace mtcal::processing
