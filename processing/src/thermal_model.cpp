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

/// The data after gap filling, and which rows each model may use.
class Prepared {
 public:
  Prepared(const ThermalData& data, const ThermalFitOptions& options) : data_(data), t_(data.temperature_c) {
    n_ = static_cast<int>(data.target_um.size());
    n_train_ = static_cast<int>(std::floor(options.train_fraction * n_));
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
  const Eigen::MatrixXd& temperatures() const { return t_; }
  int interpolated(int c) const { return interpolated_[static_cast<std::size_t>(c)]; }
  double target(int i) const { return data_.target_um(i); }

  bool rowComplete(int i, const std::vector<int>& columns) const {
    if (std::isnan(data_.target_um(i))) return false;
    return std::none_of(columns.begin(), columns.end(), [&](int c) { return std::isnan(t_(i, c)); });
  }
  /// Rows in [from, to) with the target and every column present.
  std::vector<int> rows(const std::vector<int>& columns, int from, int to) const {
    std::vector<int> out;
    for (int i = from; i < to; ++i) {
      if (rowComplete(i, columns)) out.push_back(i);
    }
    return out;
  }
  /// The temperatures of `columns` at `rows`, then an indicator column for each of `levels`.
  Eigen::MatrixXd x(const std::vector<int>& rows, const std::vector<int>& columns,
                    const std::vector<int>& levels = {}) const {
    Eigen::MatrixXd out = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(rows.size()),
                                                static_cast<Eigen::Index>(columns.size() + levels.size()));
    for (std::size_t r = 0; r < rows.size(); ++r) {
      for (std::size_t c = 0; c < columns.size(); ++c)
        out(static_cast<Eigen::Index>(r), static_cast<Eigen::Index>(c)) = t_(rows[r], columns[c]);
      for (std::size_t l = 0; l < levels.size(); ++l) {
        if (segment(rows[r]) == levels[l])
          out(static_cast<Eigen::Index>(r), static_cast<Eigen::Index>(columns.size() + l)) = 1.0;
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
  int n_ = 0, n_train_ = 0;
  std::vector<int> interpolated_;
};

double openLoop(const Eigen::VectorXd& b, const Eigen::MatrixXd& t, int row, const std::vector<int>& columns) {
  double v = b(0);
  for (std::size_t c = 0; c < columns.size(); ++c) v += b(static_cast<Eigen::Index>(c) + 1) * t(row, columns[c]);
  return v;
}

/// Sets a model's coefficients and segment levels from a fit of p.x(rows, columns, levels).
void takeCoefficients(const Prepared& p, const std::vector<int>& rows, const std::vector<int>& levels,
                      const Eigen::VectorXd& fitted, ThermalCandidate& model) {
  const auto k = static_cast<Eigen::Index>(model.columns.size()) + 1;
  model.coefficients = fitted.head(k);
  model.segment_level_um = {{p.segment(rows.front()), 0.0}};
  for (std::size_t l = 0; l < levels.size(); ++l)
    model.segment_level_um[levels[l]] = fitted(k + static_cast<Eigen::Index>(l));
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
  Predictions out;
  out.open_loop = predictOpenLoop(model, p.temperatures());
  std::map<int, double> level = model.segment_level_um;
  for (int i = 0; i < p.n(); ++i) {
    if (std::isnan(out.open_loop(i))) continue;
    const int s = p.segment(i);
    if (!level.contains(s)) {
      if (!p.rowComplete(i, model.columns)) continue;
      level[s] = p.target(i) - out.open_loop(i);
      out.level_rows.push_back(i);
      out.open_loop(i) = std::numeric_limits<double>::quiet_NaN();
      continue;
    }
    out.open_loop(i) += level[s];
  }
  out.one_step = out.open_loop;
  for (int i = 1; i < p.n(); ++i) {
    if (p.segment(i) == p.segment(i - 1) && p.rowComplete(i - 1, model.columns) && !std::isnan(out.open_loop(i - 1)) &&
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

/// Rolling-origin cross-validation within the training rows: static least squares on the
/// rows before each origin predicts the rows up to the next one (open loop).
double cvRms(const Prepared& p, const std::vector<int>& columns, int folds) {
  const auto rows = p.rows(columns, 0, p.nTrain());
  const auto n = static_cast<int>(rows.size());
  double sum = 0.0;
  int count = 0;
  for (int f = 0; f < folds; ++f) {
    const int origin = static_cast<int>(n * (0.5 + 0.4 * f / std::max(1, folds - 1)));
    const int end = f + 1 < folds ? static_cast<int>(n * (0.5 + 0.4 * (f + 1) / std::max(1, folds - 1))) : n;
    const std::vector<int> fit_rows(rows.begin(), rows.begin() + origin);
    const auto levels = p.laterSegments(fit_rows);
    if (origin <= static_cast<int>(columns.size() + levels.size()) + 2) return std::numeric_limits<double>::infinity();
    ThermalCandidate model;
    model.columns = columns;
    try {
      takeCoefficients(p, fit_rows, levels, fitLinear(p.x(fit_rows, columns, levels), p.y(fit_rows)).coefficients,
                       model);
    } catch (const InputError&) {
      return std::numeric_limits<double>::infinity();
    }
    const Predictions predicted = predict(p, model);
    const Eigen::VectorXd e =
        errors(p, predicted.open_loop, std::vector<int>(rows.begin() + origin, rows.begin() + end));
    sum += e.squaredNorm();
    count += static_cast<int>(e.size());
  }
  return count ? std::sqrt(sum / count) : std::numeric_limits<double>::infinity();
}

/// Fits a model on the training rows and evaluates it on both parts (not the CV: the callers
/// have it or compute it). @throws InputError
ThermalCandidate fitCandidate(const Prepared& p, const std::string& method, const std::vector<int>& columns,
                              const std::vector<std::string>& names, bool ar1, const ThermalFitOptions& options,
                              std::vector<std::string>& notes) {
  ThermalCandidate c;
  c.method = method;
  c.columns = columns;
  for (int col : columns) c.sensors.push_back(names[static_cast<std::size_t>(col)]);
  const auto train = p.rows(columns, 0, p.nTrain());
  const auto test = p.rows(columns, p.nTrain(), p.n());
  c.n_train = static_cast<int>(train.size());
  c.n_test = static_cast<int>(test.size());
  if (train.size() < 10 || test.empty()) {
    throw InputError(fmt::format("thermal model {}: {} training and {} test rows with every value present",
                                 fmt::join(c.sensors, "+"), train.size(), test.size()));
  }
  const auto levels = p.laterSegments(train);
  const Eigen::MatrixXd x = p.x(train, columns, levels);
  const Eigen::VectorXd y = p.y(train);
  const LinearFit fit = fitLinear(x, y);
  takeCoefficients(p, train, levels, fit.coefficients, c);
  c.aic_static = fit.aic;
  c.bic_static = fit.bic;
  Eigen::VectorXd residual = fit.residuals, innovations = fit.residuals;
  if (ar1) {
    try {
      const Ar1Fit a = fitLinearAr1(x, y, p.starts(train));
      takeCoefficients(p, train, levels, a.fit.coefficients, c);
      c.phi = a.phi;
      residual = a.fit.residuals;
      innovations = a.innovations;
    } catch (const InputError& e) {
      notes.push_back(
          fmt::format("{} ({}): {}; fitted without the AR(1) term", method, fmt::join(c.sensors, "+"), e.what()));
    }
  }
  const auto ic = informationCriteria(innovations.squaredNorm(), static_cast<int>(y.size()),
                                      static_cast<int>(columns.size() + levels.size()) + (c.phi != 0.0 ? 2 : 1));
  c.aic = ic.aic;
  c.bic = ic.bic;
  c.durbin_watson = durbinWatson(residual);
  c.durbin_watson_innovations = durbinWatson(innovations);
  const int lags = std::min(options.ljung_box_lags, static_cast<int>(y.size()) / 4);
  c.ljung_box_q_static = ljungBox(residual, lags);
  c.ljung_box_p_static = chiSquareSurvival(c.ljung_box_q_static, lags);
  c.ljung_box_q = ljungBox(innovations, lags);
  c.ljung_box_p = chiSquareSurvival(c.ljung_box_q, std::max(1, lags - (c.phi != 0.0 ? 1 : 0)));
  c.rms_train_um = rms(residual);  // open loop on the training rows
  c.peak_train_um = peak(residual);
  const Predictions predicted = predict(p, c);
  const Eigen::VectorXd e_test = errors(p, predicted.open_loop, test), e_step = errors(p, predicted.one_step, test);
  c.n_test = static_cast<int>(e_test.size());  // the rows that set a segment's level test nothing
  c.rms_test_um = rms(e_test);
  c.peak_test_um = peak(e_test);
  c.rms_test_one_step_um = rms(e_step);
  c.peak_test_one_step_um = peak(e_step);
  return c;
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

Eigen::VectorXd predictOpenLoop(const ThermalCandidate& model, const Eigen::MatrixXd& temperature_c) {
  Eigen::VectorXd out(temperature_c.rows());
  for (Eigen::Index i = 0; i < temperature_c.rows(); ++i)
    out(i) = openLoop(model.coefficients, temperature_c, static_cast<int>(i), model.columns);
  return out;  // NaN propagates from a missing temperature
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
  if (options.max_sensors < 1) throw InputError("thermal model: --max-sensors must be at least 1");
  const Prepared p(data, options);
  if (p.nTrain() < 20 || p.n() - p.nTrain() < 5) {
    throw InputError(
        fmt::format("thermal model: {} rows give {} for training and {} for the test; need at least 20 and 5", p.n(),
                    p.nTrain(), p.n() - p.nTrain()));
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
    const Eigen::VectorXd present = p.x(p.rows({c}, 0, p.nTrain()), {c});
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
  const auto common = p.rows(usable, 0, p.nTrain());
  if (common.size() < 10) {
    throw InputError(fmt::format("thermal model: only {} training rows have the target and every usable temperature",
                                 common.size()));
  }
  const Eigen::MatrixXd tc = p.x(common, usable);
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
  for (std::size_t u = 0; u < usable.size(); ++u) {
    auto& s = out.sensors[static_cast<std::size_t>(usable[u])];
    const auto i = static_cast<Eigen::Index>(u);
    s.grade = chosen_grades(i);
    s.grade_range = g_range(i);
    s.grade_initial = g_initial(i);
    s.grade_mean = g_mean(i);
    s.correlation = correlation(tc.col(i), yc);
    s.rank = static_cast<int>(std::find(by_grade.begin(), by_grade.end(), static_cast<int>(u)) - by_grade.begin()) + 1;
    if (s.correlation < 0.0 && options.normalisation == GreyNormalisation::kRange) {
      out.notes.push_back(
          fmt::format("{} falls as the target rises (r = {:.2f}): grey grades of the range normalisation rate "
                      "such a sensor low although a negative coefficient uses it",
                      s.name, s.correlation));
    }
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
  // The paper's way: clusters of correlated sensors, the highest grade of each.
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
    try {
      out.grey.push_back(fitCandidate(p, "grey", columns, data.sensors, true, options, out.notes));
      out.grey.back().cv_rms_um = cvRms(p, columns, options.cv_folds);
    } catch (const InputError& e) {
      out.notes.push_back(fmt::format("grey selection of {} sensors: {}", k, e.what()));
    }
  }
  // Forward stepwise on the cross-validated RMS.
  std::vector<int> chosen_columns;
  for (int k = 1; k <= k_max; ++k) {
    int best = -1;
    double best_cv = std::numeric_limits<double>::infinity();
    for (int c : usable) {
      if (std::find(chosen_columns.begin(), chosen_columns.end(), c) != chosen_columns.end()) continue;
      auto trial = chosen_columns;
      trial.push_back(c);
      const double cv = cvRms(p, trial, options.cv_folds);
      if (cv < best_cv) {
        best_cv = cv;
        best = c;
      }
    }
    if (best < 0) break;
    chosen_columns.push_back(best);
    try {
      out.stepwise.push_back(fitCandidate(p, "stepwise", chosen_columns, data.sensors, true, options, out.notes));
      out.stepwise.back().cv_rms_um = best_cv;  // the search's
    } catch (const InputError& e) {
      out.notes.push_back(fmt::format("stepwise selection of {} sensors: {}", k, e.what()));
      break;
    }
  }
  // Baseline: the one sensor most correlated with the target, linear, no AR term.
  int baseline = usable.front();
  for (int c : usable) {
    if (std::abs(out.sensors[static_cast<std::size_t>(c)].correlation) >
        std::abs(out.sensors[static_cast<std::size_t>(baseline)].correlation))
      baseline = c;
  }
  out.baseline = fitCandidate(p, "baseline", {baseline}, data.sensors, false, options, out.notes);
  if (const int last = p.segment(p.n() - 1); last != p.segment(0)) {
    out.notes.push_back(fmt::format(
        "the run has {} segments (it was resumed): each has a level of its own, no AR(1) step crosses a gap; a "
        "segment that starts after the training rows takes its level from its first complete row",
        std::set<int>(data.segment.begin(), data.segment.end()).size()));
  }
  out.baseline.cv_rms_um = cvRms(p, {baseline}, options.cv_folds);

  std::vector<const ThermalCandidate*> all;
  for (const auto& c : out.grey) all.push_back(&c);
  for (const auto& c : out.stepwise) all.push_back(&c);
  for (const auto* c : all) {
    if (!std::isfinite(c->cv_rms_um)) {
      out.notes.push_back(
          fmt::format("{} ({}): no cross-validation (an input is constant, or the inputs dependent, over the first "
                      "folds' rows); not eligible as the kept model",
                      c->method, fmt::join(c->sensors, "+")));
    }
  }
  if (all.empty()) throw InputError("thermal model: no candidate model could be fitted");
  double best_cv = std::numeric_limits<double>::infinity();
  for (const auto* c : all) best_cv = std::min(best_cv, c->cv_rms_um);
  const ThermalCandidate* chosen = nullptr;
  for (const auto* c : all) {
    if (c->cv_rms_um > best_cv * (1.0 + options.parsimony)) continue;
    if (!chosen || c->sensors.size() < chosen->sensors.size() ||
        (c->sensors.size() == chosen->sensors.size() && c->cv_rms_um < chosen->cv_rms_um)) {
      chosen = c;
    }
  }
  out.chosen = *chosen;
  out.gain = 1.0 - out.chosen.rms_test_um / out.baseline.rms_test_um;

  const auto& columns = out.chosen.columns;
  const auto labels = correlationClusters(tc, static_cast<int>(columns.size()));
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
  const auto dropped = p.n() - static_cast<int>(p.rows(columns, 0, p.n()).size());
  if (dropped > 0)
    out.notes.push_back(fmt::format("{} rows lack the target or a chosen sensor and are left out", dropped));
  return out;
}

}  // namespace mtcal::processing
