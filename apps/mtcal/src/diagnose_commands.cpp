// mtcal diagnose: what the simulation gets wrong in a run (docs/diagnosis.md). The run's
// residual against the model (or its own baseline), the evidence, the named causes with their
// parameters and held-out gain, a new model version with the extensions when a model was
// given, and a report folder with the residual plots.

#include <filesystem>
#include <fstream>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "commands.h"
#include "mtcal/acquisition/columns_csv.h"
#include "mtcal/acquisition/diagnosis_data.h"
#include "mtcal/services/version.h"
#include "mtcal/error.h"
#include "svg_plot.h"

namespace mtcal::app {
namespace {

std::vector<double> stdVector(const Eigen::VectorXd& v) { return {v.data(), v.data() + v.size()}; }

std::string pText(double p) { return p <= 0.0 ? "< 1e-300" : fmt::format("{:.2g}", p); }

nlohmann::json findingJson(const processing::Finding& f) {
  nlohmann::json parameters = nlohmann::json::object();
  for (const auto& p : f.parameters) parameters[p.name] = {{"value", p.value}, {"unit", p.unit}, {"standard_error", p.standard_error}};
  return {{"effect", f.candidate.effect},
          {"cause", f.candidate.cause},
          {"variable", f.candidate.variable},
          {"parameters", parameters},
          {"evidence", {{"delta_bic", f.delta_bic}, {"p_value", f.p_value}}},
          {"rms_before_um", f.rms_before_um},
          {"rms_after_um", f.rms_after_um},
          {"peak_before_um", f.peak_before_um},
          {"peak_after_um", f.peak_after_um},
          {"gain", f.gain},
          {"alternatives", f.alternatives}};
}

nlohmann::json diagnosisJson(const processing::DiagnosisData& data, const processing::Diagnosis& d, const processing::DiagnosisOptions& options) {
  nlohmann::json findings = nlohmann::json::array();
  for (const auto& f : d.findings) findings.push_back(findingJson(f));
  nlohmann::json evidence = nlohmann::json::object();
  for (const auto& [name, e] : d.evidence) {
    evidence[name] = {{"slope", e.slope},   {"trend_p", e.trend_p},     {"step", e.step},
                      {"step_p", e.step_p}, {"period", e.period},       {"period_amplitude", e.period_amplitude},
                      {"period_false_alarm", e.period_false_alarm},     {"durbin_watson", e.durbin_watson},
                      {"ljung_box_p", e.ljung_box_p}};
  }
  return {{"kind", data.kind},
          {"source", data.source},
          {"points", data.measured.size()},
          {"model", data.model_description},
          {"baseline",
           {{"rms_um", d.rms_um},
            {"heldout_rms_um", d.heldout_rms_um},
            {"heldout_peak_um", d.heldout_peak_um},
            {"description", data.baseline_description},
            {"validation", data.fold_description}}},
          {"findings", findings},
          {"after", {{"heldout_rms_um", d.final_heldout_rms_um}, {"heldout_peak_um", d.final_heldout_peak_um}, {"gain", d.gain}}},
          {"evidence", evidence},
          {"alpha", options.alpha},
          {"candidates_tried", d.candidates_tried},
          {"warnings", d.warnings},
          {"notes", d.notes}};
}

void printText(std::ostream& out, const processing::DiagnosisData& data, const processing::Diagnosis& d) {
  out << fmt::format("Diagnosis of {} ({} data, {} points)\n", data.source, data.kind, data.measured.size());
  out << fmt::format("model:      {}\n", data.model_description);
  out << fmt::format("baseline:   {}\n", data.baseline_description);
  out << fmt::format("validation: {}\n", data.fold_description);
  out << fmt::format("residual:   RMS {:.3f} {} fitted, {:.3f} held out (peak {:.3f})\n\n", d.rms_um, data.value_unit, d.heldout_rms_um,
                     d.heldout_peak_um);
  out << "evidence in the baseline's residual (p: the chance that noise alone shows as much)\n";
  out << "  variable             slope/unit   trend p   step p    period (false alarm)   Durbin-Watson  Ljung-Box p\n";
  for (const auto& [name, e] : d.evidence) {
    out << fmt::format("  {:<20} {:>10.4g}  {:>8}  {:>7}  {:>21}  {:>13.2f}  {:>11}\n", name, e.slope, pText(e.trend_p), pText(e.step_p),
                       e.period > 0.0 ? fmt::format("{:.4g} ({})", e.period, pText(e.period_false_alarm)) : std::string("-"),
                       e.durbin_watson, pText(e.ljung_box_p));
  }
  out << "\n";
  if (d.findings.empty()) {
    out << fmt::format("findings: none. No named cause or dependence on a variable passes the test ({} tried): the model explains "
                       "this run to within its scatter.\n",
                       d.candidates_tried);
  }
  for (std::size_t k = 0; k < d.findings.size(); ++k) {
    const auto& f = d.findings[k];
    out << fmt::format("{}. {} ({}): {}\n", k + 1, f.candidate.effect, f.candidate.variable, f.candidate.cause);
    for (const auto& p : f.parameters) {
      out << fmt::format("     {} = {:.4g}{} {}\n", p.name, p.value, p.standard_error > 0.0 ? fmt::format(" +- {:.2g}", p.standard_error) : "",
                         p.unit);
    }
    out << fmt::format("     evidence: delta BIC {:.1f}, p {}\n", f.delta_bic, pText(f.p_value));
    out << fmt::format("     held out: RMS {:.3f} -> {:.3f} {} (gain {:.1f} %), peak {:.3f} -> {:.3f}\n", f.rms_before_um, f.rms_after_um,
                       data.value_unit, 100.0 * f.gain, f.peak_before_um, f.peak_after_um);
    if (!f.alternatives.empty()) out << fmt::format("     cannot be told apart from: {}\n", fmt::join(f.alternatives, ", "));
  }
  if (!d.findings.empty()) {
    out << fmt::format("\nwith every finding: held-out RMS {:.3f} -> {:.3f} {} (gain {:.1f} %), peak {:.3f} -> {:.3f}\n", d.heldout_rms_um,
                       d.final_heldout_rms_um, data.value_unit, 100.0 * d.gain, d.heldout_peak_um, d.final_heldout_peak_um);
  }
  for (const auto& w : d.warnings) out << "warning: " << w << "\n";
  for (const auto& n : d.notes) out << "note: " << n << "\n";
}

/// The report folder: residuals before and after against the main variable, held out and
/// fitted, and against time when the data have it. @return the files written
std::vector<std::string> writeReport(const std::string& dir, const processing::DiagnosisData& data, const processing::Diagnosis& d) {
  std::filesystem::create_directories(dir);
  std::vector<std::string> files;
  auto write = [&](const std::string& name, const Plot& plot) {
    const auto path = (std::filesystem::path(dir) / name).string();
    std::ofstream f(path);
    if (!f) throw InputError(path + ": cannot write the report");
    f << plotSvg(plot);
    files.push_back(path);
  };
  std::vector<std::string> variables{data.main_variable};
  if (data.main_variable != "time_s" && data.variable("time_s")) variables.push_back("time_s");
  for (const auto& name : variables) {
    const auto x = stdVector(data.variable(name)->values);
    const std::string unit = data.value_unit;
    write(fmt::format("residual-vs-{}.svg", name),
          {fmt::format("{}: residual before and after the findings (fitted)", data.source), name, fmt::format("residual ({})", unit),
           {{"before", "#999999", x, stdVector(d.residual_before)}, {"after", "#1f5fbf", x, stdVector(d.residual_after)}}});
    write(fmt::format("heldout-vs-{}.svg", name),
          {fmt::format("{}: held-out residual before and after ({})", data.source, data.fold_description), name,
           fmt::format("held-out residual ({})", unit),
           {{"before", "#999999", x, stdVector(d.heldout_before)}, {"after", "#c0392b", x, stdVector(d.heldout_after)}}});
  }
  return files;
}

}  // namespace

int diagnoseCommand(const Globals& g, const DiagnoseOptions& o) {
  processing::DiagnosisData data;
  std::string measures;
  std::unique_ptr<storage::Store> store;
  acquisition::RunDiagnosisOptions run_options;
  if (o.against != 0) run_options.model_id = o.against;
  run_options.thermal_target = o.thermal_target;
  run_options.min_knot_spacing_mm = o.knot_spacing_mm;
  if (!o.est_csv.empty()) {
    if (o.run_id != 0 || o.against != 0) throw InputError("diagnose: give a run or --est FILE, not both; --against takes linear runs");
    if (!(o.spacing_mm > 0.0)) throw InputError("diagnose --est: --spacing-mm (the probe spacing) is required");
    std::ifstream in(o.est_csv);
    if (!in) throw InputError(o.est_csv + ": cannot open file");
    const auto c = acquisition::readColumnsCsv(in, o.est_csv, {"x_mm", "v1_um", "v2_um", "v3_um"}, {});
    data = processing::estDiagnosisData({o.est_csv, c.at("x_mm"), c.at("v1_um"), c.at("v2_um"), c.at("v3_um"), o.spacing_mm});
  } else {
    if (o.run_id == 0) throw InputError("diagnose: give a run id (mtcal runs) or --est FILE");
    store = std::make_unique<storage::Store>(g.db);
    auto input = acquisition::diagnosisInputOfRun(*store, o.run_id, run_options);
    data = std::move(input.data);
    measures = input.measures;
  }
  processing::DiagnosisOptions options;
  options.alpha = o.alpha;
  options.max_findings = o.max_findings;
  const auto d = processing::diagnose(data, options);
  auto json = diagnosisJson(data, d, options);
  if (o.run_id != 0) json["run_id"] = o.run_id;
  std::vector<processing::ModelExtension> found;
  for (const auto& f : d.findings) found.push_back(processing::extensionOf(f));
  // Validation runs and the report come before anything is stored: a bad one stores nothing.
  std::vector<processing::Validation> validations;
  if (!o.validate_runs.empty()) {
    if (!store) throw InputError("diagnose --validate takes stored runs");
    nlohmann::json list = nlohmann::json::array();
    for (const auto v : o.validate_runs) {
      const auto other = acquisition::diagnosisInputOfRun(*store, v, run_options);
      if (other.data.kind != data.kind) throw InputError(fmt::format("run {} is {} data, not {}: it cannot validate these findings", v, other.data.kind, data.kind));
      const auto r = processing::validateExtensions(found, other.data);
      validations.push_back(r);
      list.push_back({{"run_id", v},           {"points", r.points},           {"rms_before_um", r.rms_before_um}, {"rms_after_um", r.rms_after_um},
                      {"peak_before_um", r.peak_before_um}, {"peak_after_um", r.peak_after_um}, {"gain", r.gain},
                      {"applied", r.applied}, {"left_out", r.left_out}});
    }
    json["validation"] = list;
  }
  if (!o.report_dir.empty()) json["report"] = writeReport(o.report_dir, data, d);
  if (store && o.against != 0 && !d.findings.empty()) {
    const auto model = acquisition::saveExtendedModel(*store, o.against, o.run_id, data.kind, measures, found, kVersion);
    json["model_id"] = model;
    json["based_on_model"] = o.against;
  }
  if (store) {
    const nlohmann::json parameters = {{"against", o.against}, {"alpha", o.alpha}, {"max_findings", o.max_findings}, {"target", o.thermal_target}};
    json["result_id"] = store->addResult(o.run_id, "diagnosis", kVersion, parameters.dump(), json.dump());
  }
  if (g.json) {
    *g.out << json.dump() << "\n";
    return 0;
  }
  printText(*g.out, data, d);
  for (const auto& v : validations) {
    *g.out << fmt::format("validated on {} ({} points, the findings' coefficients fixed): RMS {:.3f} -> {:.3f} {} (gain {:.1f} %), peak {:.3f} -> {:.3f}{}\n",
                          v.source, v.points, v.rms_before_um, v.rms_after_um, data.value_unit, 100.0 * v.gain, v.peak_before_um, v.peak_after_um,
                          v.left_out.empty() ? "" : fmt::format("; left out (variables the run lacks): {}", fmt::join(v.left_out, ", ")));
  }
  if (json.contains("model_id")) {
    *g.out << fmt::format("\nstored: model {} (model {} with the extensions; later diagnoses against it use them)\n", json["model_id"].get<storage::Id>(),
                          o.against);
  } else if (store && !d.findings.empty()) {
    *g.out << "\nthe extensions are stored with the result; diagnose against a model (--against) to store them as a model version\n";
  }
  if (json.contains("report")) *g.out << fmt::format("report: {}\n", o.report_dir);
  return 0;
}

}  // namespace mtcal::app
