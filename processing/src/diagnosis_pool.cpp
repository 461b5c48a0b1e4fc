// Several runs of one kind diagnosed in one fit: a cause common to them (a drift, a backlash,
// a thermal sensitivity) is estimated once from all their readings.
#include <fmt/format.h>

#include <algorithm>
#include <set>

#include "mtcal/error.h"
#include "mtcal/processing/diagnosis.h"

namespace mtcal::processing {
namespace {

/// What makes two runs' candidates the same cause: its effect, variable and plain words.
std::string keyOf(const Candidate& c) { return c.effect + "|" + c.variable + "|" + c.cause; }

bool usesOnly(const Candidate& c, const std::set<std::string>& variables) {
  auto within = [&](const std::vector<ExtensionShape>& shapes) {
    return std::all_of(shapes.begin(), shapes.end(), [&](const ExtensionShape& s) {
      return std::all_of(s.variables.begin(), s.variables.end(),
                         [&](const std::string& v) { return variables.contains(v); });
    });
  };
  return within(c.shapes) && within(c.confounders);
}

}  // namespace

DiagnosisData poolDiagnosisData(const std::vector<DiagnosisData>& runs) {
  if (runs.size() < 2) throw InputError("pooling: fewer than two runs");
  const DiagnosisData& first = runs.front();
  Eigen::Index n = 0, baseline_columns = 0;
  std::set<std::string> common_variables;
  for (const auto& v : first.variables) common_variables.insert(v.name);
  std::set<std::string> common_candidates;
  for (const auto& c : first.candidates) common_candidates.insert(keyOf(c));
  bool sites = true;
  std::vector<std::string> sources;
  for (const auto& r : runs) {
    if (r.kind != first.kind) {
      throw InputError(fmt::format("{} is {} data and {} is {} data: one fit takes runs of one kind", first.source,
                                   first.kind, r.source, r.kind));
    }
    n += r.measured.size();
    baseline_columns += r.baseline.cols();
    std::set<std::string> names, keys;
    for (const auto& v : r.variables) names.insert(v.name);
    for (const auto& c : r.candidates) keys.insert(keyOf(c));
    std::erase_if(common_variables, [&](const std::string& v) { return !names.contains(v); });
    std::erase_if(common_candidates, [&](const std::string& k) { return !keys.contains(k); });
    sites = sites && r.site.size() == r.measured.size();
    sources.push_back(r.source);
  }
  DiagnosisData out;
  out.kind = first.kind;
  out.source = fmt::format("{} in one fit", fmt::join(sources, ", "));
  out.value_name = first.value_name;
  out.value_unit = first.value_unit;
  out.main_variable = first.main_variable;
  out.model_description = first.model_description;
  out.baseline_description = fmt::format("{}, one for each run", first.baseline_description);
  out.fold_description = fmt::format("{}, the same part of every run held out together", first.fold_description);
  out.measured.resize(n);
  out.simulated.resize(n);
  out.fold.resize(n);
  out.baseline = Eigen::MatrixXd::Zero(n, baseline_columns);
  if (sites) out.site.resize(n);
  // The readings' correlation is taken within each run; a run's first reading is not
  // independent of the last of the run before in the whitening (one pair per run: negligible).
  out.lag1_correlation = first.lag1_correlation;
  for (const auto& v : first.variables) {
    if (common_variables.contains(v.name)) out.variables.push_back({v.name, v.unit, Eigen::VectorXd(n)});
  }
  Eigen::Index row = 0, column = 0;
  int site_offset = 0;
  for (const auto& r : runs) {
    const Eigen::Index m = r.measured.size();
    out.measured.segment(row, m) = r.measured;
    out.simulated.segment(row, m) = r.simulated;
    out.fold.segment(row, m) = r.fold;
    out.baseline.block(row, column, m, r.baseline.cols()) = r.baseline;
    if (sites && m) {
      out.site.segment(row, m) = r.site.array() + site_offset;
      site_offset += r.site.maxCoeff() + 1;
    }
    for (auto& v : out.variables) v.values.segment(row, m) = r.variable(v.name)->values;
    out.absorbed_dof += r.absorbed_dof;
    for (const auto& w : r.warnings) out.warnings.push_back(fmt::format("{}: {}", r.source, w));
    for (const auto& note : r.notes) out.notes.push_back(fmt::format("{}: {}", r.source, note));
    if (r.model_description != first.model_description)
      out.notes.push_back(fmt::format("{} is predicted by {}", r.source, r.model_description));
    row += m;
    column += r.baseline.cols();
  }
  for (const auto& c : first.candidates) {
    if (common_candidates.contains(keyOf(c)) && usesOnly(c, common_variables)) out.candidates.push_back(c);
  }
  const auto left_out = first.candidates.size() - out.candidates.size();
  if (left_out > 0) {
    out.notes.push_back(
        fmt::format("{} candidate cause(s) of {} not tried: not every run has what they need", left_out, first.source));
  }
  out.notes.push_back(fmt::format(
      "{} runs in one fit: each keeps its own baseline, a named cause has one size for all of them", runs.size()));
  return out;
}

}  // namespace mtcal::processing
