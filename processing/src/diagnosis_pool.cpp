// Several runs diagnosed in one fit: a cause common to them (a drift, a backlash, a thermal
// sensitivity; across kinds, a drive's lost motion read by a positioning run and a circle) is
// estimated once from all their readings.
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <map>
#include <set>
#include <string_view>

#include "diagnosis_internal.h"
#include "mtcal/error.h"
#include "mtcal/processing/diagnosis.h"
#include "mtcal/processing/number_text.h"

namespace mtcal::processing {

using detail::baseName;
using detail::scopedName;
using detail::scopeOf;

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

/// What a fit's runs all say alike is said of.
constexpr std::string_view kEveryRun = "every run";

/// The source of a part that is runs of one error fitted as one ("run 1, run 2") and back.
constexpr std::string_view kPartRunsSeparator = ", ";
std::string partOf(const std::vector<std::string>& runs) {
  return fmt::format("{}", fmt::join(runs, kPartRunsSeparator));
}
std::vector<std::string> runsOfPart(const std::string& part) {
  std::vector<std::string> runs;
  for (std::size_t from = 0;;) {
    const auto at = part.find(kPartRunsSeparator, from);
    runs.push_back(part.substr(from, at == std::string::npos ? std::string::npos : at - from));
    if (at == std::string::npos) return runs;
    from = at + kPartRunsSeparator.size();
  }
}

/// Each value the runs give (a warning, a unit), in the order it first comes, with the sources of
/// the runs that give it.
std::vector<std::pair<std::string, std::vector<std::string>>> sourcesOf(
    const std::vector<DiagnosisData>& runs,
    const std::function<std::vector<std::string>(const DiagnosisData&)>& values) {
  std::vector<std::pair<std::string, std::vector<std::string>>> out;
  for (const auto& r : runs) {
    for (const auto& value : values(r)) {
      auto it = std::find_if(out.begin(), out.end(), [&](const auto& v) { return v.first == value; });
      if (it == out.end()) it = out.insert(out.end(), {value, {}});
      it->second.push_back(r.source);
    }
  }
  return out;
}

/// The runs' rows one after the other: measured, predicted, folds, each run's baseline in
/// columns of its own, their warnings and notes; variables and candidates are left to the caller.
DiagnosisData stacked(const std::vector<DiagnosisData>& runs, const std::string& kind) {
  const DiagnosisData& first = runs.front();
  Eigen::Index n = 0, baseline_columns = 0;
  std::vector<std::string> sources;
  for (const auto& r : runs) {
    n += r.measured.size();
    baseline_columns += r.baseline.cols();
    sources.push_back(r.source);
  }
  DiagnosisData out;
  out.kind = kind;
  out.source = fmt::format("{} in one fit", fmt::join(sources, ", "));
  out.value_name = first.value_name;
  out.value_unit = first.value_unit;
  // The runs' baselines and held-out parts: in one phrase where every run has the same, else
  // run by run.
  const auto described = [&](std::string DiagnosisData::*description, const char* if_same, const char* if_not) {
    const bool same = std::all_of(runs.begin(), runs.end(),
                                  [&](const DiagnosisData& r) { return r.*description == first.*description; });
    if (same) return fmt::format("{}{}", first.*description, if_same);
    std::vector<std::string> each;
    for (const auto& r : runs) each.push_back(fmt::format("{}: {}", r.source, r.*description));
    return fmt::format("{}{}", fmt::join(each, "; "), if_not);
  };
  out.model_description = described(&DiagnosisData::model_description, "", "");
  out.baseline_description = described(&DiagnosisData::baseline_description, ", one for each run", "");
  out.fold_description = described(&DiagnosisData::fold_description, ", the same part of every run held out together",
                                   " (the same part of every run held out together)");
  out.measured.resize(n);
  out.simulated.resize(n);
  out.fold.resize(n);
  out.baseline = Eigen::MatrixXd::Zero(n, baseline_columns);
  // The readings' correlation is taken within each run; a run's first reading is not
  // independent of the last of the run before in the whitening (one pair per run: negligible).
  // (EST runs: 1/4, or each run's from its probes' scatter; their mean.)
  out.lag1_correlation = 0.0;
  for (const auto& r : runs) out.lag1_correlation += r.lag1_correlation / static_cast<double>(runs.size());
  if (std::any_of(runs.begin(), runs.end(), [](const DiagnosisData& r) { return !r.reversal_at.empty(); })) {
    for (const auto& r : runs) {
      if (r.reversal_at.empty())
        out.reversal_at.insert(out.reversal_at.end(), r.measured.size(), -1);
      else
        out.reversal_at.insert(out.reversal_at.end(), r.reversal_at.begin(), r.reversal_at.end());
    }
  }
  Eigen::Index row = 0, column = 0;
  for (const auto& r : runs) {
    const Eigen::Index m = r.measured.size();
    out.measured.segment(row, m) = r.measured;
    out.simulated.segment(row, m) = r.simulated;
    out.fold.segment(row, m) = r.fold;
    out.baseline.block(row, column, m, r.baseline.cols()) = r.baseline;
    out.absorbed_dof += r.absorbed_dof;
    if (r.pooled_runs.empty()) {
      out.pooled_runs.push_back({r.source, m});
    } else {  // runs of one error in a fit of their own, beside others: each its rows
      out.pooled_runs.insert(out.pooled_runs.end(), r.pooled_runs.begin(), r.pooled_runs.end());
    }
    row += m;
    column += r.baseline.cols();
  }
  // A warning or note several runs give alike is said once, naming them ("run 1, run 2: ..."); a
  // fit of runs of one error beside others has named its runs' already ("run 1, run 4: ...":
  // those runs and the words, said once with the other parts' alike), its own are its runs'.
  for (const auto texts : {&DiagnosisData::warnings, &DiagnosisData::notes}) {
    std::vector<std::pair<std::string, std::vector<std::string>>> said;  // the words, the runs giving them
    const auto add = [&](const std::string& words, const std::vector<std::string>& sources) {
      auto it = std::find_if(said.begin(), said.end(), [&](const auto& s) { return s.first == words; });
      if (it == said.end()) it = said.insert(said.end(), {words, {}});
      for (const auto& source : sources) {  // each run once, however often it says the words
        if (std::find(it->second.begin(), it->second.end(), source) == it->second.end()) it->second.push_back(source);
      }
    };
    for (const auto& r : runs) {
      for (const auto& text : r.*texts) {
        if (r.pooled_runs.empty()) {
          add(text, {r.source});
          continue;
        }
        const auto colon = text.find(": ");
        const auto named = colon == std::string::npos           ? std::vector<std::string>{}
                           : text.substr(0, colon) == kEveryRun ? runsOfPart(r.source)
                                                                : runsOfPart(text.substr(0, colon));
        const bool names_its_runs = !named.empty() && std::all_of(named.begin(), named.end(), [&](const auto& source) {
          return std::any_of(r.pooled_runs.begin(), r.pooled_runs.end(),
                             [&](const auto& run) { return run.source == source; });
        });
        if (names_its_runs)
          add(text.substr(colon + 2), named);
        else
          add(text, runsOfPart(r.source));
      }
    }
    for (const auto& [words, sources] : said) {
      // One run's words that begin with its name ("run 5 is interrupted ...") are said as they are.
      const bool names_itself = sources.size() == 1 && words.starts_with(sources.front() + " ");
      const bool every_run = sources.size() > 1 && sources.size() == out.pooled_runs.size();
      (out.*texts)
          .push_back(names_itself ? words
                                  : fmt::format("{}: {}", every_run ? std::string(kEveryRun) : partOf(sources), words));
    }
  }
  return out;
}

/// A shape on a run's own variables ("run 3: direction"), its multiplier too.
ExtensionShape scoped(ExtensionShape s, const std::string& source) {
  for (auto& v : s.variables) v = scopedName(source, v);
  auto kind = detail::shapeKind(s.kind);
  if (!kind.multiplier.empty()) kind.multiplier = scopedName(source, kind.multiplier);
  s.kind = detail::shapeKindText(kind);
  return s;
}

Candidate scoped(Candidate c, const std::string& source) {
  for (auto& s : c.shapes) s = scoped(std::move(s), source);
  for (auto& s : c.confounders) s = scoped(std::move(s), source);
  c.variable = scopedName(source, c.variable);
  return c;
}

/// Runs of one kind: the variables and causes every run has, shared. `part`: the fit is a part of
/// one beside runs of other errors, whose note says how its parts are fitted.
DiagnosisData poolOneKind(const std::vector<DiagnosisData>& runs, bool part = false) {
  const DiagnosisData& first = runs.front();
  std::set<std::string> common_variables;
  for (const auto& v : first.variables) common_variables.insert(v.name);
  std::set<std::string> common_candidates;
  for (const auto& c : first.candidates) common_candidates.insert(keyOf(c));
  bool sites = true;
  for (const auto& r : runs) {
    std::set<std::string> names, keys;
    for (const auto& v : r.variables) names.insert(v.name);
    for (const auto& c : r.candidates) keys.insert(keyOf(c));
    std::erase_if(common_variables, [&](const std::string& v) { return !names.contains(v); });
    std::erase_if(common_candidates, [&](const std::string& k) { return !keys.contains(k); });
    sites = sites && r.site.size() == r.measured.size();
  }
  DiagnosisData out = stacked(runs, first.kind);
  out.main_variable = first.main_variable;
  const Eigen::Index n = out.measured.size();
  if (sites) out.site.resize(n);
  // Against one model that states its own error, the runs share it (the same nodes' errors): its
  // rows at every run's sites, in the pooled sites' order.
  const bool stated = sites && std::all_of(runs.begin(), runs.end(), [&](const DiagnosisData& r) {
                        return r.site.size() && r.model_error_factor.size() &&
                               r.model_error_factor.cols() == first.model_error_factor.cols() &&
                               r.model_description == first.model_description &&
                               r.model_error_factor.rows() == r.site.maxCoeff() + 1;
                      });
  for (const auto& v : first.variables) {
    if (common_variables.contains(v.name)) out.variables.push_back({v.name, v.unit, Eigen::VectorXd(n)});
  }
  Eigen::Index row = 0;
  int site_offset = 0;
  for (const auto& r : runs) {
    const Eigen::Index m = r.measured.size();
    if (sites && m) {
      out.site.segment(row, m) = r.site.array() + site_offset;
      if (stated) {
        out.model_error_factor.conservativeResize(site_offset + r.model_error_factor.rows(),
                                                  first.model_error_factor.cols());
        out.model_error_factor.bottomRows(r.model_error_factor.rows()) = r.model_error_factor;
      }
      site_offset += r.site.maxCoeff() + 1;
    }
    for (auto& v : out.variables) v.values.segment(row, m) = r.variable(v.name)->values;
    row += m;
  }
  std::map<std::string, int> seen;  // candidates of one key (a yaw's splines of 2, 4, 8 spans) by their order
  for (const auto& c : first.candidates) {
    const int occurrence = seen[keyOf(c)]++;
    if (common_candidates.contains(keyOf(c)) && usesOnly(c, common_variables)) {
      // A shape held within a range (a channel's curve, a spline along the run) spans every
      // run's: the first run's alone would clamp or drop the others' readings beyond it.
      Candidate widened = c;
      for (const auto& r : runs) {
        int k = 0;
        for (const auto& other : r.candidates) {
          if (keyOf(other) != keyOf(c) || k++ != occurrence || other.shapes.size() != c.shapes.size()) continue;
          for (std::size_t j = 0; j < c.shapes.size(); ++j) {
            auto& range = widened.shapes[j].range;
            const auto& its = other.shapes[j].range;
            if (range.second > range.first && its.second > its.first)
              range = {std::min(range.first, its.first), std::max(range.second, its.second)};
          }
        }
      }
      out.candidates.push_back(std::move(widened));
    }
  }
  // A cause another run lacks what it needs for (a variable, or targets off a grid: a lead error
  // on a random-offset plan beside a grid's) is tried on its own run's readings: its shapes on
  // that run's variables, zero on the others' rows.
  std::vector<std::string> own_run_only;
  row = 0;
  for (const auto& r : runs) {
    std::set<std::string> needed;
    for (const auto& c : r.candidates) {
      if (common_candidates.contains(keyOf(c)) && usesOnly(c, common_variables)) continue;
      for (const auto* shapes : {&c.shapes, &c.confounders}) {
        for (const auto& shape : *shapes) {
          needed.insert(shape.variables.begin(), shape.variables.end());
          if (const auto multiplier = detail::shapeKind(shape.kind).multiplier; !multiplier.empty())
            needed.insert(multiplier);
        }
      }
      out.candidates.push_back(scoped(c, r.source));
      own_run_only.push_back(fmt::format("{} ({}) of {}", c.effect, c.variable, r.source));
    }
    for (const auto& name : needed) {
      const auto* v = r.variable(name);
      if (!v) continue;
      DiagnosisVariable own{scopedName(r.source, name), v->unit,
                            Eigen::VectorXd::Constant(n, std::numeric_limits<double>::quiet_NaN())};
      own.values.segment(row, r.measured.size()) = v->values;
      own.own_causes_only = true;
      out.variables.push_back(std::move(own));
    }
    row += r.measured.size();
  }
  if (!own_run_only.empty()) {
    out.notes.push_back(
        fmt::format("tried on its own run's readings only, as another run lacks what it needs (a variable, or "
                    "targets off a grid): {}",
                    fmt::join(own_run_only, ", ")));
  }
  // The noise the runs state (an EST run's probes' scatter), pooled as their readings are, one
  // noise for all: their variances over their degrees of freedom. The runs' readings are weighed
  // alike, so a run stating much more than the others is not told apart (the check is of the
  // residuals scattering more than the statement, not less).
  std::vector<std::string> unstated;
  double stated_sum_of_squares = 0.0, stated_dof = 0.0;
  for (const auto& r : runs) {
    if (!(r.stated_noise_dof > 0.0)) unstated.push_back(r.source);
    stated_sum_of_squares += r.stated_noise_dof * r.stated_noise_variance;
    stated_dof += r.stated_noise_dof;
  }
  if (unstated.empty()) {
    out.stated_noise_variance = stated_sum_of_squares / stated_dof;
    out.stated_noise_dof = stated_dof;
    out.stated_noise_description = fmt::format("{} of every run", first.stated_noise_description);
  } else if (unstated.size() < runs.size()) {
    out.notes.push_back(fmt::format("{} state{} no noise: the others' statement is not carried into the fit",
                                    fmt::join(unstated, ", "), unstated.size() == 1 ? "s" : ""));
  }
  if (!part)
    out.notes.push_back(fmt::format(
        "{} runs in one fit: each keeps its own baseline, a named cause has one size for all of them", runs.size()));
  return out;
}

/// Whether every parameter of the candidate is a quantity and each shape gives one column (that
/// parameter's): it can join the same cause of other runs.
bool sharable(const Candidate& c) {
  return c.search.empty() && !c.parameters.empty() && c.parameters.size() == c.shapes.size() &&
         std::all_of(c.parameters.begin(), c.parameters.end(), [](const auto& p) { return !p.quantity.empty(); }) &&
         std::none_of(c.shapes.begin(), c.shapes.end(), [](const ExtensionShape& s) {
           return s.kind.rfind("harmonic", 0) == 0 || s.kind == "spline" || s.kind == "step_difference";
         });
}

/// A run's kind and the error it reads, where its kind reads several ("linear EYY").
std::string kindRead(const DiagnosisData& r) { return r.measures.empty() ? r.kind : r.kind + " " + r.measures; }

/// Runs of different kinds, or of one kind reading different errors: each run's own variables
/// and causes, and one cause for the quantities several runs read.
DiagnosisData poolKinds(const std::vector<DiagnosisData>& runs) {
  std::vector<std::string> kinds;
  for (const auto& r : runs) {
    if (r.lag1_correlation != 0.0) {
      throw InputError(
          fmt::format("{} is {} data, whose readings are correlated: it is fitted with runs of its own "
                      "kind only",
                      r.source, r.kind));
    }
    if (r.value_unit != runs.front().value_unit) {
      // The runs of each unit named, to be diagnosed apart (a campaign's angles beside its
      // positioning and straightness runs).
      std::vector<std::string> groups;
      for (const auto& [unit, sources] :
           sourcesOf(runs, [](const DiagnosisData& each) { return std::vector<std::string>{each.value_unit}; }))
        groups.push_back(fmt::format("in {}: {}", unit, fmt::join(sources, ", ")));
      throw InputError(
          fmt::format("{} reads {} and {} {}: one fit takes readings of one unit; diagnose the runs of "
                      "each unit apart ({})",
                      runs.front().source, runs.front().value_unit, r.source, r.value_unit, fmt::join(groups, "; ")));
    }
    if (std::find(kinds.begin(), kinds.end(), r.kind) == kinds.end()) kinds.push_back(r.kind);
  }
  DiagnosisData out = stacked(runs, fmt::format("{}", fmt::join(kinds, "+")));
  out.main_variable = scopedName(runs.front().source, runs.front().main_variable);
  std::vector<std::string> kinds_read, errors_read;  // each kind with its error; the errors alone
  for (const auto& read : sourcesOf(runs, [](const DiagnosisData& r) { return std::vector<std::string>{kindRead(r)}; }))
    kinds_read.push_back(read.first);
  for (const auto& error : sourcesOf(runs, [](const DiagnosisData& r) { return std::vector<std::string>{r.measures}; }))
    errors_read.push_back(error.first);
  const Eigen::Index n = out.measured.size();
  // Each run's points weighed by the inverse of its scatter: the RMS of its residual about what
  // its own diagnosis explains (a linear run's 0.6 um, a circle's 0.3 um, a thermal run's
  // micrometres), so that the fit's variance is one and each run counts by its precision.
  out.weight.resize(n);
  std::vector<std::string> scatter;
  for (Eigen::Index row = 0; const auto& r : runs) {
    const double rms = detail::rmsOf(diagnose(r).residual_after);
    const double floor = 1e-9 * std::max(1.0, r.measured.cwiseAbs().maxCoeff());
    out.weight.segment(row, r.measured.size()).setConstant(1.0 / std::max(rms, floor));
    scatter.push_back(fmt::format("{} {:.3g} {}", r.source, rms, r.value_unit));
    row += r.measured.size();
  }
  const bool any_sites = std::any_of(runs.begin(), runs.end(), [](const DiagnosisData& r) {
    return r.site.size() == r.measured.size() && r.site.size() > 0;
  });
  if (any_sites) out.site = Eigen::VectorXi::Constant(n, -1);
  // Which runs read each quantity.
  std::map<std::string, std::set<std::string>> readers;
  for (const auto& r : runs) {
    for (const auto& c : r.candidates) {
      if (!sharable(c)) continue;
      for (const auto& p : c.parameters) readers[p.quantity].insert(r.source);
    }
  }
  const auto shared = [&](const Candidate& c) {
    return sharable(c) && std::any_of(c.parameters.begin(), c.parameters.end(),
                                      [&](const auto& p) { return readers[p.quantity].size() >= 2; });
  };
  // The shared causes by effect: their quantities in order, and each run's own shapes added into
  // the quantity's column (scaled from the run's parameter to the quantity).
  struct Shared {
    Candidate candidate;
    std::vector<std::string> quantities, readers;
  };
  std::vector<Shared> shared_causes;
  Eigen::Index row = 0;
  int site_offset = 0;
  for (const auto& r : runs) {
    const Eigen::Index m = r.measured.size();
    if (any_sites && r.site.size() == m && m) {
      out.site.segment(row, m) = r.site.array() + site_offset;
      site_offset += r.site.maxCoeff() + 1;
    }
    for (const auto& name : {r.main_variable, std::string("time_s")}) {
      const auto plotted = scopedName(r.source, name);
      if (r.variable(name) &&
          std::find(out.plot_variables.begin(), out.plot_variables.end(), plotted) == out.plot_variables.end())
        out.plot_variables.push_back(plotted);
    }
    for (const auto& v : r.variables) {
      DiagnosisVariable own{scopedName(r.source, v.name), v.unit,
                            Eigen::VectorXd::Constant(n, std::numeric_limits<double>::quiet_NaN())};
      own.values.segment(row, m) = v.values;
      own.own_causes_only = v.own_causes_only;  // a part's run's copy stays one
      out.variables.push_back(std::move(own));
    }
    for (const auto& c : r.candidates) {
      if (!shared(c)) {
        out.candidates.push_back(scoped(c, r.source));
        continue;
      }
      auto it = std::find_if(shared_causes.begin(), shared_causes.end(),
                             [&](const Shared& s) { return s.candidate.effect == c.effect; });
      if (it == shared_causes.end()) {
        Shared s;
        s.candidate.effect = c.effect;
        s.candidate.cause = c.cause;
        it = shared_causes.insert(shared_causes.end(), std::move(s));
      }
      Shared& s = *it;
      std::vector<std::string> names;
      for (const auto& p : c.parameters) names.push_back(p.name);
      s.readers.push_back(fmt::format("{} ({})", r.source, fmt::join(names, ", ")));
      for (std::size_t k = 0; k < c.shapes.size(); ++k) {
        const auto& p = c.parameters[k];
        ExtensionShape shape = scoped(c.shapes[k], r.source);
        // The shape's column times the coefficient is the run's parameter over per_coefficient:
        // per quantity, per_quantity / per_coefficient.
        shape.scale *= p.per_quantity / p.per_coefficient;
        const auto q = std::find(s.quantities.begin(), s.quantities.end(), p.quantity);
        if (q == s.quantities.end()) {
          s.quantities.push_back(p.quantity);
          s.candidate.parameters.push_back({p.quantity, p.unit, 1.0, 0.0, p.quantity, 1.0});
        } else {
          shape.into = static_cast<int>(q - s.quantities.begin());
        }
        s.candidate.shapes.push_back(std::move(shape));
      }
      for (const auto& conf : c.confounders) s.candidate.confounders.push_back(scoped(conf, r.source));
    }
    row += m;
  }
  std::vector<std::string> common;
  for (auto& s : shared_causes) {
    // Every shape adding into an earlier column comes after the shapes that make the columns.
    std::stable_partition(s.candidate.shapes.begin(), s.candidate.shapes.end(),
                          [](const ExtensionShape& shape) { return shape.into < 0; });
    s.candidate.variable = fmt::format("{}", fmt::join(s.quantities, ", "));
    s.candidate.cause += fmt::format("; one size for every run that reads it: {}", fmt::join(s.readers, ", "));
    common.push_back(fmt::format("{} ({})", s.candidate.effect, s.candidate.variable));
    out.candidates.push_back(std::move(s.candidate));
  }
  if (common.empty()) common.push_back("none");
  out.notes.push_back(fmt::format(
      "{} runs of {} in one fit: each keeps its own baseline and causes{}, a quantity several of them read has one "
      "size for all (here: {}); each run's points weighed by its scatter about what its own diagnosis explains ({})",
      out.pooled_runs.size(),
      kinds_read.size() == kinds.size() ? fmt::format("{} kinds", kinds.size())
      : kinds.size() == 1               ? fmt::format("{} errors ({})", kinds_read.size(), fmt::join(errors_read, ", "))
                          : fmt::format("{} kinds and errors ({})", kinds_read.size(), fmt::join(kinds_read, ", ")),
      out.pooled_runs.size() > runs.size() ? " (runs of one error: their causes shared, one fit of their own)" : "",
      fmt::join(common, ", "), fmt::join(scatter, ", ")));
  return out;
}

/// Whether run a's source comes before b's, numbers by their value ("run 2" before "run 10").
bool sourceOrder(const DiagnosisData& a, const DiagnosisData& b) {
  const std::string &x = a.source, &y = b.source;
  std::size_t i = 0, j = 0;
  const auto digit = [](char c) { return c >= '0' && c <= '9'; };
  while (i < x.size() && j < y.size()) {
    if (digit(x[i]) && digit(y[j])) {
      std::size_t i_end = i, j_end = j;
      while (i_end < x.size() && digit(x[i_end])) ++i_end;
      while (j_end < y.size() && digit(y[j_end])) ++j_end;
      while (i < i_end - 1 && x[i] == '0') ++i;  // leading zeros
      while (j < j_end - 1 && y[j] == '0') ++j;
      if (i_end - i != j_end - j) return i_end - i < j_end - j;
      const int c = x.compare(i, i_end - i, y, j, j_end - j);
      if (c != 0) return c < 0;
      i = i_end;
      j = j_end;
    } else {
      if (x[i] != y[j]) return x[i] < y[j];
      ++i;
      ++j;
    }
  }
  return x.size() - i < y.size() - j;
}

/// A copy's readings agree with its source's within this (the value's unit): real runs differ by
/// their noise; a copy rounded when written differs by far less.
constexpr double kSameReading = 1e-3;

/// How `b` (`unit`) reads what `a` reads, if it does (else empty): every reading the same, or a's
/// times a factor plus a constant (a copy re-zeroed or converted), each within kSameReading where
/// `b` was written and where `a` was (times the factor), or a block of a's readings (a copy cut
/// short). Fitted lines are tried where both runs' readings spread over 100 times that (a flat
/// run is no one's copy), and blocks of 3 readings or more.
std::string copyOf(const Eigen::VectorXd& a, const Eigen::VectorXd& b, const std::string& unit) {
  const Eigen::Index n = a.size(), m = b.size();
  if (m == 0 || m > n) return {};
  const auto within = [&](double tolerance) { return fmt::format("{:g} {}", tolerance, unit); };
  if (m == n) {
    if (((a - b).cwiseAbs().array() <= kSameReading).all())
      return fmt::format("every one of its {} readings within {}", n, within(kSameReading));
    const auto spread = [](const Eigen::VectorXd& v) { return v.maxCoeff() - v.minCoeff(); };
    if (n < 3 || spread(a) <= 100.0 * kSameReading || spread(b) <= 100.0 * kSameReading) return {};
    Eigen::MatrixXd line(n, 2);
    line << Eigen::VectorXd::Ones(n), a;
    const Eigen::Vector2d c = line.colPivHouseholderQr().solve(b);
    const double tolerance = kSameReading * (1.0 + std::abs(c(1)));
    if ((b - line * c).cwiseAbs().maxCoeff() > tolerance) return {};
    const double constant = std::abs(c(0)) <= tolerance ? 0.0 : c(0);
    return fmt::format("every one of its {} readings within {} of {} times the other's {} {} {}", n, within(tolerance),
                       significant(c(1), 6), constant < 0.0 ? "minus" : "plus", significant(std::abs(constant), 4),
                       unit);
  }
  if (m < 3) return {};
  for (Eigen::Index k = 0; k + m <= n; ++k) {
    if (((a.segment(k, m) - b).cwiseAbs().array() <= kSameReading).all())
      return fmt::format("its {} readings each within {} of the other's readings {} to {} (of {})", m,
                         within(kSameReading), k + 1, k + m, n);
  }
  return {};
}
}  // namespace

std::string copyRelation(const DiagnosisData& a, const DiagnosisData& b) {
  if (a.kind != b.kind || a.value_unit != b.value_unit) return {};  // readings of other quantities
  if (auto how = copyOf(a.measured, b.measured, b.value_unit); !how.empty())
    return fmt::format("{} reads what {} reads, {}", b.source, a.source, how);
  if (auto how = copyOf(b.measured, a.measured, a.value_unit); !how.empty())
    return fmt::format("{} reads what {} reads, {}", a.source, b.source, how);
  return {};
}

DiagnosisData poolDiagnosisData(const std::vector<DiagnosisData>& runs) {
  if (runs.size() < 2) throw InputError("pooling: fewer than two runs");
  // The same readings twice (a run and its exported copy imported again, re-zeroed, converted or
  // cut short, or two simulated runs of one seed) would count one run's evidence twice.
  for (std::size_t i = 0; i < runs.size(); ++i) {
    for (std::size_t j = i + 1; j < runs.size(); ++j) {
      if (const auto copy = copyRelation(runs[i], runs[j]); !copy.empty())
        throw InputError(
            fmt::format("{}: the same readings twice would count as twice the evidence (a copy of the "
                        "run?); diagnose one of them",
                        copy));
    }
  }
  const bool one_kind = std::all_of(runs.begin(), runs.end(),
                                    [&](const DiagnosisData& r) { return kindRead(r) == kindRead(runs.front()); });
  if (!one_kind) {
    // Runs of one kind and error are one fit of their own first (their causes shared: a lead
    // error of two runs of X estimated once), then beside the others, each with its own causes:
    // none stands for another's.
    std::vector<DiagnosisData> parts;
    for (const auto& read :
         sourcesOf(runs, [](const DiagnosisData& r) { return std::vector<std::string>{kindRead(r)}; })) {
      std::vector<DiagnosisData> group;
      for (const auto& r : runs) {
        if (kindRead(r) == read.first) group.push_back(r);
      }
      if (group.size() == 1) {
        parts.push_back(std::move(group.front()));
        continue;
      }
      std::stable_sort(group.begin(), group.end(), sourceOrder);
      std::vector<std::string> ordered;
      for (const auto& r : group) ordered.push_back(r.source);
      parts.push_back(poolOneKind(group, true));
      auto& part = parts.back();
      part.source = partOf(ordered);
      part.measures = group.front().measures;
      // Its baseline and held-out parts as its runs have them, where all alike: the fit of the
      // parts says they are each run's.
      for (const auto description : {&DiagnosisData::baseline_description, &DiagnosisData::fold_description}) {
        if (std::all_of(group.begin(), group.end(),
                        [&](const DiagnosisData& r) { return r.*description == group.front().*description; }))
          part.*description = group.front().*description;
      }
    }
    return poolKinds(parts);
  }
  // One fit of the same runs whatever order they are given in: the first run's candidates (their
  // searched values, spans) and descriptions stand for all, so the runs are taken in the order of
  // their sources ("run 2" before "run 10").
  if (std::is_sorted(runs.begin(), runs.end(), sourceOrder)) return poolOneKind(runs);
  std::vector<DiagnosisData> ordered = runs;
  std::stable_sort(ordered.begin(), ordered.end(), sourceOrder);
  return poolOneKind(ordered);
}

std::vector<RunsExtension> extensionsByRun(const ModelExtension& extension) {
  const auto scope = [](const ExtensionShape& s) {
    return s.variables.empty() ? std::string() : scopeOf(s.variables.front());
  };
  if (extension.shapes.empty() || scope(extension.shapes.front()).empty()) return {{{}, extension}};
  // A part's runs; a cause of one run only of runs of one error beside others is scoped twice
  // ("run 1, run 2: run 2: position_mm"), and is that run's.
  const auto runsOf = [](const std::string& scope) {
    const auto inner = scope.rfind(": ");
    return runsOfPart(inner == std::string::npos ? scope : scope.substr(inner + 2));
  };
  const auto unscoped = [](ExtensionShape s) {
    for (auto& v : s.variables) v = baseName(v);
    auto kind = detail::shapeKind(s.kind);
    kind.multiplier = baseName(kind.multiplier);
    s.kind = detail::shapeKindText(kind);
    s.into = -1;
    return s;
  };
  const bool adds = std::any_of(extension.shapes.begin(), extension.shapes.end(),
                                [](const ExtensionShape& s) { return s.into >= 0; });
  if (!adds) {  // one part's own cause: every shape on its variables
    ModelExtension own = extension;
    for (auto& s : own.shapes) s = unscoped(s);
    own.variable = baseName(own.variable);
    return {{runsOf(scope(extension.shapes.front())), own}};
  }
  // A shared cause: one column (and coefficient) per shape, each part's shapes apart.
  std::vector<std::pair<std::string, ModelExtension>> parts;
  int column = 0;
  for (const auto& s : extension.shapes) {
    const int k = s.into >= 0 ? s.into : column++;
    const auto source = scope(s);
    auto it = std::find_if(parts.begin(), parts.end(), [&](const auto& e) { return e.first == source; });
    if (it == parts.end()) {
      ModelExtension own = extension;
      own.shapes.clear();
      own.coefficients.clear();
      it = parts.insert(parts.end(), {source, std::move(own)});
    }
    it->second.shapes.push_back(unscoped(s));
    it->second.coefficients.push_back(extension.coefficients.at(static_cast<std::size_t>(k)));
  }
  std::vector<RunsExtension> out;
  for (auto& [source, own] : parts) out.push_back({runsOf(source), std::move(own)});
  return out;
}

}  // namespace mtcal::processing
