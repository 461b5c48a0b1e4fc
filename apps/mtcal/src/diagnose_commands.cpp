// mtcal diagnose: what the simulation gets wrong in a run (docs/diagnosis.md), rendered for
// people or as JSON.

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "cli_session.h"
#include "commands.h"
#include "mtcal/error.h"
#include "mtcal/services/archive.h"
#include "mtcal/services/diagnose.h"

namespace mtcal::app {
namespace {

/// The largest run id an option takes: a round number people read (a store of a trillion runs is
/// none), below 2^53, where every whole number is read exactly.
constexpr long long kLargestRunId = 999'999'999'999;

using DiagnoseOptions = services::DiagnoseRequest;

using services::pValueText;
using services::sizeText;

void printText(std::ostream& out, const processing::DiagnosisData& data, const processing::Diagnosis& d, double alpha) {
  out << fmt::format("Diagnosis of {}: {} data, {} points\n", data.source, data.kind, data.measured.size());
  out << fmt::format("model:      {}\n", data.model_description);
  out << fmt::format("baseline:   {}\n", data.baseline_description);
  out << fmt::format("validation: {}\n", data.fold_description);
  out << fmt::format("residual:   RMS {} {} fitted, {} held out (peak {} {})\n\n", sizeText(d.rms_um), data.value_unit,
                     sizeText(d.heldout_rms_um), sizeText(d.heldout_peak_um), data.value_unit);
  out << fmt::format("evidence in the baseline's residual ({})\n", services::evidenceLegend(data.value_unit));
  // The variables' column as wide as the longest name (a fit of several runs names them "run 3: ...").
  const auto rows = services::evidenceRows(data, d);
  std::size_t width = 20;
  for (const auto& row : rows) width = std::max(width, row.variable.size());
  out << fmt::format("  {:<{}} slope/unit   trend p   period (false alarm)   Durbin-Watson  Ljung-Box p\n", "variable",
                     width);
  for (const auto& row : rows) {
    out << fmt::format("  {:<{}} {:>10}  {:>8}  {:>21}  {:>13}  {:>11}\n", row.variable, width, row.slope, row.trend_p,
                       row.period, row.durbin_watson, row.ljung_box_p);
  }
  if (const auto step = services::directionStepText(data, d)) out << "  " << *step << "\n";
  out << "\n";
  if (d.findings.empty())
    out << "findings: none. " << services::nothingNamedText(d, alpha, data.pooled_runs.size() > 1) << "\n";
  for (std::size_t k = 0; k < d.findings.size(); ++k) {
    const auto& f = d.findings[k];
    out << fmt::format("{}. {} ({}): {}\n", k + 1, f.candidate.effect, f.candidate.variable, f.candidate.cause);
    for (const auto& p : f.parameters) {
      out << "     " << services::parameterText(p) << "\n";
    }
    out << fmt::format("     evidence: delta BIC {:.1f}, p {}\n", f.delta_bic, pValueText(f.p_value));
    out << fmt::format("     held out{}: RMS {} -> {} {} (gain {:.1f} %), peak {} -> {} {}\n",
                       services::heldOutScope(f), sizeText(f.rms_before_um), sizeText(f.rms_after_um), data.value_unit,
                       100.0 * f.gain, sizeText(f.peak_before_um), sizeText(f.peak_after_um), data.value_unit);
    if (!f.alternatives.empty())
      out << fmt::format("     cannot be told apart from: {}\n", fmt::join(f.alternatives, ", "));
    if (f.replaced_form) out << "     " << services::replacedFormText(*f.replaced_form) << "\n";
    for (const auto& o : f.other_forms) out << "     " << services::otherFormText(o) << "\n";
  }
  if (!d.findings.empty()) {
    out << fmt::format("\nwith every finding: held-out RMS {} -> {} {} (gain {:.1f} %), peak {} -> {} {}\n",
                       sizeText(d.heldout_rms_um), sizeText(d.final_heldout_rms_um), data.value_unit, 100.0 * d.gain,
                       sizeText(d.heldout_peak_um), sizeText(d.final_heldout_peak_um), data.value_unit);
  }
  for (const auto& w : d.warnings) out << "warning: " << w << "\n";
  for (const auto& n : d.notes) out << "note: " << n << "\n";
}

int diagnoseCommand(const Globals& g, const DiagnoseOptions& o) {
  CliSession cli(g);
  const auto a = services::diagnose(cli.session, o);
  cli.observer.finish();
  if (jsonPrinted(g, a.document())) return 0;
  printText(*g.out, a.data, a.diagnosis, a.options.alpha);
  for (const auto& [run_id, v] : a.validations) {
    if (!services::anyFindingToApply(a.diagnosis)) {  // none, or the set-up's only
      *g.out << fmt::format("validated on {}: no finding to apply ({} points, RMS {} {} about its own baseline)\n",
                            v.source, v.points, sizeText(v.rms_before_um), a.data.value_unit);
      continue;
    }
    *g.out << fmt::format(
        "validated on {} ({} points, the findings' coefficients fixed): RMS {} -> {} {} (gain {:.1f} %), peak "
        "{} -> {} {}{}{}\n",
        v.source, v.points, sizeText(v.rms_before_um), sizeText(v.rms_after_um), a.data.value_unit, 100.0 * v.gain,
        sizeText(v.peak_before_um), sizeText(v.peak_after_um), a.data.value_unit,
        v.applied.empty() ? "; applied: none" : fmt::format("; applied: {}", fmt::join(v.applied, ", ")),
        v.left_out.empty()
            ? ""
            : fmt::format("; left out (the run lacks their variables, they are another kind's, or the set-up's): {}",
                          fmt::join(v.left_out, ", ")));
  }
  if (a.model_id) {
    *g.out << fmt::format("\n{}: model {} (model {} with the extensions; later diagnoses against it use them)\n",
                          a.model_already_stored ? "already stored, the same version" : "stored", *a.model_id,
                          o.against);
  } else if (a.result_id != 0 && !a.diagnosis.findings.empty()) {
    if (o.against == 0)
      *g.out << "\nthe extensions are stored with the result; diagnose against a model (--against) to store them as "
                "a model version\n";
    else if (!services::anyFindingToApply(a.diagnosis))
      *g.out << "\nno new model version: the findings are the set-up's, not the machine's; they are stored with the "
                "result\n";
  }
  if (!a.report_files.empty()) *g.out << fmt::format("report: {}\n", o.report_dir);
  return 0;
}

}  // namespace

void registerDiagnoseCommands(CliContext& c) {
  auto o = std::make_shared<DiagnoseOptions>();
  auto* diagnose_cmd = c.app->add_subcommand(
      "diagnose",
      "what the model gets wrong in a run: residual, evidence, named causes, model extension, held-out gain");
  diagnose_cmd->add_option("RUN", o->runs,
                           "run id (linear, circle, thermal, est or gantry); several, or cN (every completed or "
                           "imported run of campaign N): one fit, a cause common to them estimated once. Runs of one "
                           "kind share every cause; runs of different kinds keep their own and share what two of them "
                           "read (a drive's lost motion in a positioning run and a circle); est runs only with est "
                           "runs");
  diagnose_cmd
      ->add_option_function<std::string>(
          "--against", [o](const std::string& text) { o->against = services::modelIdOf(text); },
          "model (m2 or 2) predicting the run (its geometry for linear runs and circles, its extensions for every "
          "kind); a new model version stores the findings")
      ->check(CLI::Validator(
          [](std::string& text) -> std::string {
            try {
              services::modelIdOf(text);
              return {};
            } catch (const InputError& e) {
              return e.what();
            }
          },
          "MODEL", "model"));
  diagnose_cmd
      ->add_option("--report", o->report_dir,
                   "folder for the report: report.html (findings in words, held-out gain, the checks on other "
                   "runs) and its residual plots (SVG)")
      ->check(notEmpty("a folder", "DIR"));
  diagnose_cmd->add_option("--target", o->thermal_target, "thermal runs: the displacement channel (default: the first)")
      ->check(notEmpty("a channel's name", "NAME"));
  diagnose_cmd->add_option(
      "--est", o->est_csv,
      "EST data from a file: x_mm,v1_um,v2_um,v3_um (three probes)[,s1_um,s2_um,s3_um,readings] (their scatter)");
  diagnose_cmd->add_option("--spacing-mm", o->spacing_mm, "with --est: the probe spacing (= the step)")
      ->check(positive());
  auto csv = std::make_shared<CsvOptions>();
  addCsvOptions(diagnose_cmd, *csv);
  diagnose_cmd->add_option("--alpha", o->alpha, "family-wise chance of a finding on effect-free data")
      ->capture_default_str()
      ->check(between(1e-6, 0.5));
  diagnose_cmd
      ->add_option("--max-findings", o->max_findings,
                   fmt::format("most causes named in all (default {0}; runs of several kinds or errors in one fit: "
                               "{0} for each, at most {1})",
                               services::kDefaultMaxFindings, services::kMostFindings))
      ->transform(wholeBetween(1, services::kMostFindings));
  diagnose_cmd
      ->add_option(
          "--validate", o->validate_runs,
          "other runs of the same kind (other positions or times): the findings applied with their coefficients fixed")
      ->transform(wholeBetween(1, kLargestRunId));
  diagnose_cmd
      ->add_option("--knot-spacing-mm", o->knot_spacing_mm,
                   fmt::format("a linear run's own error curve: smallest knot spacing (default {})",
                               processing::kDefaultKnotSpacingMm))
      ->check(between(processing::kFinestKnotSpacingMm, processing::kCoarsestKnotSpacingMm));
  c.on(diagnose_cmd, [&c, o, csv] {
    o->est_csv_dialect = csv->dialect();
    return diagnoseCommand(c.g, *o);
  });
}

}  // namespace mtcal::app
