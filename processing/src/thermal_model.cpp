#include "mtcal/processing/thermal_model.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <numeric>
#include <set>

#include "mtcal/error.h"
#include "mtcal/processing/regression.h"

namespace mtcal::processing {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

Eigen::VectorXd normalised(const Eigen::VectorXd& x, GreyNormalisation normalisation, const std::string& what) {
  switch (normalisation) {
    case GreyNormalisation::kRange: {
      const double range = x.maxCoeff() - x.minCoeff();
      if (!(range > 0.0)) throw InputError(fmt::format("grey relational analysis: {} is constant", what));
      return (x.array() - x.minCoeff()) / range;
    }
    case GreyNormalisation::kInitialValue:
      if (x(0) == 0.0) throw InputError(fmt::format("grey relational analysis: {} starts at 0", what));
      return x / x(0);
    case GreyNormalisation::kMean: {
      const double mean = x.mean();
      if (mean == 0.0) throw InputError(fmt::format("grey relational analysis: {} has mean 0", what));
      return x / mean;
    }
  }
  return x;
}

double correlation(const Eigen::VectorXd& a, const Eigen::VectorXd& b) {
  const Eigen::VectorXd da = a.array() - a.mean(), db = b.array() - b.mean();
  const double d = std::sqrt(da.squaredNorm() * db.squaredNorm());
  return d > 0.0 ? da.dot(db) / d : 0.0;
}

/// Linear interpolation of interior gaps up to `max_gap` values; @return how many were filled
int fillShortGaps(Eigen::Ref<Eigen::VectorXd> x, int max_gap) {
  int filled = 0;
  const Eigen::Index n = x.size();
  Eigen::Index last = -1;
  for (Eigen::Index i = 0; i < n; ++i) {
    if (std::isnan(x(i))) continue;
    const Eigen::Index gap = i - last - 1;
    if (last >= 0 && gap > 0 && gap <= max_gap) {
      for (Eigen::Index j = last + 1; j < i; ++j) {
        const double w = static_cast<double>(j - last) / static_cast<double>(i - last);
        x(j) = (1.0 - w) * x(last) + w * x(i);
        ++filled;
      }
    }
    last = i;
  }
  return filled;
}

double rms(const Eigen::VectorXd& e) {
  return e.size() ? std::sqrt(e.squaredNorm() / static_cast<double>(e.size())) : kNaN;
}
double peak(const Eigen::VectorXd& e) { return e.size() ? e.cwiseAbs().maxCoeff() : kNaN; }

/// A model's input: a sensor's column, through a first-order lag of time constant lag_s (0: none).
struct Input {
  int column = 0;
  double lag_s = 0.0;
  bool operator==(const Input&) const = default;
  auto operator<=>(const Input&) const = default;
};
using Inputs = std::vector<Input>;

/// The data after gap filling, the lagged temperatures, and which rows each model may use.
class Prepared {
 public:
  Prepared(const ThermalData& data, const ThermalFitOptions& options) : data_(data), t_(data.temperature_c) {
    n_ = static_cast<int>(data.target_um.size());
    n_train_ = static_cast<int>(std::floor(options.train_fraction * n_));
    n_search_ = static_cast<int>(std::floor((1.0 - options.validation_fraction) * n_train_));
    for (Eigen::Index c = 0; c < t_.cols(); ++c)
      interpolated_.push_back(fillShortGaps(t_.col(c), options.max_gap_samples));
    if (!data.segment.empty() && static_cast<int>(data.segment.size()) != n_)
      throw InputError("thermal model: the segments do not match the rows");
  }
  int segment(int i) const { return data_.segment.empty() ? 0 : data_.segment[static_cast<std::size_t>(i)]; }
  /// The segments of `rows` after the first one's: each gets a level of its own.
  std::vector<int> laterSegments(const std::vector<int>& rows) const {
    std::vector<int> out;
    for (int r : rows) {
      if (segment(r) != segment(rows.front()) && std::find(out.begin(), out.end(), segment(r)) == out.end())
        out.push_back(segment(r));
    }
    return out;
  }
  /// Which of `rows` begin a series: the first, and each first row of a segment.
  std::vector<bool> starts(const std::vector<int>& rows) const {
    std::vector<bool> out(rows.size());
    for (std::size_t r = 0; r < rows.size(); ++r) out[r] = r == 0 || segment(rows[r]) != segment(rows[r - 1]);
    return out;
  }
  int n() const { return n_; }
  int nTrain() const { return n_train_; }
  /// The training rows the searches use; the rest of the training rows validate.
  int nSearch() const { return n_search_; }
  const Eigen::MatrixXd& temperatures() const { return t_; }
  int interpolated(int c) const { return interpolated_[static_cast<std::size_t>(c)]; }
  double target(int i) const { return data_.target_um(i); }

  /// An input's value at every row: the temperature, or its first-order lag
  /// u_i = u_{i-1} + (1 - e^(-dt/lag)) (T_i - u_{i-1}), started at the temperature at each
  /// segment's first reading (the machine there taken as settled), held over a missing one
  /// (NaN there). Causal: a row's value uses no later temperature.
  const Eigen::VectorXd& series(const Input& input) const {
    auto found = lagged_.find(input);
    if (found != lagged_.end()) return found->second;
    Eigen::VectorXd u = t_.col(input.column);
    if (input.lag_s > 0.0) {
      double state = kNaN;
      for (int i = 0; i < n_; ++i) {
        const double t = t_(i, input.column);
        if (i > 0 && segment(i) != segment(i - 1)) state = kNaN;
        if (std::isnan(t)) continue;  // u(i) stays NaN, the state is held
        if (std::isnan(state)) {
          state = t;
        } else {
          const double dt = data_.time_s(i) - data_.time_s(i - 1);
          state += (1.0 - std::exp(-dt / input.lag_s)) * (t - state);
        }
        u(i) = state;
      }
    }
    return lagged_.emplace(input, std::move(u)).first->second;
  }
  bool rowComplete(int i, const Inputs& inputs) const {
    if (std::isnan(data_.target_um(i))) return false;
    return std::none_of(inputs.begin(), inputs.end(), [&](const Input& u) { return std::isnan(series(u)(i)); });
  }
  /// Rows in [from, to) with the target and every input present.
  std::vector<int> rows(const Inputs& inputs, int from, int to) const {
    std::vector<int> out;
    for (int i = from; i < to; ++i) {
      if (rowComplete(i, inputs)) out.push_back(i);
    }
    return out;
  }
  /// The inputs at `rows`, then an indicator column for each of `levels`.
  Eigen::MatrixXd x(const std::vector<int>& rows, const Inputs& inputs, const std::vector<int>& levels = {}) const {
    Eigen::MatrixXd out = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(rows.size()),
                                                static_cast<Eigen::Index>(inputs.size() + levels.size()));
    for (std::size_t c = 0; c < inputs.size(); ++c) {
      const Eigen::VectorXd& u = series(inputs[c]);
      for (std::size_t r = 0; r < rows.size(); ++r)
        out(static_cast<Eigen::Index>(r), static_cast<Eigen::Index>(c)) = u(rows[r]);
    }
    for (std::size_t r = 0; r < rows.size(); ++r) {
      for (std::size_t l = 0; l < levels.size(); ++l) {
        if (segment(rows[r]) == levels[l])
          out(static_cast<Eigen::Index>(r), static_cast<Eigen::Index>(inputs.size() + l)) = 1.0;
      }
    }
    return out;
  }
  Eigen::VectorXd y(const std::vector<int>& rows) const {
    Eigen::VectorXd out(static_cast<Eigen::Index>(rows.size()));
    for (std::size_t r = 0; r < rows.size(); ++r) out(static_cast<Eigen::Index>(r)) = data_.target_um(rows[r]);
    return out;
  }

 private:
  const ThermalData& data_;
  Eigen::MatrixXd t_;
  int n_ = 0, n_train_ = 0, n_search_ = 0;
  std::vector<int> interpolated_;
  mutable std::map<Input, Eigen::VectorXd> lagged_;
};

/// A model reading `inputs` (its columns and lags; nothing fitted yet).
ThermalCandidate withInputs(const Inputs& inputs) {
  ThermalCandidate model;
  for (const auto& u : inputs) {
    model.columns.push_back(u.column);
    model.lag_s.push_back(u.lag_s);
  }
  return model;
}

Inputs inputsOf(const ThermalCandidate& model) {
  Inputs out;
  for (std::size_t i = 0; i < model.columns.size(); ++i) out.push_back({model.columns[i], model.lag_s[i]});
  return out;
}

/// A family's fit of the rows: coefficients (b0, b, then the levels), phi, residuals and innovations.
struct FamilyFit {
  Eigen::VectorXd coefficients;
  double phi = 0.0;
  Eigen::VectorXd residuals, innovations;
  LinearFit least_squares;
  std::string ar1_refused;  ///< why the AR(1) term was left out (the ar1 family only)
};
FamilyFit fitFamily(const Prepared& p, const std::vector<int>& rows, const Inputs& inputs,
                    const std::vector<int>& levels, ThermalFamily family) {
  FamilyFit out;
  const Eigen::MatrixXd x = p.x(rows, inputs, levels);
  const Eigen::VectorXd y = p.y(rows);
  out.least_squares = fitLinear(x, y);
  out.coefficients = out.least_squares.coefficients;
  out.residuals = out.innovations = out.least_squares.residuals;
  if (family != ThermalFamily::kAr1) return out;
  try {
    Ar1Fit a = fitLinearAr1(x, y, p.starts(rows));
    out.coefficients = a.fit.coefficients;
    out.phi = a.phi;
    out.residuals = a.fit.residuals;
    out.innovations = a.innovations;
  } catch (const InputError& e) {
    out.ar1_refused = e.what();
  }
  return out;
}

/// Sets a model's coefficients, phi and segment levels from a fit of p.x(rows, inputs, levels).
void takeFit(const Prepared& p, const std::vector<int>& rows, const std::vector<int>& levels, const FamilyFit& fit,
             ThermalCandidate& model) {
  const auto k = static_cast<Eigen::Index>(model.columns.size()) + 1;
  model.coefficients = fit.coefficients.head(k);
  model.phi = fit.phi;
  model.segment_level_um = {{p.segment(rows.front()), 0.0}};
  for (std::size_t l = 0; l < levels.size(); ++l)
    model.segment_level_um[levels[l]] = fit.coefficients(k + static_cast<Eigen::Index>(l));
}

/// A model's predictions of every row: open loop, and one step ahead (plus phi times the
/// previous row's measured residual, where that row is complete and of the same segment).
/// NaN where a value is missing, and at the first complete row of a segment the model has no
/// level for: that row sets the level (`level_rows`), it does not test the model.
struct Predictions {
  Eigen::VectorXd open_loop, one_step;
  std::vector<int> level_rows;
};
Predictions predict(const Prepared& p, const ThermalCandidate& model) {
  const Inputs inputs = inputsOf(model);
  Predictions out;
  out.open_loop = Eigen::VectorXd::Constant(p.n(), model.coefficients(0));
  for (std::size_t c = 0; c < inputs.size(); ++c)
    out.open_loop += model.coefficients(static_cast<Eigen::Index>(c) + 1) * p.series(inputs[c]);
  std::map<int, double> level = model.segment_level_um;
  for (int i = 0; i < p.n(); ++i) {
    if (std::isnan(out.open_loop(i))) continue;
    const int s = p.segment(i);
    if (!level.contains(s)) {
      if (!p.rowComplete(i, inputs)) continue;
      level[s] = p.target(i) - out.open_loop(i);
      out.level_rows.push_back(i);
      out.open_loop(i) = kNaN;
      continue;
    }
    out.open_loop(i) += level[s];
  }
  out.one_step = out.open_loop;
  for (int i = 1; i < p.n(); ++i) {
    if (p.segment(i) == p.segment(i - 1) && p.rowComplete(i - 1, inputs) && !std::isnan(out.open_loop(i - 1)) &&
        !std::isnan(out.open_loop(i))) {
      out.one_step(i) += model.phi * (p.target(i - 1) - out.open_loop(i - 1));
    }
  }
  return out;
}

/// target - prediction at the rows that the prediction tests (not the rows that set a level).
Eigen::VectorXd errors(const Prepared& p, const Eigen::VectorXd& predicted, const std::vector<int>& rows) {
  std::vector<double> e;
  for (int r : rows) {
    if (!std::isnan(predicted(r))) e.push_back(p.target(r) - predicted(r));
  }
  return Eigen::Map<const Eigen::VectorXd>(e.data(), static_cast<Eigen::Index>(e.size()));
}

struct CvRms {
  double open_loop = std::numeric_limits<double>::infinity();
  double one_step = std::numeric_limits<double>::infinity();
};

/// For each (origin, end) of `folds` (indices into `rows`): the family's fit of rows[0, origin)
/// predicts rows[origin, end), open loop and one step ahead. Infinite when a fit fails.
CvRms heldOut(const Prepared& p, const Inputs& inputs, ThermalFamily family, const std::vector<int>& rows,
              const std::vector<std::pair<int, int>>& folds) {
  double open_sum = 0.0, step_sum = 0.0;
  int count = 0;
  for (const auto& [origin, end] : folds) {
    const std::vector<int> fit_rows(rows.begin(), rows.begin() + origin);
    const auto levels = p.laterSegments(fit_rows);
    if (origin <= static_cast<int>(inputs.size() + levels.size()) + 2) return {};
    ThermalCandidate model = withInputs(inputs);
    try {
      takeFit(p, fit_rows, levels, fitFamily(p, fit_rows, inputs, levels, family), model);
    } catch (const InputError&) {
      return {};
    }
    const Predictions predicted = predict(p, model);
    const std::vector<int> held_out(rows.begin() + origin, rows.begin() + end);
    const Eigen::VectorXd e = errors(p, predicted.open_loop, held_out),
                          e_step = errors(p, predicted.one_step, held_out);
    open_sum += e.squaredNorm();
    step_sum += e_step.squaredNorm();
    count += static_cast<int>(e.size());
  }
  if (!count) return {};
  return {std::sqrt(open_sum / count), std::sqrt(step_sum / count)};
}

/// Rolling-origin cross-validation within the search rows (the training rows before the
/// validation block): origins at 50..90 % of them, each fold predicting up to the next origin.
CvRms crossValidate(const Prepared& p, const Inputs& inputs, ThermalFamily family, int folds) {
  const auto rows = p.rows(inputs, 0, p.nSearch());
  const auto n = static_cast<int>(rows.size());
  std::vector<std::pair<int, int>> ranges;
  for (int f = 0; f < folds; ++f) {
    const int origin = static_cast<int>(n * (0.5 + 0.4 * f / std::max(1, folds - 1)));
    const int end = f + 1 < folds ? static_cast<int>(n * (0.5 + 0.4 * (f + 1) / std::max(1, folds - 1))) : n;
    ranges.emplace_back(origin, end);
  }
  return heldOut(p, inputs, family, rows, ranges);
}

/// The validation block: the family's fit of the search rows predicts the rest of the training rows.
CvRms validate(const Prepared& p, const Inputs& inputs, ThermalFamily family) {
  const auto rows = p.rows(inputs, 0, p.nTrain());
  const auto origin = static_cast<int>(std::lower_bound(rows.begin(), rows.end(), p.nSearch()) - rows.begin());
  return heldOut(p, inputs, family, rows, {{origin, static_cast<int>(rows.size())}});
}

/// Fits a model of the family on the training rows, cross-validates it, and evaluates it on
/// both parts. @throws InputError
ThermalCandidate fitCandidate(const Prepared& p, const std::string& method, ThermalFamily family, const Inputs& inputs,
                              const std::vector<std::string>& names, const ThermalFitOptions& options,
                              std::vector<std::string>& notes) {
  ThermalCandidate c = withInputs(inputs);
  c.method = method;
  c.family = family;
  for (const auto& u : inputs) c.sensors.push_back(names[static_cast<std::size_t>(u.column)]);
  const std::vector<std::string> input_names = thermalInputNames(c);
  const auto train = p.rows(inputs, 0, p.nTrain());
  const auto test = p.rows(inputs, p.nTrain(), p.n());
  c.n_train = static_cast<int>(train.size());
  c.n_test = static_cast<int>(test.size());
  if (train.size() < 10 || test.empty()) {
    throw InputError(fmt::format("thermal model {}: {} training and {} test rows with every value present",
                                 fmt::join(input_names, "+"), train.size(), test.size()));
  }
  const auto levels = p.laterSegments(train);
  const FamilyFit fit = fitFamily(p, train, inputs, levels, family);
  if (!fit.ar1_refused.empty()) {
    notes.push_back(fmt::format("{} ({}): {}; fitted without the AR(1) term", method, fmt::join(input_names, "+"),
                                fit.ar1_refused));
  }
  takeFit(p, train, levels, fit, c);
  c.aic_static = fit.least_squares.aic;
  c.bic_static = fit.least_squares.bic;
  const auto n_train = static_cast<int>(train.size());
  const auto ic = informationCriteria(fit.innovations.squaredNorm(), n_train,
                                      static_cast<int>(inputs.size() + levels.size()) + (c.phi != 0.0 ? 2 : 1));
  c.aic = ic.aic;
  c.bic = ic.bic;
  c.durbin_watson = durbinWatson(fit.residuals);
  c.durbin_watson_innovations = durbinWatson(fit.innovations);
  const int lags = std::min(options.ljung_box_lags, n_train / 4);
  c.ljung_box_q_static = ljungBox(fit.residuals, lags);
  c.ljung_box_p_static = chiSquareSurvival(c.ljung_box_q_static, lags);
  c.ljung_box_q = ljungBox(fit.innovations, lags);
  c.ljung_box_p = chiSquareSurvival(c.ljung_box_q, std::max(1, lags - (c.phi != 0.0 ? 1 : 0)));
  c.rms_train_um = rms(fit.residuals);  // open loop on the training rows
  c.peak_train_um = peak(fit.residuals);
  const Predictions predicted = predict(p, c);
  const Eigen::VectorXd e_test = errors(p, predicted.open_loop, test), e_step = errors(p, predicted.one_step, test);
  c.n_test = static_cast<int>(e_test.size());  // the rows that set a segment's level test nothing
  c.rms_test_um = rms(e_test);
  c.peak_test_um = peak(e_test);
  c.rms_test_one_step_um = rms(e_step);
  c.peak_test_one_step_um = peak(e_step);
  const CvRms cv = crossValidate(p, inputs, family, options.cv_folds), validation = validate(p, inputs, family);
  c.cv_rms_um = cv.open_loop;
  c.cv_rms_one_step_um = cv.one_step;
  c.validation_rms_um = validation.open_loop;
  c.validation_rms_one_step_um = validation.one_step;
  return c;
}

/// Forward selection from `pool` on the family's cross-validated open-loop RMS, 1..k_max inputs.
ThermalPath forwardPath(const Prepared& p, ThermalFamily family, const Inputs& pool, int k_max,
                        const std::vector<std::string>& names, const ThermalFitOptions& options,
                        std::vector<std::string>& notes) {
  ThermalPath path{"stepwise", family, {}};
  Inputs chosen;
  for (int k = 1; k <= k_max; ++k) {
    std::optional<Input> best;
    double best_cv = std::numeric_limits<double>::infinity();
    for (const auto& u : pool) {
      if (std::find(chosen.begin(), chosen.end(), u) != chosen.end()) continue;
      auto trial = chosen;
      trial.push_back(u);
      const double cv = crossValidate(p, trial, family, options.cv_folds).open_loop;
      if (cv < best_cv) {
        best_cv = cv;
        best = u;
      }
    }
    if (!best) break;
    chosen.push_back(*best);
    try {
      path.models.push_back(fitCandidate(p, "stepwise", family, chosen, names, options, notes));
    } catch (const InputError& e) {
      notes.push_back(fmt::format("stepwise selection ({}) of {} inputs: {}", thermalFamilyName(family), k, e.what()));
      break;
    }
  }
  return path;
}

}  // namespace

const char* greyNormalisationName(GreyNormalisation normalisation) {
  switch (normalisation) {
    case GreyNormalisation::kRange:
      return "range";
    case GreyNormalisation::kInitialValue:
      return "initial";
    case GreyNormalisation::kMean:
      return "mean";
  }
  return "?";
}

GreyNormalisation greyNormalisationFromName(const std::string& name) {
  for (auto n : {GreyNormalisation::kRange, GreyNormalisation::kInitialValue, GreyNormalisation::kMean}) {
    if (name == greyNormalisationName(n)) return n;
  }
  throw InputError("grey normalisation '" + name + "': expected range, initial or mean");
}

Eigen::VectorXd greyRelationalGrades(const Eigen::VectorXd& reference, const Eigen::MatrixXd& comparison,
                                     GreyNormalisation normalisation, double rho) {
  if (comparison.rows() != reference.size() || reference.size() < 2) {
    throw InputError(fmt::format("grey relational analysis: {} reference values, {} rows to compare", reference.size(),
                                 comparison.rows()));
  }
  if (!(rho > 0.0 && rho <= 1.0))
    throw InputError(fmt::format("grey relational analysis: rho {} is not in (0, 1]", rho));
  const Eigen::VectorXd x0 = normalised(reference, normalisation, "the reference");
  Eigen::MatrixXd delta(comparison.rows(), comparison.cols());
  for (Eigen::Index c = 0; c < comparison.cols(); ++c) {
    delta.col(c) = (x0 - normalised(comparison.col(c), normalisation, fmt::format("sequence {}", c + 1))).cwiseAbs();
  }
  const double dmin = delta.minCoeff(), dmax = delta.maxCoeff();
  if (!(dmax > 0.0)) return Eigen::VectorXd::Ones(comparison.cols());
  const Eigen::MatrixXd xi = (dmin + rho * dmax) / (delta.array() + rho * dmax);
  return xi.colwise().mean().transpose();
}

std::vector<int> correlationClusters(const Eigen::MatrixXd& columns, int clusters) {
  const auto m = static_cast<int>(columns.cols());
  if (clusters < 1 || clusters > m) throw InputError(fmt::format("clustering: {} clusters of {} columns", clusters, m));
  Eigen::MatrixXd d(m, m);
  for (int i = 0; i < m; ++i) {
    for (int j = 0; j < m; ++j) d(i, j) = 1.0 - std::abs(correlation(columns.col(i), columns.col(j)));
  }
  std::vector<std::vector<int>> groups;
  for (int i = 0; i < m; ++i) groups.push_back({i});
  auto linkage = [&](const std::vector<int>& a, const std::vector<int>& b) {
    double s = 0.0;
    for (int i : a) {
      for (int j : b) s += d(i, j);
    }
    return s / static_cast<double>(a.size() * b.size());
  };
  while (static_cast<int>(groups.size()) > clusters) {
    std::size_t best_a = 0, best_b = 1;
    double best = std::numeric_limits<double>::infinity();
    for (std::size_t a = 0; a < groups.size(); ++a) {
      for (std::size_t b = a + 1; b < groups.size(); ++b) {
        const double l = linkage(groups[a], groups[b]);
        if (l < best) {
          best = l;
          best_a = a;
          best_b = b;
        }
      }
    }
    groups[best_a].insert(groups[best_a].end(), groups[best_b].begin(), groups[best_b].end());
    groups.erase(groups.begin() + static_cast<std::ptrdiff_t>(best_b));
  }
  for (auto& g : groups) std::sort(g.begin(), g.end());
  std::sort(groups.begin(), groups.end());
  std::vector<int> label(static_cast<std::size_t>(m));
  for (std::size_t g = 0; g < groups.size(); ++g) {
    for (int i : groups[g]) label[static_cast<std::size_t>(i)] = static_cast<int>(g);
  }
  return label;
}

const char* thermalFamilyName(ThermalFamily family) {
  switch (family) {
    case ThermalFamily::kStatic:
      return "static";
    case ThermalFamily::kAr1:
      return "ar1";
    case ThermalFamily::kLagged:
      return "lagged";
  }
  return "?";
}

std::string thermalInputName(const ThermalCandidate& model, std::size_t input) {
  const double lag_s = model.lag_s[input];
  if (lag_s <= 0.0) return model.sensors[input];
  return lag_s >= 3600.0 && std::fmod(lag_s, 360.0) == 0.0
             ? fmt::format("{} lag {:g} h", model.sensors[input], lag_s / 3600.0)
             : fmt::format("{} lag {:g} min", model.sensors[input], lag_s / 60.0);
}

std::vector<std::string> thermalInputNames(const ThermalCandidate& model) {
  std::vector<std::string> out;
  for (std::size_t i = 0; i < model.sensors.size(); ++i) out.push_back(thermalInputName(model, i));
  return out;
}

std::vector<std::string> thermalSensorsOf(const ThermalCandidate& model) {
  std::vector<std::string> out;
  for (const auto& s : model.sensors) {
    if (std::find(out.begin(), out.end(), s) == out.end()) out.push_back(s);
  }
  return out;
}

std::vector<const ThermalCandidate*> bestOfEachPath(const ThermalFitResult& result) {
  std::vector<const ThermalCandidate*> out;
  for (const auto& path : result.paths) {
    const ThermalCandidate* best = nullptr;
    for (const auto& c : path.models) {
      if (!best || c.validation_rms_um < best->validation_rms_um) best = &c;
    }
    if (best) out.push_back(best);
  }
  return out;
}

ThermalFitResult fitThermalModel(const ThermalData& data, const ThermalFitOptions& options) {
  const auto n = data.target_um.size();
  const auto sensor_count = static_cast<int>(data.sensors.size());
  if (data.temperature_c.rows() != n || data.temperature_c.cols() != sensor_count || data.time_s.size() != n) {
    throw InputError("thermal model: the target, the temperatures and the times have different sizes");
  }
  if (!(options.train_fraction > 0.0 && options.train_fraction < 1.0)) {
    throw InputError(fmt::format("thermal model: train fraction {} is not between 0 and 1", options.train_fraction));
  }
  if (!(options.validation_fraction > 0.0 && options.validation_fraction <= 0.5)) {
    throw InputError(
        fmt::format("thermal model: validation fraction {} is not in (0, 0.5]", options.validation_fraction));
  }
  if (options.max_sensors < 1) throw InputError("thermal model: --max-sensors must be at least 1");
  const Prepared p(data, options);
  if (p.nTrain() < 20 || p.n() - p.nTrain() < 5) {
    throw InputError(
        fmt::format("thermal model: {} rows give {} for training and {} for the test; need at least 20 and 5", p.n(),
                    p.nTrain(), p.n() - p.nTrain()));
  }
  // The displacement the temperatures explain: read, and moving, over the training rows.
  const Eigen::VectorXd train_target = p.y(p.rows({}, 0, p.nTrain()));
  if (train_target.size() < 2) {
    throw InputError(fmt::format("thermal model: the target (the displacement) has {} values in the {} training rows",
                                 train_target.size(), p.nTrain()));
  }
  if (train_target.maxCoeff() == train_target.minCoeff()) {
    throw InputError(
        fmt::format("thermal model: the target (the displacement) is {:g} um throughout the training rows: nothing "
                    "to explain",
                    train_target(0)));
  }
  ThermalFitResult out;
  out.n_rows = p.n();
  out.n_train_rows = p.nTrain();
  out.split_time_s = data.time_s(p.nTrain());
  out.normalisation = options.normalisation;
  out.rho = options.rho;

  // Which sensors can be used at all.
  std::vector<int> usable;
  for (int c = 0; c < sensor_count; ++c) {
    ThermalSensorStat s;
    s.name = data.sensors[static_cast<std::size_t>(c)];
    s.missing = static_cast<int>(data.temperature_c.col(c).array().isNaN().count());
    s.interpolated = p.interpolated(c);
    const auto train_missing = p.temperatures().col(c).head(p.nTrain()).array().isNaN().count();
    const Inputs alone = {{c, 0.0}};
    const Eigen::VectorXd present = p.x(p.rows(alone, 0, p.nTrain()), alone);
    if (static_cast<double>(train_missing) > options.max_missing_fraction * p.nTrain()) {
      s.usable = false;
      s.note = fmt::format("missing in {} of {} training rows", train_missing, p.nTrain());
    } else if (present.size() < 2 || present.maxCoeff() - present.minCoeff() <= 0.0) {
      s.usable = false;
      s.note = "constant over the training rows";
    } else {
      usable.push_back(c);
    }
    out.sensors.push_back(s);
  }
  if (usable.empty())
    throw InputError("thermal model: no temperature column is usable (every one missing or constant)");

  // Grey relational grades and correlations on the training rows where all usable sensors are present.
  Inputs usable_inputs;
  for (int c : usable) usable_inputs.push_back({c, 0.0});
  const auto common = p.rows(usable_inputs, 0, p.nTrain());
  if (common.size() < 10) {
    throw InputError(fmt::format("thermal model: only {} training rows have the target and every usable temperature",
                                 common.size()));
  }
  const Eigen::MatrixXd tc = p.x(common, usable_inputs);
  const Eigen::VectorXd yc = p.y(common);
  auto grades = [&](GreyNormalisation g) {
    try {
      return greyRelationalGrades(yc, tc, g, options.rho);
    } catch (const InputError& e) {
      out.notes.push_back(fmt::format("grey grades with the {} normalisation: {}", greyNormalisationName(g), e.what()));
      return Eigen::VectorXd(Eigen::VectorXd::Constant(tc.cols(), kNaN));
    }
  };
  const Eigen::VectorXd g_range = grades(GreyNormalisation::kRange),
                        g_initial = grades(GreyNormalisation::kInitialValue), g_mean = grades(GreyNormalisation::kMean);
  const Eigen::VectorXd& chosen_grades = options.normalisation == GreyNormalisation::kRange  ? g_range
                                         : options.normalisation == GreyNormalisation::kMean ? g_mean
                                                                                             : g_initial;
  if (chosen_grades.array().isNaN().any())
    throw InputError("thermal model: no grey grades with the chosen normalisation");
  std::vector<int> by_grade(usable.size());
  std::iota(by_grade.begin(), by_grade.end(), 0);
  std::stable_sort(by_grade.begin(), by_grade.end(), [&](int a, int b) { return chosen_grades(a) > chosen_grades(b); });
  std::vector<std::string> falling;  // sensors anticorrelated with the target
  for (std::size_t u = 0; u < usable.size(); ++u) {
    auto& s = out.sensors[static_cast<std::size_t>(usable[u])];
    const auto i = static_cast<Eigen::Index>(u);
    s.grade = chosen_grades(i);
    s.grade_range = g_range(i);
    s.grade_initial = g_initial(i);
    s.grade_mean = g_mean(i);
    s.correlation = correlation(tc.col(i), yc);
    s.rank = static_cast<int>(std::find(by_grade.begin(), by_grade.end(), static_cast<int>(u)) - by_grade.begin()) + 1;
    if (s.correlation < 0.0 && options.normalisation == GreyNormalisation::kRange)
      falling.push_back(fmt::format("{} (r = {:.2f})", s.name, s.correlation));
  }
  if (!falling.empty()) {
    out.notes.push_back(
        fmt::format("{} fall(s) as the target rises: grey grades of the range normalisation rate such a sensor low "
                    "although a negative coefficient uses it",
                    fmt::join(falling, ", ")));
  }
  auto top = [&](const Eigen::VectorXd& g) {
    Eigen::Index i = 0;
    g.maxCoeff(&i);
    return data.sensors[static_cast<std::size_t>(usable[static_cast<std::size_t>(i)])];
  };
  if (!g_initial.array().isNaN().any() && !g_mean.array().isNaN().any() &&
      (top(g_range) != top(g_initial) || top(g_range) != top(g_mean))) {
    out.notes.push_back(
        fmt::format("the normalisation changes the top-ranked sensor: range {}, initial value {}, mean {}",
                    top(g_range), top(g_initial), top(g_mean)));
  }

  const int k_max = std::min<int>(options.max_sensors, static_cast<int>(usable.size()));
  // The paper's way: clusters of correlated sensors, the highest grade of each, AR(1) errors.
  ThermalPath grey{"grey", ThermalFamily::kAr1, {}};
  for (int k = 1; k <= k_max; ++k) {
    const auto labels = correlationClusters(tc, k);
    std::vector<int> columns;
    for (int cluster = 0; cluster < k; ++cluster) {
      for (int u : by_grade) {
        if (labels[static_cast<std::size_t>(u)] == cluster) {
          columns.push_back(usable[static_cast<std::size_t>(u)]);
          break;
        }
      }
    }
    std::stable_sort(columns.begin(), columns.end(), [&](int a, int b) {
      return out.sensors[static_cast<std::size_t>(a)].grade > out.sensors[static_cast<std::size_t>(b)].grade;
    });
    Inputs inputs;
    for (int c : columns) inputs.push_back({c, 0.0});
    try {
      grey.models.push_back(fitCandidate(p, "grey", ThermalFamily::kAr1, inputs, data.sensors, options, out.notes));
    } catch (const InputError& e) {
      out.notes.push_back(fmt::format("grey selection of {} sensors: {}", k, e.what()));
    }
  }
  out.paths.push_back(std::move(grey));
  // Forward selection in each family; the lagged family's pool holds every sensor at every lag.
  // A time constant longer than a quarter of the search's span is not resolved by its rows: such
  // a lag is a slow trend of the run, not of the machine, and extrapolates as one.
  const double search_span_s = data.time_s(std::max(0, p.nSearch() - 1)) - data.time_s(0);
  Inputs lagged_pool;
  std::vector<double> unresolved;
  for (double lag : options.lag_grid_s) {
    if (lag > 0.25 * search_span_s) unresolved.push_back(lag / 60.0);
  }
  for (int c : usable) {
    lagged_pool.push_back({c, 0.0});
    for (double lag : options.lag_grid_s) {
      if (lag > 0.0 && lag <= 0.25 * search_span_s) lagged_pool.push_back({c, lag});
    }
  }
  if (!unresolved.empty()) {
    out.notes.push_back(fmt::format("lags of {} min not tried: longer than a quarter of the {:.1f} h the search sees",
                                    fmt::join(unresolved, ", "), search_span_s / 3600.0));
  }
  out.paths.push_back(forwardPath(p, ThermalFamily::kStatic, usable_inputs, k_max, data.sensors, options, out.notes));
  out.paths.push_back(forwardPath(p, ThermalFamily::kAr1, usable_inputs, k_max, data.sensors, options, out.notes));
  out.paths.push_back(forwardPath(p, ThermalFamily::kLagged, lagged_pool, k_max, data.sensors, options, out.notes));
  // The references: every sensor by least squares, and the one sensor most correlated.
  if (usable.size() >= 2) {
    try {
      out.all_sensors = fitCandidate(p, "all", ThermalFamily::kStatic, usable_inputs, data.sensors, options, out.notes);
    } catch (const InputError& e) {
      out.notes.push_back(fmt::format("every sensor at once: {}", e.what()));
    }
  }
  int baseline = usable.front();
  for (int c : usable) {
    if (std::abs(out.sensors[static_cast<std::size_t>(c)].correlation) >
        std::abs(out.sensors[static_cast<std::size_t>(baseline)].correlation))
      baseline = c;
  }
  out.baseline =
      fitCandidate(p, "baseline", ThermalFamily::kStatic, {{baseline, 0.0}}, data.sensors, options, out.notes);
  if (const int last = p.segment(p.n() - 1); last != p.segment(0)) {
    out.notes.push_back(fmt::format(
        "the run has {} segments (it was resumed): each has a level of its own, no AR(1) step crosses a gap; a "
        "segment that starts after the training rows takes its level from its first complete row",
        std::set<int>(data.segment.begin(), data.segment.end()).size()));
  }

  std::vector<const ThermalCandidate*> all;
  for (const auto& path : out.paths) {
    for (const auto& c : path.models) all.push_back(&c);
  }
  if (out.all_sensors) all.push_back(&*out.all_sensors);
  for (const auto* c : all) {
    if (!std::isfinite(c->validation_rms_um)) {
      out.notes.push_back(fmt::format(
          "{} {} ({}): no validation (an input is constant, or the inputs dependent, over the search's rows); "
          "not eligible as the kept model",
          c->method, thermalFamilyName(c->family), fmt::join(c->sensors, "+")));
    }
  }
  if (all.empty()) throw InputError("thermal model: no candidate model could be fitted");
  double best_validation = std::numeric_limits<double>::infinity();
  for (const auto* c : all) best_validation = std::min(best_validation, c->validation_rms_um);
  const ThermalCandidate* chosen = nullptr;
  for (const auto* c : all) {
    if (c->validation_rms_um > best_validation * (1.0 + options.parsimony)) continue;
    if (!chosen || c->columns.size() < chosen->columns.size() ||
        (c->columns.size() == chosen->columns.size() && c->validation_rms_um < chosen->validation_rms_um)) {
      chosen = c;
    }
  }
  if (!chosen) throw InputError("thermal model: no candidate model could be validated");
  out.chosen = *chosen;
  out.gain = 1.0 - out.chosen.rms_test_um / out.baseline.rms_test_um;
  {
    std::vector<double> test;
    for (int i = p.nTrain(); i < p.n(); ++i) {
      if (!std::isnan(p.target(i))) test.push_back(p.target(i));
    }
    const Eigen::Map<const Eigen::VectorXd> t(test.data(), static_cast<Eigen::Index>(test.size()));
    out.test_sd_um = test.size() > 1 ? std::sqrt((t.array() - t.mean()).square().sum() / (t.size() - 1)) : kNaN;
  }

  std::set<int> chosen_sensors(out.chosen.columns.begin(), out.chosen.columns.end());
  const auto labels = correlationClusters(tc, static_cast<int>(chosen_sensors.size()));
  for (std::size_t u = 0; u < usable.size(); ++u) out.sensors[static_cast<std::size_t>(usable[u])].cluster = labels[u];
  auto predicted = predict(p, out.chosen);
  out.predicted_open_loop_um = std::move(predicted.open_loop);
  out.predicted_one_step_um = std::move(predicted.one_step);
  if (p.n() > 2) {
    const Eigen::VectorXd dt = data.time_s.tail(p.n() - 1) - data.time_s.head(p.n() - 1);
    if (dt.maxCoeff() > 1.1 * dt.minCoeff()) {
      out.notes.push_back(
          fmt::format("the sampling interval varies ({:.1f} to {:.1f} s): phi is per row, not per second",
                      dt.minCoeff(), dt.maxCoeff()));
    }
  }
  const auto dropped = p.n() - static_cast<int>(p.rows(inputsOf(out.chosen), 0, p.n()).size());
  if (dropped > 0)
    out.notes.push_back(fmt::format("{} rows lack the target or a chosen sensor and are left out", dropped));
  return out;
}

}  // namespace mtcal::processing
