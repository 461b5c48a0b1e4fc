#include "mtcal/services/diagnose.h"

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <functional>
#include <limits>
#include <map>
#include <set>

#include "mtcal/acquisition/csv.h"
#include "mtcal/acquisition/diagnosis_data.h"
#include "mtcal/error.h"
#include "mtcal/services/est.h"
#include "mtcal/services/model.h"
#include "mtcal/services/report.h"
#include "mtcal/services/svg_plot.h"
#include "mtcal/services/version.h"
#include "mtcal/services/workshop.h"

namespace mtcal::services {
namespace {

/// The kinds of run diagnose takes.
std::vector<std::string> diagnosableKinds() {
  return {storage::run_kind::kLinear, storage::run_kind::kCircle, storage::run_kind::kThermal, storage::run_kind::kEst,
          storage::run_kind::kGantry};
}

/// A number, or null where it is NaN (not made): as the stored document reads back.
nlohmann::json numberOrNull(double value) {
  return std::isnan(value) ? nlohmann::json(nullptr) : nlohmann::json(value);
}

nlohmann::json parametersJson(const std::vector<processing::ParameterValue>& values) {
  nlohmann::json parameters = nlohmann::json::object();
  for (const auto& p : values)
    parameters[p.name] = {{"value", p.value}, {"unit", p.unit}, {"standard_error", p.standard_error}};
  return parameters;
}

nlohmann::json otherForms(const processing::Finding& f) {
  nlohmann::json out = nlohmann::json::array();
  for (const auto& o : f.other_forms)
    out.push_back({{"cause", o.cause},
                   {"delta_bic", o.delta_bic},
                   {"delta_aic", o.delta_aic},
                   {"weight", o.weight},
                   {"parameters", parametersJson(o.parameters)}});
  return out;
}

nlohmann::json findingJson(const processing::Finding& f) {
  const nlohmann::json parameters = parametersJson(f.parameters);
  return {{"effect", f.candidate.effect},
          {"cause", f.candidate.cause},
          {"variable", f.candidate.variable},
          {"parameters", parameters},
          {"evidence",
           {{"delta_bic", f.delta_bic},
            {"p_value", f.p_value},
            {"p_value_model_error_refitted", numberOrNull(f.p_value_model_error_refitted)}}},
          {"rms_before_um", f.rms_before_um},
          {"rms_after_um", f.rms_after_um},
          {"peak_before_um", f.peak_before_um},
          {"peak_after_um", f.peak_after_um},
          {"gain", f.gain},
          {"heldout_runs", f.heldout_runs},
          {"alternatives", f.alternatives},
          {"other_forms", otherForms(f)},
          {"replaced_form", f.replaced_form ? nlohmann::json{{"cause", f.replaced_form->cause},
                                                             {"delta_bic", f.replaced_form->delta_bic},
                                                             {"p_value", f.replaced_form->p_value}}
                                            : nlohmann::json(nullptr)}};
}

nlohmann::json diagnosisJson(const processing::DiagnosisData& data, const processing::Diagnosis& d,
                             const processing::DiagnosisOptions& options) {
  nlohmann::json findings = nlohmann::json::array();
  for (const auto& f : d.findings) findings.push_back(findingJson(f));
  nlohmann::json evidence = nlohmann::json::object();
  for (const auto& [name, e] : d.evidence) {
    evidence[name] = {{"slope", e.slope},
                      {"trend_p", e.trend_p},
                      {"step", e.step},
                      {"step_p", e.step_p},
                      {"period", e.period},
                      {"period_amplitude", e.period_amplitude},
                      {"period_false_alarm", e.period_false_alarm},
                      {"durbin_watson", e.durbin_watson},
                      {"ljung_box_p", e.ljung_box_p}};
  }
  nlohmann::json considered = nlohmann::json::array();
  for (const auto& c : d.considered) {
    considered.push_back({{"round", c.round},
                          {"effect", c.effect},
                          {"variable", c.variable},
                          {"cause", c.cause},
                          {"delta_bic", numberOrNull(c.delta_bic)},
                          {"p_value", numberOrNull(c.p_value)},
                          {"heldout_rms_um", numberOrNull(c.heldout_rms_um)},
                          {"verdict", c.verdict}});
  }
  nlohmann::json disagree = nlohmann::json::array();
  for (const auto& r : d.runs_disagree) {
    nlohmann::json runs = nlohmann::json::array();
    for (const auto& run : r.runs)
      runs.push_back({{"source", run.source}, {"parameters", parametersJson(run.parameters)}});
    disagree.push_back({{"effect", r.effect},
                        {"variable", r.variable},
                        {"f", r.f},
                        {"dof", {std::lround(r.dof1), std::lround(r.dof2)}},
                        {"p_value", r.p_value},
                        {"runs", runs}});
  }
  nlohmann::json off_fit = nlohmann::json::array();
  for (const auto& o : d.readings_off_fit)
    off_fit.push_back({{"source", o.source}, {"points", o.points}, {"reversal_spikes", o.reversal_spikes}});
  return {
      {"kind", data.kind},
      {"source", data.source},
      {"points", data.measured.size()},
      {"value_unit", data.value_unit},
      {"model", data.model_description},
      {"baseline",
       {{"rms_um", d.rms_um},
        {"heldout_rms_um", d.heldout_rms_um},
        {"heldout_peak_um", d.heldout_peak_um},
        {"description", data.baseline_description},
        {"validation", data.fold_description}}},
      {"findings", findings},
      {"after",
       {{"heldout_rms_um", d.final_heldout_rms_um}, {"heldout_peak_um", d.final_heldout_peak_um}, {"gain", d.gain}}},
      {"evidence", evidence},
      {"alpha", options.alpha},
      {"candidates_tried", d.candidates_tried},
      {"considered", considered},
      {"warnings", d.warnings},
      {"runs_disagree", disagree},
      {"readings_off_fit", off_fit},
      {"stated_error",
       d.stated_error.what.empty()
           ? nlohmann::json(nullptr)
           : nlohmann::json{{"what", d.stated_error.what},
                            {"outcome", d.stated_error.outcome},
                            {"p_value", numberOrNull(d.stated_error.p_value)},
                            {"p_value_point_to_point", numberOrNull(d.stated_error.p_value_point_to_point)},
                            {"noise_rms_um", numberOrNull(d.stated_error.noise_rms)},
                            {"noise_dof", d.stated_error.noise_dof}}},
      {"notes", d.notes}};
}

/// Makes the report folder (it may exist). @throws InputError naming it and why
void makeReportFolder(const std::string& dir) {
  std::error_code error;
  std::filesystem::create_directories(dir, error);
  if (!error && !std::filesystem::is_directory(dir, error) && !error)
    error = std::make_error_code(std::errc::not_a_directory);
  if (error) throw InputError(fmt::format("{}: cannot make the report folder: {}", dir, error.message()));
  // A file written and removed: a folder that takes none is said before the fit, not after it.
  const auto probe = std::filesystem::path(dir) / fmt::format(".mtcal-write-check-{}", ::getpid());
  std::FILE* file = std::fopen(probe.c_str(), "wx");  // a new file, never one already there
  if (!file) throw InputError(fmt::format("{}: cannot write in the report folder: {}", dir, std::strerror(errno)));
  std::fclose(file);
  std::filesystem::remove(probe, error);
}

/// The report folder: the diagnosis' report (report.html) and its plots as SVG files.
/// @return the files written
std::vector<std::string> writeReport(Session& session, const std::string& dir, const DiagnosisAnalysis& a) {
  makeReportFolder(dir);
  // The plots and the page written together: one that cannot be written leaves none of them.
  std::vector<std::pair<std::string, std::string>> written;
  for (const auto& [name, plot] : diagnosisPlots(a.data, a.diagnosis))
    written.emplace_back((std::filesystem::path(dir) / name).string(), plotSvg(plot));
  written.emplace_back((std::filesystem::path(dir) / "report.html").string(), diagnosisReport(session, a).html);
  writeTextFiles(written);
  std::vector<std::string> files;
  for (const auto& [path, text] : written) files.push_back(path);
  // Plots of an earlier report in the folder stay, named: this report neither shows nor replaces them.
  std::vector<std::string> earlier;
  std::error_code error;
  for (const auto& entry : std::filesystem::directory_iterator(dir, error)) {
    const auto name = entry.path().filename().string();
    const bool plot = name.ends_with(".svg") && (name.starts_with("residual-vs-") || name.starts_with("heldout-vs-"));
    if (plot && std::find(files.begin(), files.end(), entry.path().string()) == files.end()) earlier.push_back(name);
  }
  if (!earlier.empty()) {
    std::sort(earlier.begin(), earlier.end());
    session.observer().onMessage(
        "warning", fmt::format("{}: {} of an earlier report, not this one's (report.html shows this one's plots)", dir,
                               fmt::join(earlier, ", ")));
  }
  return files;
}

/// `values` each once, in their order; for each repeat, a warning `said(value)` in `warnings`.
template <class T>
std::vector<T> eachOnce(const std::vector<T>& values, std::vector<std::string>& warnings,
                        const std::function<std::string(const T&)>& said) {
  std::vector<T> once;
  for (const auto& v : values) {
    if (std::find(once.begin(), once.end(), v) == once.end())
      once.push_back(v);
    else
      warnings.push_back(said(v));
  }
  return once;
}

}  // namespace

nlohmann::json DiagnosisAnalysis::document() const {
  auto json = diagnosisJson(data, diagnosis, options);
  json["schema_version"] = 1;
  if (run_id != 0) json["run_id"] = run_id;
  if (!pooled_runs.empty()) json["runs"] = pooled_runs;
  if (!validations.empty()) {
    nlohmann::json list = nlohmann::json::array();
    for (const auto& [v, r] : validations) {
      list.push_back({{"run_id", v},
                      {"points", r.points},
                      {"rms_before_um", r.rms_before_um},
                      {"rms_after_um", r.rms_after_um},
                      {"peak_before_um", r.peak_before_um},
                      {"peak_after_um", r.peak_after_um},
                      {"gain", r.gain},
                      {"applied", r.applied},
                      {"left_out", r.left_out}});
    }
    json["validation"] = list;
  }
  if (!report_files.empty()) json["report"] = report_files;
  if (model_id) {
    json["model_id"] = *model_id;
    json["model_already_stored"] = model_already_stored;
    json["based_on_model"] = based_on_model;
  }
  if (result_id != 0) json["result_id"] = result_id;
  return json;
}

bool anyFindingToApply(const processing::Diagnosis& d) {
  return std::any_of(d.findings.begin(), d.findings.end(),
                     [](const processing::Finding& f) { return !f.candidate.of_setup; });
}

std::string heldOutScope(const processing::Finding& f) {
  if (f.heldout_runs.empty()) return {};
  return fmt::format(" ({}'s points)", fmt::join(f.heldout_runs, " and "));
}

std::string nothingNamedText(const processing::Diagnosis& d, double alpha, bool several_runs) {
  std::vector<std::pair<double, std::string>> along;  // by the smaller of the two p values, strongest first
  for (const auto& [name, e] : d.evidence) {
    if (const double p = std::fmin(e.trend_p, e.ljung_box_p); p < alpha) along.emplace_back(p, name);  // NaN: untested
  }
  std::sort(along.begin(), along.end());
  const auto nothing =
      fmt::format("No named cause or dependence on a variable passes the test ({} tried)", d.candidates_tried);
  std::size_t off_fit = 0;
  for (const auto& o : d.readings_off_fit) off_fit += o.points.size();
  const std::string off_fit_text =
      off_fit == 0 ? std::string()
                   : fmt::format(
                         ", with {} far off the fit, which the tests include and which may hide a cause (see "
                         "the warnings)",
                         off_fit == 1 ? std::string("one reading") : fmt::format("{} readings", off_fit));
  if (along.empty()) {
    return nothing + (off_fit > 0
                          ? off_fit_text + "."
                          : fmt::format(": the model explains {} to within {} scatter.",
                                        several_runs ? "these runs" : "this run", several_runs ? "their" : "its"));
  }
  constexpr std::size_t kNamed = 4;  // the strongest named, the others counted
  std::string names;
  for (std::size_t k = 0; k < std::min(kNamed, along.size()); ++k) names += (k ? ", " : "") + along[k].second;
  if (along.size() > kNamed) names += fmt::format(" and {} more", along.size() - kNamed);
  return nothing + off_fit_text +
         fmt::format(
             "; the residual still has a trend or a correlation along {} (p below {:g}): what is left is none "
             "of the named causes, or too weak to be told from the model's own error.",
             names, alpha);
}

std::string parameterText(const processing::ParameterValue& p) {
  return fmt::format("{} = {} {}", p.name, processing::valueWithUncertainty(p.value, p.standard_error), p.unit);
}

std::string pValueText(double p) {
  if (std::isnan(p)) return "-";  // not tested
  return p < 1e-300 ? "< 1e-300" : fmt::format("{:.2g}", p);
}

std::vector<EvidenceRow> evidenceRows(const processing::DiagnosisData& data, const processing::Diagnosis& d) {
  std::vector<EvidenceRow> rows;
  for (const auto& [name, e] : d.evidence) {
    double range = std::numeric_limits<double>::infinity();
    std::string shown = name;  // with its unit where the name does not say it (a sensor's degC)
    if (const auto* variable = data.variable(name)) {
      // The name's suffix in lower case, degC as _c (air_temp_c, air_pressure_pa, position_mm).
      std::string suffix = variable->unit == "degC" ? "c" : variable->unit;
      std::transform(suffix.begin(), suffix.end(), suffix.begin(),
                     [](unsigned char ch) { return static_cast<char>(std::tolower(ch)); });
      if (!variable->unit.empty() && !name.ends_with("_" + suffix)) shown += " (" + variable->unit + ")";
      constexpr double kInfinity = std::numeric_limits<double>::infinity();
      const Eigen::ArrayXd& values = variable->values.array();
      range =
          values.isNaN().select(-kInfinity, values).maxCoeff() - values.isNaN().select(kInfinity, values).minCoeff();
    }
    const double slope = std::abs(e.slope) * range < 1e-6 * d.rms_um ? 0.0 : e.slope;
    // Four digits; below a thousandth in powers of ten (4.932e-06, not 0.000004932).
    const auto shownNumber = [](double value) {
      return value != 0.0 && std::abs(value) < 1e-3 ? fmt::format("{:.3e}", value) : processing::significant(value, 4);
    };
    rows.push_back(
        {shown, shownNumber(slope), pValueText(e.trend_p),
         e.period > 0.0 ? fmt::format("{} ({})", shownNumber(e.period), pValueText(e.period_false_alarm)) : "-",
         std::isnan(e.durbin_watson) ? std::string("-") : fmt::format("{:.2f}", e.durbin_watson),
         pValueText(e.ljung_box_p)});
  }
  return rows;
}

std::string evidenceLegend(const std::string& unit) {
  return fmt::format(
      "p: the chance that noise alone shows as much in that one test, not corrected for the table's many tests (a "
      "finding's p, in the findings, is corrected for every candidate tried); slope in {} per unit of the variable, "
      "period "
      "in its unit",
      unit);
}

std::optional<std::string> directionStepText(const processing::DiagnosisData& data, const processing::Diagnosis& d,
                                             const std::string& unit) {
  const auto main = d.evidence.find(data.main_variable);
  if (main == d.evidence.end() || !std::isfinite(main->second.step_p)) return std::nullopt;
  return fmt::format("step between the directions (mean of direction +1 less -1): {} {}, p {}",
                     sizeText(main->second.step), unit.empty() ? data.value_unit : unit,
                     pValueText(main->second.step_p));
}

std::string replacedFormText(const processing::Finding::ReplacedForm& form) {
  // p to 3 digits: 0.0101 beside an alpha of 0.01 is not 0.01.
  return fmt::format("tested as {} too: its further terms are not needed (delta BIC {:.1f}, p {:.3g})", form.cause,
                     form.delta_bic, form.p_value);
}

std::string otherFormText(const processing::Finding::OtherForm& form,
                          const std::function<std::string(const processing::ParameterValue&)>& parameter) {
  std::string values;
  for (const auto& p : form.parameters) values += (values.empty() ? "" : ", ") + parameter(p);
  // A lower BIC than the finding's: the form named was chosen when its cause entered, against
  // the findings before it (or by the backward check); the other form is weighed beside every
  // finding.
  return fmt::format(
      "another form of the cause: {} (BIC {:+.1f}, AIC {:+.1f}, Akaike weight {:.0f} %) gives {}; its spread is "
      "counted in the standard errors{}",
      form.cause, form.delta_bic, form.delta_aic, 100.0 * form.weight, values,
      form.delta_bic < 0.0 ? "; beside every other finding it fits better than the form named (a cause's form is "
                             "chosen as the cause enters the search, against the findings before it, or by the "
                             "backward check)"
                           : "");
}

DiagnosisAnalysis diagnose(Session& session, const DiagnoseRequest& o) {
  DiagnosisAnalysis a;
  std::vector<std::string> given_twice;  // warnings of the diagnosis
  // Every run of the fit: its id, the source its data name it by, its kind and what it measures.
  struct PooledRun {
    storage::Id id;
    std::string source, kind, measures, machine;
  };
  std::vector<PooledRun> members;
  std::vector<processing::DiagnosisData> pooled_inputs;  // each run of one fit, kept where others validate it
  // A run of the fit of this kind that measures this error: the findings' part for its readings.
  const auto memberMeasuring = [&](const std::string& kind, const std::string& measures) {
    return std::find_if(members.begin(), members.end(),
                        [&](const PooledRun& m) { return m.kind == kind && m.measures == measures; });
  };
  storage::Store* store = nullptr;
  acquisition::RunDiagnosisOptions run_options;
  if (o.against != 0) run_options.model_id = o.against;
  run_options.thermal_target = o.thermal_target;
  run_options.min_knot_spacing_mm = o.knot_spacing_mm.value_or(processing::kDefaultKnotSpacingMm);
  if (!o.est_csv.empty()) {
    if (o.run_id != 0 || !o.runs.empty()) throw InputError("diagnose: give a run or --est FILE, not both");
    if (o.against != 0)
      throw InputError("diagnose --est FILE: --against takes a stored run (a file has no machine to predict it)");
    if (!o.thermal_target.empty()) throw InputError("diagnose --est FILE: --target names a thermal run's displacement");
    if (o.knot_spacing_mm)
      throw InputError(
          "diagnose --est FILE: --knot-spacing-mm is a linear run's baseline (an EST run's is the probes')");
    if (o.spacing_mm == 0.0) throw InputError("diagnose --est: --spacing-mm (the probe spacing, mm) is required");
    if (!(o.spacing_mm > 0.0) || !std::isfinite(o.spacing_mm))
      throw InputError(fmt::format("diagnose --est: --spacing-mm {}: the probe spacing must be a positive length in mm",
                                   o.spacing_mm));
    auto c = readProbeCsv(o.est_csv, false, o.est_csv_dialect);
    if (c.v3_um.empty())
      throw InputError(
          fmt::format("{}: two probes (no v3_um column): a diagnosis tests what a third probe reads "
                      "against the two-probe prediction, so it needs x_mm, v1_um, v2_um, v3_um",
                      o.est_csv));
    c.spacing_mm = o.spacing_mm;
    a.data = processing::estDiagnosisData(c);
  } else {
    if (o.run_id == 0 && o.runs.empty()) throw InputError("diagnose: give a run id (mtcal runs) or --est FILE");
    if (o.spacing_mm != 0.0) throw InputError("diagnose: --spacing-mm is for --est FILE (a stored run has its own)");
    if (o.knot_spacing_mm && o.against != 0)
      throw InputError(
          "diagnose: --knot-spacing-mm sets a linear run's own error curve, which a diagnosis against a model "
          "(--against) does not fit (its baseline is the model's prediction): give one or the other");
    const auto& dialect = o.est_csv_dialect;
    if (dialect.delimiter != 0 || dialect.decimal != 0 || !dialect.columns.empty())
      throw InputError(
          "diagnose: --delimiter, --decimal and --columns are how --est FILE is written (a stored run was read when "
          "it was imported)");
    store = &session.store();
    const auto runs_once = eachOnce<std::string>(o.runs, given_twice, [](const std::string& run) {
      return fmt::format("{}{} is given twice: it is diagnosed once",
                         run.find_first_not_of("0123456789") == std::string::npos ? "run " : "", run);
    });
    std::vector<storage::Id> ids;
    if (o.run_id != 0) ids.push_back(o.run_id);
    std::vector<storage::Id> in_two_ways;  // by its id and its campaign
    for (const auto id : resolveRuns(*store, runs_once, diagnosableKinds(), &in_two_ways)) {
      if (std::find(ids.begin(), ids.end(), id) == ids.end()) ids.push_back(id);
    }
    for (const auto id : in_two_ways)
      given_twice.push_back(fmt::format("run {} is given twice: it is diagnosed once", id));
    a.run_id = ids.front();
    std::vector<processing::DiagnosisData> runs;
    for (const auto id : ids) {
      // Runs of one kind that read different errors (a campaign's X, Y and Z positioning) are one
      // fit: each error's runs share their causes, and the errors share only the quantities they
      // all read (processing::poolDiagnosisData).
      auto input = acquisition::diagnosisInputOfRun(*store, id, run_options);
      if (auto warning = acquisition::unfinishedRunWarning(input.run))
        input.data.warnings.push_back(std::move(*warning));
      for (auto& warning : acquisition::importWarnings(input.run)) input.data.warnings.push_back(std::move(warning));
      members.push_back({id, input.data.source, input.data.kind, input.measures, input.run.machine_name});
      runs.push_back(std::move(input.data));
    }
    if (!o.thermal_target.empty() &&
        std::none_of(members.begin(), members.end(), [](const PooledRun& m) { return m.kind == "thermal"; }))
      throw InputError("diagnose: --target names a thermal run's displacement; no run here is a thermal one");
    if (o.knot_spacing_mm &&
        std::none_of(members.begin(), members.end(), [](const PooledRun& m) { return m.kind == "linear"; }))
      throw InputError("diagnose: --knot-spacing-mm sets a linear run's own error curve; no run here is a linear one");
    if (runs.size() == 1) {
      a.data = std::move(runs.front());
    } else {
      a.data = processing::poolDiagnosisData(runs);
      a.pooled_runs = ids;
      if (!o.validate_runs.empty()) pooled_inputs = std::move(runs);
    }
    // A cause common to the runs is estimated once: runs of different machines share none.
    std::map<std::string, std::vector<storage::Id>> by_machine;
    for (const auto& m : members) by_machine[m.machine].push_back(m.id);
    if (const auto it = by_machine.find(storage::kImportedMachine); it != by_machine.end() && it->second.size() > 1) {
      a.data.warnings.push_back(
          fmt::format("runs {} were imported without a machine's name (import --machine NAME): they are taken as one "
                      "machine's, a cause common to them estimated once",
                      fmt::join(it->second, ", ")));
    }
    if (o.against != 0) {
      // The machine the model was identified on: runs of another are predicted by another's model.
      std::set<std::string> model_machines;
      std::vector<storage::Id> model_runs;
      // Runs imported without a machine's name are of a machine not known: compared with none.
      for (const auto id : identifyingRuns(store->model(o.against)).runs) {
        try {
          if (const auto machine = store->run(id).machine_name; machine != storage::kImportedMachine) {
            model_machines.insert(machine);
            model_runs.push_back(id);
          }
        } catch (const InputError&) {  // a run since deleted: its machine is not known
        }
      }
      std::vector<std::string> other;
      for (const auto& m : members) {
        if (!model_machines.empty() && m.machine != storage::kImportedMachine && !model_machines.contains(m.machine))
          other.push_back(fmt::format("run {} of {}", m.id, m.machine));
      }
      if (!other.empty())
        a.data.warnings.push_back(fmt::format(
            "model {} was identified on {} (run{} {}), {}: a model of another machine predicts these readings",
            o.against, fmt::join(model_machines, " and "), model_runs.size() > 1 ? "s" : "",
            fmt::join(model_runs, ", "), fmt::join(other, ", ")));
    }
    if (by_machine.size() > 1) {
      std::vector<std::string> machines;
      for (const auto& [machine, runs_of_it] : by_machine)
        machines.push_back(
            fmt::format("{} (run{} {})", machine, runs_of_it.size() > 1 ? "s" : "", fmt::join(runs_of_it, ", ")));
      a.data.warnings.push_back(
          fmt::format("the runs are of {} machines, {}: a cause common to the runs is estimated once, as "
                      "if it were one machine's",
                      by_machine.size(), fmt::join(machines, "; ")));
    }
  }
  // The runs that will check the findings, read and checked before the fit: a wrong one is
  // named at once, not after it.
  std::vector<acquisition::RunDiagnosisInput> checks;
  const auto validate_runs = eachOnce<storage::Id>(o.validate_runs, given_twice, [](const storage::Id& run) {
    return fmt::format("--validate {} is given twice: it validates once", run);
  });
  if (!validate_runs.empty()) {
    if (!store) throw InputError("diagnose --validate takes stored runs");
    const auto kinds = "+" + a.data.kind + "+";  // a fit of runs of different kinds: linear+circle
    for (const auto v : validate_runs) {
      if (std::any_of(members.begin(), members.end(), [&](const PooledRun& m) { return m.id == v; }))
        throw InputError(fmt::format("run {} is diagnosed: it cannot validate its own findings", v));
      try {
        checks.push_back(acquisition::diagnosisInputOfRun(*store, v, run_options));
      } catch (const InputError& e) {
        throw InputError(fmt::format("--validate {}: {}", v, e.what()));
      }
      const auto& check = checks.back();
      if (auto warning = acquisition::unfinishedRunWarning(check.run))
        a.data.warnings.push_back(fmt::format("validation: {}", *warning));
      // Findings are a machine's: on another machine's run they check whether it has them too.
      // A run imported without a machine's name is of a machine not known: it may be another.
      if (!members.empty() && std::none_of(members.begin(), members.end(),
                                           [&](const PooledRun& m) { return m.machine == check.run.machine_name; })) {
        const auto named = [](const std::string& machine) {
          return machine == storage::kImportedMachine ? std::string("a machine not named (imported without --machine)")
                                                      : machine;
        };
        const bool known =
            check.run.machine_name != storage::kImportedMachine && members.front().machine != storage::kImportedMachine;
        a.data.warnings.push_back(
            fmt::format("validation: run {} is of {}, the diagnosed run{} of {}: the findings {} applied to another "
                        "machine's readings",
                        v, named(check.run.machine_name), members.size() > 1 ? "s" : "", named(members.front().machine),
                        known ? "are" : "may be"));
      }
      for (const auto& warning : acquisition::importWarnings(check.run))
        a.data.warnings.push_back(fmt::format("validation: {}", warning));
      if (kinds.find("+" + check.data.kind + "+") == std::string::npos) {
        throw InputError(fmt::format("run {} is {} data, not {}: it cannot validate these findings", v, check.data.kind,
                                     a.data.kind));
      }
      // A finding is an error's: checked on runs of an error a diagnosed run reads.
      if (memberMeasuring(check.data.kind, check.measures) == members.end()) {
        std::vector<std::string> read;
        for (const auto& m : members) {
          if (m.kind == check.data.kind) read.push_back(fmt::format("run {} {}", m.id, m.measures));
        }
        throw InputError(
            fmt::format("run {} measures {}, which no diagnosed run reads ({}): the findings are an "
                        "error's, checked on runs of that error",
                        v, check.measures, fmt::join(read, ", ")));
      }
      // A copy of a diagnosed run holds the readings the findings were fitted to: it checks nothing.
      const auto copy_of_diagnosed = [&](const processing::DiagnosisData& diagnosed) {
        if (const auto copy = processing::copyRelation(diagnosed, check.data); !copy.empty())
          throw InputError(
              fmt::format("{}: the run that validates and a diagnosed run hold the same readings, to which "
                          "the findings were fitted; validate with another run",
                          copy));
      };
      if (pooled_inputs.empty()) copy_of_diagnosed(a.data);
      for (const auto& diagnosed : pooled_inputs) copy_of_diagnosed(diagnosed);
    }
    pooled_inputs.clear();  // checked: the fit has them pooled
  }
  a.options.alpha = o.alpha;
  // Each kind and error of runs in one fit searched for as many causes as one run.
  std::set<std::pair<std::string, std::string>> parts;
  for (const auto& m : members) parts.insert({m.kind, m.measures});
  const int max_findings = o.max_findings.value_or(
      std::min(kMostFindings, kDefaultMaxFindings * std::max<int>(1, static_cast<int>(parts.size()))));
  a.options.max_findings = max_findings;
  std::optional<ProgressClock> clock;  // from the first test, when the search knows how many there are
  const auto passes = static_cast<std::size_t>(processing::expectedDiagnosisPasses(a.data));
  a.options.on_progress = [&](std::size_t done, std::size_t total) {
    if (!clock) clock.emplace(total);
    // At most one round of every candidate per finding allowed: the search stops when a round
    // names nothing, and the count then jumps to the end.
    session.observer().onProgress(
        clock->at(done, fmt::format("tests of candidate causes (up to {} rounds of {}{})", max_findings,
                                    total / passes / static_cast<std::size_t>(std::max(max_findings, 1)),
                                    passes > 1 ? ", twice: the noise estimated, then as stated" : "")));
  };
  // Said before the fit, which may take long, not after it.
  if (!o.report_dir.empty()) makeReportFolder(o.report_dir);
  a.diagnosis = processing::diagnose(a.data, a.options);
  a.diagnosis.warnings.insert(a.diagnosis.warnings.begin(), given_twice.begin(), given_twice.end());
  // Reversal spikes are seen in the residual against the circle's angle, which the report plots.
  if (o.report_dir.empty() &&
      std::any_of(a.diagnosis.readings_off_fit.begin(), a.diagnosis.readings_off_fit.end(),
                  [](const processing::Diagnosis::ReadingsOffFit& r) { return r.reversal_spikes; }))
    a.diagnosis.notes.push_back(
        "the reversal spikes show in the residual against the angle: --report DIR writes the diagnosis's report, "
        "which plots it");
  a.options.on_progress = nullptr;
  // A property of the set-up (a circle's centre, the probes' zeros) is this run's, not the
  // machine's: not stored in a model, not applied to another run.
  std::vector<processing::ModelExtension> found;
  std::vector<std::string> of_setup;
  for (const auto& f : a.diagnosis.findings) {
    if (f.candidate.of_setup)
      of_setup.push_back(f.candidate.effect);
    else
      found.push_back(processing::extensionOf(f));
  }
  if (!of_setup.empty() && (o.against != 0 || !checks.empty()))
    a.diagnosis.notes.push_back(fmt::format("{} {} the set-up's (where the instrument sits), not the machine's: {}",
                                            fmt::join(of_setup, " and "), of_setup.size() == 1 ? "is" : "are",
                                            o.against != 0 && !checks.empty()
                                                ? "not part of the extended model nor applied to the runs that validate"
                                            : o.against != 0 ? "not part of the extended model"
                                                             : "not applied to the runs that validate"));
  // What each finding is for the model: for the readings of its run's kind (runs of different
  // kinds in one fit: each run's own part of it, one part per kind and measured error, so that a
  // later run is not corrected twice by one finding read in two runs of its kind).
  std::vector<acquisition::AppliedExtension> added;
  for (const auto& e : found) {
    const std::size_t first_part = added.size();
    for (auto& [runs, extension] : processing::extensionsByRun(e)) {
      // The run the part is of; of runs of one error fitted as one beside others, the first.
      const auto member = std::find_if(members.begin(), members.end(), [&](const PooledRun& m) {
        return runs.empty() ? m.id == a.run_id : m.source == runs.front();
      });
      const std::string kind = member != members.end() ? member->kind : a.data.kind;
      const std::string measured = member != members.end() ? member->measures : std::string();
      const auto read_twice =
          std::any_of(added.begin() + static_cast<std::ptrdiff_t>(first_part), added.end(),
                      [&](const acquisition::AppliedExtension& x) { return x.kind == kind && x.measures == measured; });
      if (!read_twice)
        added.push_back({std::move(extension), kind, measured, member != members.end() ? member->id : a.run_id});
    }
  }
  // Validation runs and the report come before anything is stored: a bad one stores nothing.
  for (std::size_t k = 0; k < checks.size(); ++k) {
    const auto& other = checks[k].data;
    std::vector<processing::ModelExtension> for_kind;
    for (const auto& e : added) {
      if (e.kind == other.kind && e.measures == checks[k].measures) for_kind.push_back(e.extension);
    }
    auto validation = processing::validateExtensions(for_kind, other);
    // A finding with no part for this kind of run (a circle's squareness, a linear run checked)
    // is left out too, as is the set-up's.
    for (const auto& f : a.diagnosis.findings) {
      const bool applies = std::any_of(for_kind.begin(), for_kind.end(), [&](const processing::ModelExtension& x) {
        return x.effect == f.candidate.effect;
      });
      if (!applies && std::find(validation.left_out.begin(), validation.left_out.end(), f.candidate.effect) ==
                          validation.left_out.end())
        validation.left_out.push_back(f.candidate.effect);
    }
    a.validations.push_back({validate_runs[k], std::move(validation)});
  }
  if (!o.report_dir.empty()) a.report_files = writeReport(session, o.report_dir, a);
  if (store && o.against != 0 && !added.empty() && store->readOnly()) {
    session.observer().onMessage("warning", "the store is read-only: the extended model is not stored");
  } else if (store && o.against != 0 && !added.empty()) {
    const auto saved = acquisition::saveExtendedModel(*store, o.against, a.run_id, added, kVersion);
    a.model_id = saved.id;
    a.model_already_stored = saved.already_stored;
    a.based_on_model = o.against;
  }
  if (store) {
    const nlohmann::json parameters = {
        {"against", o.against},
        {"alpha", o.alpha},
        {"max_findings", max_findings},
        {"target", o.thermal_target},
        {"runs", a.pooled_runs},
        {"knot_spacing_mm", o.knot_spacing_mm ? nlohmann::json(*o.knot_spacing_mm) : nlohmann::json(nullptr)},
        {"validate", validate_runs}};
    // The stored document is the one printed, without its own id and the report's files (a
    // report is made again at any time: the same diagnosis with one is the one stored); a fit of
    // several runs is stored with the first.
    auto stored = a.document();
    stored.erase("report");
    a.result_id = session.storeResult(a.run_id, "diagnosis", kVersion, parameters.dump(), stored.dump()).value_or(0);
  }
  return a;
}

}  // namespace mtcal::services
