#pragma once
// What the simulation gets wrong in a run (docs/diagnosis.md): the run's residual against a
// model (or its own baseline), the evidence, the named causes with their parameters and
// held-out gain, the findings checked on other runs, a new model version with the extensions
// when a model was given, and a report folder with the residual plots.

#include <functional>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "mtcal/acquisition/csv.h"
#include "mtcal/processing/diagnosis.h"
#include "mtcal/processing/number_text.h"
#include "mtcal/services/session.h"

namespace mtcal::services {

/// Most causes a diagnosis names by default, for one run or each kind and error of runs in one fit.
using processing::kDefaultMaxFindings;
/// Most causes a diagnosis names, asked or by default.
constexpr int kMostFindings = 30;

struct DiagnoseRequest {
  storage::Id run_id = 0;
  /// Further runs (ids, or cN: every completed or imported run of campaign N) diagnosed with
  /// run_id in one fit (processing::poolDiagnosisData): runs of one kind measure the same error;
  /// runs of different kinds share the quantities they read (a drive's lost motion).
  /// run_id 0: the first of them.
  std::vector<std::string> runs;
  storage::Id against = 0;                  ///< a model predicting the (linear) run; 0: the run's own baseline
  std::string report_dir;                   ///< SVG residual plots here, when given
  std::string thermal_target;               ///< thermal runs: the displacement channel (default: the first)
  std::string est_csv;                      ///< EST data from a file (x_mm, v1_um, v2_um, v3_um) instead of a run
  acquisition::CsvDialect est_csv_dialect;  ///< how that file is written (default: detected)
  double spacing_mm = 0.0;                  ///< with est_csv: the probe spacing
  double alpha = 0.01;                      ///< family-wise chance of a finding on effect-free data
  /// Most causes named (none given: kDefaultMaxFindings, and as many for each kind and error of runs
  /// in one fit, at most kMostFindings).
  std::optional<int> max_findings;
  /// A linear run's own baseline: its smallest knot spacing (none given: processing::kDefaultKnotSpacingMm).
  std::optional<double> knot_spacing_mm;
  std::vector<storage::Id> validate_runs;  ///< runs of the same kind the findings are applied to, fixed
};

/// The findings applied, fixed, to another run.
struct FindingsValidation {
  storage::Id run_id = 0;
  processing::Validation result;
};

/// A diagnosis (processor "diagnosis" when of a stored run).
struct DiagnosisAnalysis {
  storage::Id run_id = 0, result_id = 0;  ///< 0: data from a file, not stored
  std::vector<storage::Id> pooled_runs;   ///< every run of one fit (run_id first); empty: one run
  processing::DiagnosisData data;
  processing::DiagnosisOptions options;
  processing::Diagnosis diagnosis;
  std::vector<FindingsValidation> validations;
  std::vector<std::string> report_files;
  std::optional<storage::Id> model_id;  ///< the new model version with the extensions
  bool model_already_stored = false;    ///< model_id is the same version stored by a diagnosis before
  storage::Id based_on_model = 0;
  nlohmann::json document() const;
};

/// A number to significant digits, for the front ends (processing/number_text.h).
using processing::significant;

/// What a diagnosis that names nothing says, for the text and the report: that nothing passes
/// (of the candidates tried), and either that the model explains the run to within its scatter
/// or, where the residual's evidence still shows a trend or a correlation along a variable (p
/// below `alpha`), along which: what is left is none of the named causes, or too weak to be
/// told from the model's own error. Readings far off the fit are said too: the tests include
/// them, and they may hide a cause.
std::string nothingNamedText(const processing::Diagnosis& d, double alpha, bool several_runs = false);

/// Whether any finding is the machine's, to apply to another run (a set-up's never is).
bool anyFindingToApply(const processing::Diagnosis& d);

/// Whose points a finding's held-out figures are of, where not every run's: " (run 4's points)";
/// else empty.
std::string heldOutScope(const processing::Finding& f);

/// A finding's parameter for the text, its standard error to 2 significant digits and the value
/// to its last digit (valueWithUncertainty): "growth_over_run = -7.12 +- 0.94 ppm".
std::string parameterText(const processing::ParameterValue& p);

/// A finding's other form in words, for the text and the report: "another form of the cause:
/// ... (BIC +5.9, AIC +2.6, Akaike weight 22 %) gives growth_over_run = -7.124 +- 0.94 ppm; its
/// spread is counted in the standard errors"; with a BIC below the finding's, also that it fits
/// better beside every other finding, and when a cause's form is chosen.
/// `parameter` writes each of its values (the report's own style: parameterText's otherwise).
std::string otherFormText(
    const processing::Finding::OtherForm& form,
    const std::function<std::string(const processing::ParameterValue&)>& parameter = parameterText);

/// A p value as the text and the report write it: 2 significant digits, "< 1e-300" below, "-"
/// where not tested (NaN).
std::string pValueText(double p);

using processing::sizeText;

/// One variable's evidence in the baseline's residual, as the text's table and the report's
/// write it: the slope per unit (0 where its trend over the variable's range is below a
/// millionth of the residual's RMS: the own baseline takes the position's trend exactly, to a
/// slope of 1e-19), the trend's p, the strongest period with its false-alarm probability, the
/// Durbin-Watson statistic and the Ljung-Box p ("-" where not made).
struct EvidenceRow {
  std::string variable, slope, trend_p, period, durbin_watson, ljung_box_p;
};
std::vector<EvidenceRow> evidenceRows(const processing::DiagnosisData& data, const processing::Diagnosis& d);
/// How to read the evidence table, for the text and the report: "p: the chance that noise alone
/// shows as much in that one test (not corrected for the many tests of the table: a finding's
/// p is) ...". `unit`: as written.
std::string evidenceLegend(const std::string& unit);

/// The step between the directions, one test of the readings (not of a variable): "step between
/// the directions (mean of direction +1 less -1): -0.416 um, p 0.00056"; none where not made.
/// `unit`: as written (the report's µm); empty: the data's.
std::optional<std::string> directionStepText(const processing::DiagnosisData& data, const processing::Diagnosis& d,
                                             const std::string& unit = {});

/// The richer form a finding was found as, in words, for the text and the report: "tested as
/// thermal_growth (time_s) too: its further terms are not needed (delta BIC -4.0, p 0.0576)".
std::string replacedFormText(const processing::Finding::ReplacedForm& form);

/// Diagnoses a run (or EST readings from a file). Validation runs and the report come before
/// anything is stored: a bad one stores nothing. Progress: the search's steps.
/// @throws InputError for a request that cannot be diagnosed
DiagnosisAnalysis diagnose(Session& session, const DiagnoseRequest& request);

}  // namespace mtcal::services
