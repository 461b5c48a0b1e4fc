#include "mtcal/processing/diagnosis.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <numeric>
#include <set>

#include <Eigen/Dense>
#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "mtcal/error.h"
#include "mtcal/processing/bspline.h"
#include "mtcal/processing/error_model.h"
#include "mtcal/processing/geometry3d.h"
#include "mtcal/processing/regression.h"
#include "mtcal/processing/thermal_model.h"

namespace mtcal::processing {
namespace {

constexpr double kTwoPi = 2.0 * std::numbers::pi;
/// Apparent displacement per mm of uncompensated dead path and K of air temperature (um):
/// the air index falls by 0.929 ppm/K near 20 degC, 101.3 kPa (Edlen).
constexpr double kDeadPathUmPerMmK = 0.929e-3;
/// Optics further off the line than this are a set-up no one makes: a fit asking for more is
/// another cause with the same shape.
constexpr double kMaxAbbeOffsetMm = 500.0;
constexpr double kMaxDeadPathMm = 3000.0;

Eigen::VectorXd vec(const std::vector<double>& v) { return Eigen::Map<const Eigen::VectorXd>(v.data(), static_cast<Eigen::Index>(v.size())); }

/// The clamped cubic (or lower, with few sites) B-spline basis of `spans` spans over `range`.
BSpline basisSpline(std::pair<double, double> range, int spans) {
  const int degree = 3;
  std::vector<double> interior;
  for (int k = 1; k < spans; ++k) interior.push_back(range.first + (range.second - range.first) * k / spans);
  const auto knots = BSpline::clampedKnots(range.first, range.second, degree, interior);
  return BSpline(degree, knots, Eigen::VectorXd::Zero(static_cast<Eigen::Index>(knots.size()) - degree - 1));
}

/// Least squares of y on the columns of x (rank revealing, columns scaled to unit norm).
struct LeastSquares {
  Eigen::VectorXd coefficients;  ///< 0 for columns left out as dependent
  Eigen::VectorXd residual;
  Eigen::VectorXd standard_error;
  int rank = 0;
  double rss = 0.0;
};
LeastSquares leastSquares(const Eigen::MatrixXd& x, const Eigen::VectorXd& y) {
  LeastSquares f;
  if (x.cols() == 0) {
    f.residual = y;
    f.rss = y.squaredNorm();
    return f;
  }
  // Columns scaled to unit norm; a column that is numerically zero (a sinusoid sampled at its
  // zeros) stays zero rather than being blown up to a unit column of rounding errors.
  const double negligible = 1e-9 * std::sqrt(static_cast<double>(x.rows()));
  Eigen::VectorXd norms = x.colwise().norm().transpose();
  Eigen::MatrixXd xs = x;
  for (Eigen::Index j = 0; j < norms.size(); ++j) {
    if (norms(j) > negligible) {
      xs.col(j) /= norms(j);
    } else {
      xs.col(j).setZero();
      norms(j) = 1.0;
    }
  }
  // The complete orthogonal decomposition gives the least-squares solution of least norm even
  // when columns are dependent (column-pivoting QR's basic solution then misses the minimum).
  Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd> cod(xs);
  cod.setThreshold(1e-10);
  f.rank = static_cast<int>(cod.rank());
  f.coefficients = cod.solve(y).cwiseQuotient(norms);
  f.residual = y - x * f.coefficients;
  f.rss = f.residual.squaredNorm();
  f.standard_error = Eigen::VectorXd::Zero(x.cols());
  const Eigen::Index dof = x.rows() - f.rank;
  if (dof > 0 && f.rank == x.cols()) {
    Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(xs);
    const Eigen::MatrixXd r = qr.matrixR().topLeftCorner(f.rank, f.rank).triangularView<Eigen::Upper>();
    const Eigen::MatrixXd rinv = r.triangularView<Eigen::Upper>().solve(Eigen::MatrixXd::Identity(f.rank, f.rank));
    const Eigen::VectorXd var_scaled = (rinv * rinv.transpose()).diagonal();
    const double s2 = f.rss / static_cast<double>(dof);
    for (Eigen::Index k = 0; k < f.rank; ++k) {
      const Eigen::Index j = qr.colsPermutation().indices()(k);
      f.standard_error(j) = std::sqrt(s2 * var_scaled(k)) / norms(j);
    }
  }
  return f;
}

struct HeldOut {
  Eigen::VectorXd residual;
  double rms = 0.0, peak = 0.0;
};
/// Every fold left out in turn: fitted on the others, its residuals predicted.
HeldOut crossValidate(const Eigen::MatrixXd& x, const Eigen::VectorXd& y, const Eigen::VectorXi& fold) {
  HeldOut h;
  h.residual = Eigen::VectorXd::Zero(y.size());
  const int folds = fold.size() ? fold.maxCoeff() + 1 : 0;
  for (int f = 0; f < folds; ++f) {
    std::vector<Eigen::Index> train, test;
    for (Eigen::Index i = 0; i < y.size(); ++i) (fold(i) == f ? test : train).push_back(i);
    if (test.empty()) continue;
    const Eigen::MatrixXd xt = x(train, Eigen::all);
    const auto fit = leastSquares(xt, y(train));
    for (Eigen::Index i : test) h.residual(i) = y(i) - (x.cols() ? x.row(i).dot(fit.coefficients) : 0.0);
  }
  h.rms = std::sqrt(h.residual.squaredNorm() / static_cast<double>(std::max<Eigen::Index>(1, y.size())));
  h.peak = h.residual.cwiseAbs().maxCoeff();
  return h;
}

double rmsOf(const Eigen::VectorXd& r) { return r.size() ? std::sqrt(r.squaredNorm() / static_cast<double>(r.size())) : 0.0; }

/// Whether every column is the same at all points of each site (a function of the site alone).
bool constantWithin(const Eigen::MatrixXd& columns, const Eigen::VectorXi& site) {
  const int sites = site.maxCoeff() + 1;
  Eigen::MatrixXd first = Eigen::MatrixXd::Constant(sites, columns.cols(), std::numeric_limits<double>::quiet_NaN());
  const double tolerance = 1e-9 * std::max(1.0, columns.cwiseAbs().maxCoeff());
  for (Eigen::Index i = 0; i < columns.rows(); ++i) {
    for (Eigen::Index j = 0; j < columns.cols(); ++j) {
      double& f = first(site(i), j);
      if (std::isnan(f)) {
        f = columns(i, j);
      } else if (std::abs(columns(i, j) - f) > tolerance) {
        return false;
      }
    }
  }
  return true;
}

/// The sums of every column per site and the sites' counts.
std::pair<Eigen::MatrixXd, Eigen::VectorXd> siteSums(const Eigen::MatrixXd& x, const Eigen::VectorXi& site) {
  const int sites = site.maxCoeff() + 1;
  std::pair<Eigen::MatrixXd, Eigen::VectorXd> out{Eigen::MatrixXd::Zero(sites, x.cols()), Eigen::VectorXd::Zero(sites)};
  for (Eigen::Index i = 0; i < x.rows(); ++i) {
    out.first.row(site(i)) += x.row(i);
    out.second(site(i)) += 1.0;
  }
  return out;
}

/// The means of every column per site, each scaled by the square root of the site's count
/// (so that least squares on them is the weighted fit of the means).
Eigen::MatrixXd siteMeans(const Eigen::MatrixXd& x, const Eigen::VectorXi& site) {
  auto [sum, count] = siteSums(x, site);
  for (Eigen::Index s = 0; s < sum.rows(); ++s) sum.row(s) *= count(s) > 0.0 ? 1.0 / std::sqrt(count(s)) : 0.0;
  return sum;
}

/// Every column less its mean over each site.
Eigen::MatrixXd withinSites(const Eigen::MatrixXd& x, const Eigen::VectorXi& site) {
  const auto [sum, count] = siteSums(x, site);
  Eigen::MatrixXd out = x;
  for (Eigen::Index i = 0; i < x.rows(); ++i) out.row(i) -= sum.row(site(i)) / count(site(i));
  return out;
}

struct Evaluation {
  Candidate candidate;  ///< with the searched value set
  Eigen::MatrixXd columns;
  double delta_bic = 0.0, p_value = 1.0;
  int added_rank = 0;
};

/// The model a round's candidates are tested against: its design, fit, and an orthonormal
/// basis of its columns' space.
struct CurrentModel {
  const Eigen::MatrixXd& design;
  LeastSquares fit;
  Eigen::MatrixXd q;
  CurrentModel(const Eigen::MatrixXd& d, const Eigen::VectorXd& y) : design(d), fit(leastSquares(d, y)) {
    if (fit.rank == 0) return;
    Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd> cod(d * d.colwise().norm().cwiseMax(1e-300).cwiseInverse().asDiagonal());
    cod.setThreshold(1e-10);
    q = cod.householderQ() * Eigen::MatrixXd::Identity(d.rows(), fit.rank);
  }
};

/// The candidate's best searched value and its test against the current model.
Evaluation evaluate(const Candidate& c, const DiagnosisData& data, const CurrentModel& model, const Eigen::VectorXd& y, int family) {
  Evaluation e;
  e.candidate = c;
  const auto n = static_cast<double>(y.size());
  const auto& design = model.design;
  const auto& current = model.fit;
  const auto& q = model.q;
  auto project_out = [&](const Eigen::MatrixXd& cols) -> Eigen::MatrixXd {
    return q.cols() ? Eigen::MatrixXd(cols - q * (q.transpose() * cols)) : cols;
  };
  std::vector<double> tries = c.search.empty() ? std::vector<double>{c.shapes.front().searched} : c.search;
  double best_rss = std::numeric_limits<double>::infinity();
  for (double value : tries) {
    Candidate trial = c;
    trial.shapes.front().searched = value;
    const Eigen::MatrixXd cols = extensionColumns(trial.shapes, data);
    const auto fit = leastSquares(project_out(cols), current.residual);
    if (fit.rank == 0 || !(fit.rss < best_rss)) continue;
    best_rss = fit.rss;
    e.candidate = trial;
    e.columns = cols;
    e.added_rank = fit.rank;
  }
  if (e.added_rank == 0) return e;
  // The test's stratum: a term that depends on the position alone (the same at every repeat of
  // a position) is tested on the positions' means against their scatter about the model
  // (lack of fit), not against the scatter of repeats: the model's own error at a position
  // repeats in every cycle and would otherwise pass as evidence.
  double rss0 = current.rss, rss1 = best_rss, points = n;
  int rank0 = current.rank, added = e.added_rank;
  const bool sites = data.site.size() == y.size();
  if (sites && !constantWithin(e.columns, data.site)) {
    // A term that varies within a site is tested against the repeats' scatter: every site's
    // own mean is free (what the model gets wrong at a position is not evidence of it).
    // (Frisch-Waugh-Lovell: the site means taken out of everything.)
    const auto count = static_cast<int>(data.site.maxCoeff() + 1);
    const Eigen::MatrixXd base = withinSites(design, data.site);
    Eigen::MatrixXd with(base.rows(), base.cols() + e.columns.cols());
    with << base, withinSites(e.columns, data.site);
    const Eigen::VectorXd within_y = withinSites(y, data.site);
    const auto f0 = leastSquares(base, within_y), f1 = leastSquares(with, within_y);
    rss0 = f0.rss;
    rss1 = f1.rss;
    rank0 = f0.rank + count;
    added = f1.rank - f0.rank;
    if (added <= 0) {
      e.added_rank = 0;
      return e;
    }
  } else if (sites) {
    // The terms that vary within sites keep what the repeats say of them (their coefficients
    // from the full fit); the site-level terms and the candidate are fitted to the sites' means.
    std::vector<Eigen::Index> site_level;
    Eigen::VectorXd z = current.residual;
    for (Eigen::Index j = 0; j < design.cols(); ++j) {
      if (!constantWithin(design.col(j), data.site)) continue;
      site_level.push_back(j);
      if (current.coefficients.size()) z += design.col(j) * current.coefficients(j);
    }
    const Eigen::MatrixXd mean_design = siteMeans(design(Eigen::all, site_level), data.site);
    Eigen::MatrixXd with(mean_design.rows(), mean_design.cols() + e.columns.cols());
    with << mean_design, siteMeans(e.columns, data.site);
    const Eigen::VectorXd mean_y = siteMeans(z, data.site);
    const auto f0 = leastSquares(mean_design, mean_y), f1 = leastSquares(with, mean_y);
    rss0 = f0.rss;
    rss1 = f1.rss;
    rank0 = f0.rank;
    added = f1.rank - f0.rank;
    points = static_cast<double>(mean_y.size());
    if (added <= 0) {
      e.added_rank = 0;
      return e;
    }
  }
  const double dof2 = points - rank0 - added - (sites ? 0 : data.absorbed_dof);
  if (dof2 < 2.0 || !(rss1 > 0.0)) return e;
  const double f = ((rss0 - rss1) / added) / (rss1 / dof2);
  const double p_single = fisherFSurvival(f, added, dof2);
  const double p_search = c.search.empty() ? p_single : -std::expm1(c.independent_tries * std::log1p(-std::min(p_single, 1.0 - 1e-16)));
  e.p_value = std::min(1.0, p_search * family);
  const double searched_parameters = c.search.empty() ? 0.0 : 1.0;
  e.delta_bic = points * std::log(rss0 / rss1) - (added + searched_parameters) * std::log(points);
  return e;
}

/// Why a fitted candidate is physically implausible (a parameter beyond its limit); empty: it is not.
std::string implausibleParameter(const Candidate& c, const Eigen::VectorXd& coef) {
  for (std::size_t k = 0; k < c.parameters.size() && static_cast<Eigen::Index>(k) < coef.size(); ++k) {
    const auto& p = c.parameters[k];
    const double value = coef(static_cast<Eigen::Index>(k)) * p.per_coefficient;
    if (p.max_abs > 0.0 && std::abs(value) > p.max_abs) {
      return fmt::format("implausible: {} = {:.4g} {} (beyond {} {})", p.name, value, p.unit, p.max_abs, p.unit);
    }
  }
  return {};
}

std::vector<ParameterValue> parametersOf(const Candidate& c, const Eigen::VectorXd& coef, const Eigen::VectorXd& se,
                                         const Eigen::MatrixXd& columns, const DiagnosisData& data) {
  std::vector<ParameterValue> out;
  for (std::size_t k = 0; k < c.parameters.size() && static_cast<Eigen::Index>(k) < coef.size(); ++k) {
    const auto& p = c.parameters[k];
    out.push_back({p.name, p.unit, coef(static_cast<Eigen::Index>(k)) * p.per_coefficient,
                   se(static_cast<Eigen::Index>(k)) * std::abs(p.per_coefficient)});
  }
  const auto& shape = c.shapes.front();
  if (shape.kind.rfind("harmonic", 0) == 0 && coef.size() >= 2) {
    out.push_back({"amplitude", "um", std::hypot(coef(0), coef(1)), std::hypot(se(0), se(1)) / std::sqrt(2.0)});
  }
  if (shape.kind == "step_difference") {
    // The yaw curve (urad) about its least-squares line: its constant and its constant rate
    // are not determined (the latter is the probes' zeros).
    const auto spline = basisSpline(shape.range, shape.spans);
    Eigen::VectorXd full = Eigen::VectorXd::Zero(spline.coefficients().size());
    full.tail(coef.size()) = coef;
    const BSpline yaw(spline.degree(), spline.knots(), full);
    const int samples = 201;
    Eigen::MatrixXd line(samples, 2);
    Eigen::VectorXd values(samples);
    for (int k = 0; k < samples; ++k) {
      const double x = shape.range.first + (shape.range.second - shape.range.first) * k / (samples - 1.0);
      line.row(k) << 1.0, x;
      values(k) = yaw(x);
    }
    const Eigen::VectorXd about_line = values - line * line.colPivHouseholderQr().solve(values);
    out.push_back({"yaw_peak_to_valley", "urad", about_line.maxCoeff() - about_line.minCoeff(), 0.0});
  } else if (c.parameters.empty()) {  // a generic dependence: the size of what it adds
    const Eigen::VectorXd values = columns * coef;
    out.push_back({"peak_to_valley", "um", values.maxCoeff() - values.minCoeff(), 0.0});
  }
  if (!c.search.empty()) out.push_back({c.searched_name, c.searched_unit, shape.searched, 0.0});
  if (c.effect == "thermal_drift" && c.variable == "time_s") {  // what the run saw, whatever the shape
    const auto& t = data.variable("time_s")->values;
    Eigen::Index first = 0, last = 0;
    t.minCoeff(&first);
    t.maxCoeff(&last);
    const Eigen::VectorXd values = columns * coef;
    out.push_back({"drift_over_run", data.value_unit, values(last) - values(first), 0.0});
  }
  return out;
}

/// The median gap between sorted, distinct values (distinct()).
double medianSpacing(const std::vector<double>& values) {
  if (values.size() < 2) return 0.0;
  std::vector<double> d;
  for (std::size_t i = 1; i < values.size(); ++i) d.push_back(values[i] - values[i - 1]);
  std::nth_element(d.begin(), d.begin() + static_cast<std::ptrdiff_t>(d.size() / 2), d.end());
  return d[d.size() / 2];
}

std::vector<double> distinct(const Eigen::VectorXd& v) {
  std::vector<double> s(v.data(), v.data() + v.size());
  std::sort(s.begin(), s.end());
  s.erase(std::unique(s.begin(), s.end(), [](double a, double b) { return std::abs(a - b) < 1e-9; }), s.end());
  return s;
}

/// "The residual depends on <variable>": a smooth function of one variable (cubic B-spline).
Candidate genericCandidate(const DiagnosisVariable& v) {
  Candidate c;
  c.effect = "generic";
  c.variable = v.name;
  c.cause = fmt::format("the residual depends on {} in a way none of the named causes describes", v.name);
  const int spans = std::clamp(static_cast<int>(distinct(v.values).size()) / 6, 1, 4);
  ExtensionShape s{"spline", {v.name}};
  s.spans = spans;
  s.range = {v.values.minCoeff(), v.values.maxCoeff()};
  c.shapes = {s};
  return c;
}

ExtensionShape shape(const std::string& kind, std::vector<std::string> variables, double scale = 1.0, double reference = 0.0,
                     double searched = 0.0) {
  ExtensionShape s;
  s.kind = kind;
  s.variables = std::move(variables);
  s.scale = scale;
  s.reference = reference;
  s.searched = searched;
  return s;
}

Candidate candidate(std::string effect, std::string variable, std::string cause, std::vector<ExtensionShape> shapes,
                    std::vector<Candidate::Parameter> parameters) {
  Candidate c;
  c.effect = std::move(effect);
  c.variable = std::move(variable);
  c.cause = std::move(cause);
  c.shapes = std::move(shapes);
  c.parameters = std::move(parameters);
  return c;
}

/// Log-spaced time constants over the run and a first-order drift candidate.
Candidate firstOrderDrift(const Eigen::VectorXd& time_s) {
  const double span = time_s.maxCoeff() - time_s.minCoeff();
  auto c = candidate("thermal_drift", "time_s", "the machine drifts with time towards a new thermal state (first-order response)",
                     {shape("first_order", {"time_s"}, 1.0, time_s.minCoeff())}, {{"amplitude", "um", 1.0}});
  for (int k = 0; k < 12; ++k) c.search.push_back(span * std::pow(40.0, k / 11.0) / 20.0);  // span/20 .. 2 span
  c.shapes.front().searched = c.search.front();
  c.independent_tries = 4.0;
  c.searched_name = "time_constant";
  c.searched_unit = "s";
  return c;
}

Candidate linearDrift() {
  return candidate("thermal_drift", "time_s", "the machine drifts steadily with time (warm-up or room temperature)",
                   {shape("linear", {"time_s"}, 1.0 / 3600.0)}, {{"drift_rate", "um/h", 1.0}});
}

double mean(const Eigen::VectorXd& v) { return v.size() ? v.mean() : 0.0; }

bool varies(const DiagnosisData& d, const std::string& name) {
  const auto* v = d.variable(name);
  return v && v->values.size() && v->values.allFinite() && v->values.maxCoeff() - v->values.minCoeff() > 1e-12;
}

Eigen::VectorXi foldsByBlocks(const Eigen::VectorXd& order_by, int blocks) {
  const Eigen::Index n = order_by.size();
  std::vector<Eigen::Index> idx(static_cast<std::size_t>(n));
  std::iota(idx.begin(), idx.end(), Eigen::Index{0});
  std::stable_sort(idx.begin(), idx.end(), [&](auto a, auto b) { return order_by(a) < order_by(b); });
  Eigen::VectorXi fold(n);
  for (Eigen::Index k = 0; k < n; ++k) fold(idx[static_cast<std::size_t>(k)]) = static_cast<int>(k * blocks / n);
  return fold;
}

/// Channels become variables; one with a missing value is left out (noted), never filled.
void addChannels(DiagnosisData& d, const std::vector<DiagnosisVariable>& channels, std::size_t n, const char* what) {
  for (const auto& c : channels) {
    if (c.values.size() != static_cast<Eigen::Index>(n)) {
      throw InputError(fmt::format("{}: {} {} has {} values for {} points", d.source, what, c.name, c.values.size(), n));
    }
    if (!c.values.allFinite()) {
      d.notes.push_back(fmt::format("{} {} has missing values: not used", what, c.name));
      continue;
    }
    d.variables.push_back(c);
  }
}

void checkSizes(std::size_t n, std::initializer_list<std::size_t> sizes, const std::string& what) {
  for (auto s : sizes) {
    if (s != n) throw InputError(fmt::format("{}: columns of different lengths ({} and {})", what, n, s));
  }
  if (n < 8) throw InputError(fmt::format("{}: {} points; a diagnosis needs 8 or more", what, n));
}

}  // namespace

const DiagnosisVariable* DiagnosisData::variable(const std::string& name) const {
  for (const auto& v : variables) {
    if (v.name == name) return &v;
  }
  return nullptr;
}

nlohmann::json ExtensionShape::toJson() const {
  nlohmann::json j = {{"kind", kind}, {"variables", variables}, {"reference", reference}, {"searched", searched}, {"scale", scale}};
  if (spans > 0) {
    j["spans"] = spans;
    j["range"] = {range.first, range.second};
  }
  return j;
}

ExtensionShape ExtensionShape::fromJson(const nlohmann::json& j) {
  try {
    ExtensionShape s;
    s.kind = j.at("kind").get<std::string>();
    s.variables = j.at("variables").get<std::vector<std::string>>();
    s.reference = j.value("reference", 0.0);
    s.searched = j.value("searched", 0.0);
    s.scale = j.value("scale", 1.0);
    s.spans = j.value("spans", 0);
    if (j.contains("range")) s.range = {j.at("range").at(0).get<double>(), j.at("range").at(1).get<double>()};
    return s;
  } catch (const nlohmann::json::exception& e) {
    throw InputError(std::string("model extension shape: ") + e.what());
  }
}

Eigen::MatrixXd extensionColumns(const std::vector<ExtensionShape>& shapes, const DiagnosisData& data) {
  const Eigen::Index n = data.measured.size();
  std::vector<Eigen::VectorXd> cols;
  for (const auto& s : shapes) {
    std::vector<const Eigen::VectorXd*> v;
    for (const auto& name : s.variables) {
      const auto* var = data.variable(name);
      if (!var) throw InputError(fmt::format("{}: the extension '{}' needs the variable {}, which the data lack", data.source, s.kind, name));
      v.push_back(&var->values);
    }
    auto need = [&](std::size_t count) {
      if (v.size() < count) throw InputError(fmt::format("extension '{}' needs {} variables", s.kind, count));
    };
    // "kind*variable": the kind's columns times that variable; the reversal kinds are times
    // the direction.
    std::string kind = s.kind, multiplier;
    if (const auto star = kind.find('*'); star != std::string::npos) {
      multiplier = kind.substr(star + 1);
      kind = kind.substr(0, star);
    }
    if (kind == "sign_sin_cos" || kind == "sign_cos_sin") multiplier = "direction";
    std::vector<Eigen::VectorXd> out;
    const Eigen::ArrayXd phase = (kind == "sin" || kind == "cos" || kind == "harmonic") && s.searched > 0.0
                                     ? Eigen::ArrayXd(kTwoPi * v.at(0)->array() / s.searched)
                                     : Eigen::ArrayXd();
    if (kind == "linear") {
      need(1);
      out.push_back((v[0]->array() - s.reference).matrix());
    } else if (kind == "product") {
      need(2);
      out.push_back((v[0]->array() * (v[1]->array() - s.reference)).matrix());
    } else if (kind == "first_order") {
      need(1);
      if (!(s.searched > 0.0)) throw InputError("first-order extension without a time constant");
      out.push_back((1.0 - (-(v[0]->array() - s.reference).max(0.0) / s.searched).exp()).matrix());
    } else if (kind == "sin" || kind == "cos" || kind == "harmonic") {
      need(1);
      if (!(s.searched > 0.0)) throw InputError(fmt::format("extension '{}' without a period", s.kind));
      if (kind != "cos") out.push_back(phase.sin().matrix());
      if (kind != "sin") out.push_back(phase.cos().matrix());
    } else if (kind == "constant") {
      out.push_back(Eigen::VectorXd::Ones(n));
    } else if (kind == "sign_sin_cos" || kind == "sign_cos_sin") {
      need(1);
      const Eigen::ArrayXd a = v[0]->array() * std::numbers::pi / 180.0;
      const Eigen::ArrayXd first = kind == "sign_sin_cos" ? Eigen::ArrayXd(a.sin()) : Eigen::ArrayXd(a.cos());
      const Eigen::ArrayXd second = kind == "sign_sin_cos" ? Eigen::ArrayXd(a.cos()) : Eigen::ArrayXd(a.sin());
      out.push_back((first.sign() * second).matrix());
    } else if (kind == "spline" || kind == "step_difference") {
      need(kind == "spline" ? 1 : 2);
      const auto spline = basisSpline(s.range, std::max(1, s.spans));
      const Eigen::Index m = spline.coefficients().size();
      Eigen::MatrixXd b(n, m);
      for (Eigen::Index i = 0; i < n; ++i) {
        const double x0 = std::clamp((*v[0])(i), s.range.first, s.range.second);
        b.row(i) = spline.basis(x0).transpose();
        if (kind == "step_difference") b.row(i) = spline.basis(std::clamp((*v[1])(i), s.range.first, s.range.second)).transpose() - b.row(i);
      }
      // A spline's constant is the baseline's; a difference of one has none: the first
      // coefficient is left out (held at 0) in both. A yaw growing at a constant rate reads
      // as a constant on probe 3, which the probes' zeros are too: the differences are taken
      // about their mean, so that constant is the zeros' (probe_offset).
      for (Eigen::Index j = kind == "spline" ? 0 : 1; j < (kind == "spline" ? m - 1 : m); ++j) {
        out.push_back(kind == "spline" ? Eigen::VectorXd(b.col(j)) : Eigen::VectorXd(b.col(j).array() - b.col(j).mean()));
      }
    } else {
      throw InputError(fmt::format("unknown extension shape '{}'", s.kind));
    }
    const auto* factor = multiplier.empty() ? nullptr : data.variable(multiplier);
    if (!multiplier.empty() && !factor) {
      throw InputError(fmt::format("{}: extension '{}' needs the variable {}, which the data lack", data.source, s.kind, multiplier));
    }
    for (auto& c : out) {
      if (factor) c = c.cwiseProduct(factor->values);
      cols.push_back(c * s.scale);
    }
  }
  Eigen::MatrixXd x(n, static_cast<Eigen::Index>(cols.size()));
  for (std::size_t j = 0; j < cols.size(); ++j) x.col(static_cast<Eigen::Index>(j)) = cols[j];
  if (!x.allFinite()) throw InputError(fmt::format("{}: an extension's variable has unknown values", data.source));
  return x;
}

Diagnosis diagnose(const DiagnosisData& data, const DiagnosisOptions& options) {
  const Eigen::Index n = data.measured.size();
  if (data.simulated.size() != n || data.baseline.rows() != n || data.fold.size() != n) {
    throw InputError(fmt::format("{}: {} measured values but {} predictions, {} baseline rows, {} folds", data.source, n,
                                 data.simulated.size(), data.baseline.rows(), data.fold.size()));
  }
  for (const auto& v : data.variables) {
    if (v.values.size() != n) throw InputError(fmt::format("{}: variable {} has {} values for {} points", data.source, v.name, v.values.size(), n));
  }
  if (n < 8) throw InputError(fmt::format("{}: {} points; a diagnosis needs 8 or more", data.source, n));
  if (!data.measured.allFinite() || !data.simulated.allFinite()) throw InputError(fmt::format("{}: a measured or predicted value is missing", data.source));

  Diagnosis out;
  out.warnings = data.warnings;
  out.notes = data.notes;
  const Eigen::VectorXd y = data.measured - data.simulated;
  Eigen::MatrixXd design = data.baseline;
  const auto base = leastSquares(design, y);
  out.residual_before = base.residual;
  out.rms_um = rmsOf(base.residual);
  auto held = crossValidate(design, y, data.fold);
  out.heldout_before = held.residual;
  out.heldout_rms_um = held.rms;
  out.heldout_peak_um = held.peak;

  // Evidence of the baseline's residual against every variable.
  Eigen::VectorXi group;
  if (const auto* d = data.variable("direction")) group = (d->values.array() > 0.0).cast<int>();
  for (const auto& v : data.variables) {
    const auto values = distinct(v.values);
    if (values.size() < 3 || !v.values.allFinite() || (base.residual.array() == 0.0).all()) continue;
    const double span = values.back() - values.front();
    const double spacing = medianSpacing(values);
    const bool periodic = values.size() >= 12 && spacing > 0.0;
    out.evidence[v.name] = residualEvidence(base.residual, v.values, v.name == "direction" ? Eigen::VectorXi() : group,
                                            periodic ? 2.0 * spacing : 0.0, periodic ? span / 2.0 : 0.0, periodic ? 200 : 0);
  }

  // Generic candidates: one per variable with enough distinct values.
  std::vector<Candidate> generic;
  for (const auto& v : data.variables) {
    if (v.name == "direction" || !v.values.allFinite() || distinct(v.values).size() < 6) continue;
    // A smooth function of the position alone is what the model's error curve (or the run's
    // own baseline) is: its error there is the model's uncertainty, not an unknown cause.
    if (data.site.size() == v.values.size() && constantWithin(v.values, data.site)) continue;
    generic.push_back(genericCandidate(v));
  }
  const int family = static_cast<int>(data.candidates.size() + generic.size());
  out.candidates_tried = family;

  std::set<std::string> accepted_effects;
  std::set<std::string> explained_variables;
  for (int round = 0; round < options.max_findings; ++round) {
    std::vector<std::pair<Evaluation, HeldOut>> passing;
    const CurrentModel current(design, y);
    for (const auto* pool : std::array<const std::vector<Candidate>*, 2>{&data.candidates, &generic}) {
      for (const auto& c : *pool) {
        if (c.effect != "generic" && accepted_effects.count(c.effect)) continue;
        if (c.effect == "generic" && explained_variables.count(c.variable)) continue;
        auto e = evaluate(c, data, current, y, family);
        Considered record{round + 1, c.effect, c.variable, e.delta_bic, e.p_value, NAN, ""};
        auto reject = [&](std::string why) {
          record.verdict = std::move(why);
          out.considered.push_back(record);
        };
        if (e.added_rank == 0) {
          reject("nothing the model does not already have");
          continue;
        }
        if (!(e.p_value < options.alpha)) {
          reject("not significant");
          continue;
        }
        if (!(e.delta_bic > 0.0)) {
          reject("BIC not lower");
          continue;
        }
        Eigen::MatrixXd with(n, design.cols() + e.columns.cols());
        with << design, e.columns;
        const auto implausible = implausibleParameter(e.candidate, leastSquares(with, y).coefficients.tail(e.columns.cols()));
        if (!implausible.empty()) {
          reject(implausible);
          continue;
        }
        auto h = crossValidate(with, y, data.fold);
        record.heldout_rms_um = h.rms;
        if (!(h.rms < (1.0 - options.min_gain) * held.rms)) {
          reject(fmt::format("held-out gain below {:.0f} %", 100.0 * options.min_gain));
          continue;
        }
        record.verdict = "passes";
        out.considered.push_back(record);
        passing.emplace_back(std::move(e), std::move(h));
      }
      if (!passing.empty()) break;  // a generic finding only when no named cause fits
    }
    if (passing.empty()) break;
    std::sort(passing.begin(), passing.end(), [](const auto& a, const auto& b) { return a.first.delta_bic > b.first.delta_bic; });
    auto& [best, best_held] = passing.front();
    Finding f;
    f.candidate = best.candidate;
    f.delta_bic = best.delta_bic;
    f.p_value = best.p_value;
    f.rms_before_um = held.rms;
    f.peak_before_um = held.peak;
    f.rms_after_um = best_held.rms;
    f.peak_after_um = best_held.peak;
    f.gain = held.rms > 0.0 ? 1.0 - best_held.rms / held.rms : 0.0;
    for (std::size_t k = 1; k < passing.size(); ++k) {
      const auto& other = passing[k].first.candidate;
      if (other.effect != best.candidate.effect && best.delta_bic - passing[k].first.delta_bic < 2.0) {
        f.alternatives.push_back(fmt::format("{} ({})", other.effect, other.variable));
      }
    }
    Eigen::MatrixXd with(n, design.cols() + best.columns.cols());
    with << design, best.columns;
    design = std::move(with);
    held = best_held;
    f.columns_in_design = {design.cols() - best.columns.cols(), best.columns.cols()};
    accepted_effects.insert(f.candidate.effect);
    explained_variables.insert(f.candidate.variable);
    out.findings.push_back(std::move(f));
  }
  const auto final_fit = leastSquares(design, y);
  // Every finding's parameters from the joint fit of all of them (terms found later can share
  // part of an earlier one's signature).
  for (auto& f : out.findings) {
    const auto [first, count] = f.columns_in_design;
    f.coefficients = final_fit.coefficients.segment(first, count);
    const Eigen::VectorXd se = final_fit.standard_error.size() ? Eigen::VectorXd(final_fit.standard_error.segment(first, count))
                                                               : Eigen::VectorXd::Zero(count);
    f.parameters = parametersOf(f.candidate, f.coefficients, se, design.middleCols(first, count), data);
  }
  out.residual_after = final_fit.residual;
  out.heldout_after = held.residual;
  out.final_heldout_rms_um = held.rms;
  out.final_heldout_peak_um = held.peak;
  out.gain = out.heldout_rms_um > 0.0 ? 1.0 - held.rms / out.heldout_rms_um : 0.0;
  return out;
}

nlohmann::json ModelExtension::toJson() const {
  nlohmann::json shapes_json = nlohmann::json::array();
  for (const auto& s : shapes) shapes_json.push_back(s.toJson());
  nlohmann::json params = nlohmann::json::object();
  for (const auto& p : parameters) params[p.name] = {{"value", p.value}, {"unit", p.unit}, {"standard_error", p.standard_error}};
  return {{"effect", effect}, {"cause", cause}, {"variable", variable}, {"shapes", shapes_json}, {"coefficients", coefficients}, {"parameters", params}};
}

ModelExtension ModelExtension::fromJson(const nlohmann::json& j) {
  try {
    ModelExtension e;
    e.effect = j.at("effect").get<std::string>();
    e.cause = j.value("cause", "");
    e.variable = j.value("variable", "");
    for (const auto& s : j.at("shapes")) e.shapes.push_back(ExtensionShape::fromJson(s));
    e.coefficients = j.at("coefficients").get<std::vector<double>>();
    const nlohmann::json params = j.contains("parameters") ? j.at("parameters") : nlohmann::json::object();
    for (const auto& [name, p] : params.items()) {
      e.parameters.push_back({name, p.value("unit", ""), p.value("value", 0.0), p.value("standard_error", 0.0)});
    }
    return e;
  } catch (const nlohmann::json::exception& ex) {
    throw InputError(std::string("model extension: ") + ex.what());
  }
}

ModelExtension extensionOf(const Finding& f) {
  return {f.candidate.effect, f.candidate.cause, f.candidate.variable, f.candidate.shapes,
          std::vector<double>(f.coefficients.data(), f.coefficients.data() + f.coefficients.size()), f.parameters};
}

Eigen::VectorXd extensionValues(const std::vector<ModelExtension>& extensions, const DiagnosisData& data) {
  Eigen::VectorXd sum = Eigen::VectorXd::Zero(data.measured.size());
  for (const auto& e : extensions) {
    const Eigen::MatrixXd cols = extensionColumns(e.shapes, data);
    if (static_cast<std::size_t>(cols.cols()) != e.coefficients.size()) {
      throw InputError(fmt::format("model extension {}: {} coefficients for {} columns", e.effect, e.coefficients.size(), cols.cols()));
    }
    sum += cols * vec(e.coefficients);
  }
  return sum;
}

AppliedExtensions applyExtensions(const std::vector<ModelExtension>& extensions, const DiagnosisData& data) {
  AppliedExtensions a;
  a.values = Eigen::VectorXd::Zero(data.measured.size());
  for (const auto& e : extensions) {
    try {
      a.values += extensionValues({e}, data);
      a.applied.push_back(e.effect);
    } catch (const InputError& ex) {
      a.left_out.push_back(e.effect);
      a.why.push_back(ex.what());
    }
  }
  return a;
}

Validation validateExtensions(const std::vector<ModelExtension>& extensions, const DiagnosisData& other) {
  Validation v;
  v.source = other.source;
  v.points = other.measured.size();
  const Eigen::VectorXd y = other.measured - other.simulated;
  const auto added = applyExtensions(extensions, other);
  v.applied = added.applied;
  v.left_out = added.left_out;
  const auto before = leastSquares(other.baseline, y), after = leastSquares(other.baseline, y - added.values);
  v.rms_before_um = rmsOf(before.residual);
  v.rms_after_um = rmsOf(after.residual);
  v.peak_before_um = before.residual.cwiseAbs().maxCoeff();
  v.peak_after_um = after.residual.cwiseAbs().maxCoeff();
  v.gain = v.rms_before_um > 0.0 ? 1.0 - v.rms_after_um / v.rms_before_um : 0.0;
  return v;
}

std::vector<double> aliasedPeriods(const std::vector<double>& positions_mm, double shortest_mm) {
  Eigen::VectorXd p = vec(positions_mm);
  const auto sites = distinct(p);
  if (sites.size() < 3) return {};
  double spacing = std::numeric_limits<double>::infinity();
  for (std::size_t i = 1; i < sites.size(); ++i) spacing = std::min(spacing, sites[i] - sites[i - 1]);
  for (double s : sites) {
    const double k = (s - sites.front()) / spacing;
    if (std::abs(k - std::round(k)) > 1e-6) return {};
  }
  std::vector<double> periods;
  for (int k = 1; spacing / k >= shortest_mm - 1e-12; ++k) periods.push_back(spacing / k);
  return periods;
}

// ---- linear runs ----

DiagnosisData linearDiagnosisData(const LinearRunInput& in) {
  const std::size_t n = in.position_mm.size();
  checkSizes(n, {in.deviation_um.size(), in.direction.size(), in.cycle.size()}, in.source);
  if (!in.time_s.empty() && in.time_s.size() != n) throw InputError(fmt::format("{}: {} times for {} points", in.source, in.time_s.size(), n));
  if (!in.simulated_um.empty() && in.simulated_um.size() != n) throw InputError(fmt::format("{}: {} predictions for {} points", in.source, in.simulated_um.size(), n));
  DiagnosisData d;
  d.kind = "linear";
  d.source = in.source;
  d.main_variable = "position_mm";
  d.measured = vec(in.deviation_um);
  const bool has_model = !in.simulated_um.empty();
  d.simulated = has_model ? vec(in.simulated_um) : Eigen::VectorXd::Zero(static_cast<Eigen::Index>(n));
  d.model_description = has_model ? in.model_description : "none";
  const Eigen::VectorXd x = vec(in.position_mm);
  Eigen::VectorXd dir(static_cast<Eigen::Index>(n)), cyc(dir.size());
  for (std::size_t i = 0; i < n; ++i) {
    if (in.direction[i] != 1 && in.direction[i] != -1) throw InputError(fmt::format("{}: point {}: direction {} (must be +1 or -1)", in.source, i + 1, in.direction[i]));
    dir(static_cast<Eigen::Index>(i)) = in.direction[i];
    cyc(static_cast<Eigen::Index>(i)) = in.cycle[i];
  }
  d.variables = {{"position_mm", "mm", x}, {"direction", "", dir}, {"cycle", "", cyc}};
  if (!in.time_s.empty()) d.variables.push_back({"time_s", "s", vec(in.time_s)});
  addChannels(d, in.channels, n, "channel");
  for (const auto& a : in.model_angles_urad) d.variables.push_back(a);

  // Baseline: the line's zero against a model; without one the run's own error curve,
  // averaged over both directions, knots no closer than min_knot_spacing_mm.
  const auto sites = distinct(x);
  if (has_model) {
    d.baseline = Eigen::MatrixXd::Ones(static_cast<Eigen::Index>(n), 1);
    d.baseline_description = fmt::format("the model ({}) with the line's zero free", in.model_description);
  } else {
    if (sites.size() < 2) throw InputError(fmt::format("{}: every point at one position: no error curve", in.source));
    const int degree = std::min<int>(3, static_cast<int>(sites.size()) - 1);
    const auto knots = errorCurveKnots(sites, degree, in.min_knot_spacing_mm);
    const BSpline spline(degree, knots, Eigen::VectorXd::Zero(static_cast<Eigen::Index>(knots.size()) - degree - 1));
    d.baseline.resize(static_cast<Eigen::Index>(n), spline.coefficients().size());
    for (std::size_t i = 0; i < n; ++i) d.baseline.row(static_cast<Eigen::Index>(i)) = spline.basis(in.position_mm[i]).transpose();
    d.baseline_description = fmt::format(
        "the run's own error curve averaged over both directions: cubic B-spline, {} coefficients for {} positions (knots at least {} mm apart)",
        spline.coefficients().size(), sites.size(), in.min_knot_spacing_mm);
    if (static_cast<std::size_t>(spline.coefficients().size()) >= sites.size()) {
      d.notes.push_back("the baseline passes through the mean of every position: structure between the positions (a cyclic error "
                        "shorter than the spacing) shows only in a run that measures other positions");
    }
  }
  d.site.resize(static_cast<Eigen::Index>(n));
  for (std::size_t i = 0; i < n; ++i) {
    d.site(static_cast<Eigen::Index>(i)) = static_cast<int>(
        std::lower_bound(sites.begin(), sites.end(), in.position_mm[i] - 1e-9) - sites.begin());
  }
  // Folds: the repeats; a single repeat is split into blocks of time (or of the order).
  std::set<int> cycles(in.cycle.begin(), in.cycle.end());
  d.fold.resize(static_cast<Eigen::Index>(n));
  if (cycles.size() >= 2) {
    std::vector<int> order(cycles.begin(), cycles.end());
    for (std::size_t i = 0; i < n; ++i) d.fold(static_cast<Eigen::Index>(i)) = static_cast<int>(std::lower_bound(order.begin(), order.end(), in.cycle[i]) - order.begin());
    d.fold_description = fmt::format("by repeat: each of the {} cycles left out in turn", cycles.size());
  } else {
    Eigen::VectorXd order = in.time_s.empty() ? Eigen::VectorXd::LinSpaced(static_cast<Eigen::Index>(n), 0, static_cast<double>(n - 1)) : vec(in.time_s);
    d.fold = foldsByBlocks(order, 4);
    d.fold_description = "one repeat: four contiguous blocks in time order, each left out in turn";
  }
  // On a grid of spacing s only periods from 2 s up are distinct: shorter ones read as one of them.
  const auto aliased = aliasedPeriods(in.position_mm);
  if (const auto& periods = aliased; !periods.empty()) {
    std::string list;
    for (std::size_t k = 0; k < std::min<std::size_t>(periods.size(), 4); ++k) list += fmt::format("{}{:.4g}", k ? ", " : "", periods[k]);
    d.warnings.push_back(fmt::format(
        "every target is on a {:.4g} mm grid: a cyclic error of period {} mm (or any {:.4g} mm / k) reads the same at every target "
        "and cannot be seen, and any other period reads as its alias longer than {:.4g} mm; measure a plan with random target "
        "offsets or a finer validation run (e.g. every ~3 mm)",
        periods.front(), list, periods.front(), 2.0 * periods.front()));
  }

  // Candidate causes.
  const double mid = 0.5 * (x.minCoeff() + x.maxCoeff());
  const double length = std::max(1e-9, x.maxCoeff() - x.minCoeff());
  d.candidates.push_back(candidate("backlash", "direction", "reversal error: lost motion of the drive between the two approach directions",
                                   {shape("linear", {"direction"}, 0.5)}, {{"reversal", "um", 1.0}}));
  d.candidates.push_back(candidate("backlash", "direction",
                                   "reversal error that changes along the travel (wear or a pitch of the screw varying with load)",
                                   {shape("linear", {"direction"}, 0.5), shape("product", {"direction", "position_mm"}, 0.5 / length, mid)},
                                   {{"reversal", "um", 1.0}, {"reversal_change_over_travel", "um", 1.0}}));
  if (varies(d, "time_s")) {
    const auto& t = d.variable("time_s")->values;
    d.candidates.push_back(linearDrift());
    d.candidates.push_back(firstOrderDrift(t));
    d.candidates.push_back(candidate("thermal_drift", "time_s", "thermal growth of the axis with time: an error proportional to position and time",
                                     {shape("product", {"position_mm", "time_s"}, 1e-3 / 3600.0)}, {{"growth_rate", "ppm/h", 1.0}}));
  }
  // Cyclic error: periods between 2 mm and twice the knot spacing (longer ones the baseline
  // follows), searched evenly in frequency, three times finer than the run's span resolves.
  {
    // Longer periods are within what an error curve with knots this far apart represents:
    // a model's own identification error looks like them.
    const double longest = 2.0 * in.min_knot_spacing_mm;
    const double shortest = aliased.empty() ? 2.0 : 2.0 * aliased.front();
    if (longest > shortest) {
      auto c = candidate("cyclic_error", "position_mm", "periodic error of the drive (screw lead, encoder or scale interpolation)",
                         {shape("harmonic", {"position_mm"})}, {{"sin", "um", 1.0}, {"cos", "um", 1.0}});
      if (!aliased.empty()) {
        c.cause += fmt::format(" (on the {:.4g} mm grid the period found may stand for any p with 1/p = 1/period + k/{:.4g} mm)",
                               aliased.front(), aliased.front());
      }
      const double df = 1.0 / (3.0 * length);
      for (double f = 1.0 / longest; f <= 1.0 / shortest; f += df) c.search.push_back(1.0 / f);
      c.independent_tries = std::max(1.0, c.search.size() / 3.0);
      c.shapes.front().searched = c.search.front();
      c.searched_name = "period";
      c.searched_unit = "mm";
      d.candidates.push_back(c);
    }
  }
  for (const auto& a : in.model_angles_urad) {
    if (!varies(d, a.name)) continue;
    d.candidates.push_back(candidate("abbe_error", a.name,
                                     fmt::format("Abbe error: the optics sit off the line the model assumes, so the angular error {} adds "
                                                 "offset x angle",
                                                 a.name),
                                     {shape("linear", {a.name}, 1e-3)}, {{"offset", "mm", 1.0, kMaxAbbeOffsetMm}}));
  }
  if (has_model) {
    d.candidates.push_back(candidate("scale_error", "position_mm",
                                     "error proportional to position: scale (linear expansion, encoder pitch) or cosine misalignment of the optics",
                                     {shape("linear", {"position_mm"}, 1e-3, x.minCoeff())}, {{"scale", "ppm", 1.0}}));
  }
  for (const auto& [name, unit, per, parameter] : {std::tuple{"air_temp_c", "ppm/K", 1.0, "air_temp_coefficient"},
                                                   std::tuple{"air_pressure_pa", "ppm/hPa", 100.0, "air_pressure_coefficient"}}) {
    if (!varies(d, name)) continue;
    const double ref = mean(d.variable(name)->values);
    d.candidates.push_back(candidate("environment_compensation", name,
                                     fmt::format("wrong environmental compensation: an error proportional to position and to the change of {}", name),
                                     {shape("product", {"position_mm", name}, 1e-3 / per, ref)}, {{parameter, unit, 1.0}}));
  }
  if (varies(d, "air_temp_c")) {
    d.candidates.push_back(candidate("environment_compensation", "air_temp_c",
                                     "dead path: the beam between the interferometer and the datum is not compensated for the air's change",
                                     {shape("linear", {"air_temp_c"}, kDeadPathUmPerMmK, mean(d.variable("air_temp_c")->values))},
                                     {{"dead_path", "mm", 1.0, kMaxDeadPathMm}}));
  }
  if (varies(d, "material_temp_c")) {
    d.candidates.push_back(candidate("thermal_drift", "material_temp_c",
                                     "thermal growth of the axis with the machine's temperature (expansion not, or wrongly, compensated)",
                                     {shape("product", {"position_mm", "material_temp_c"}, 1e-3, mean(d.variable("material_temp_c")->values))},
                                     {{"expansion_error", "ppm/K", 1.0}}));
  }
  return d;
}

// ---- circular tests ----

DiagnosisData circleDiagnosisData(const CircleRunInput& in) {
  const std::size_t n = in.angle_deg.size();
  checkSizes(n, {in.deviation_um.size(), in.direction.size()}, in.source);
  if (!(in.radius_mm > 0.0) || !(in.feed_mm_per_min > 0.0)) throw InputError(fmt::format("{}: radius and feed must be positive", in.source));
  DiagnosisData d;
  d.kind = "circle";
  d.source = in.source;
  d.main_variable = "angle_deg";
  d.measured = vec(in.deviation_um);
  d.simulated = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(n));
  d.model_description = "a perfect circle";
  Eigen::VectorXd dir(static_cast<Eigen::Index>(n));
  for (std::size_t i = 0; i < n; ++i) dir(static_cast<Eigen::Index>(i)) = in.direction[i] >= 0 ? 1.0 : -1.0;
  d.variables = {{"angle_deg", "deg", vec(in.angle_deg)}, {"direction", "", dir}};
  if (!in.time_s.empty()) {
    if (in.time_s.size() != n) throw InputError(fmt::format("{}: {} times for {} points", in.source, in.time_s.size(), n));
    d.variables.push_back({"time_s", "s", vec(in.time_s)});
  }
  d.baseline = Eigen::MatrixXd::Ones(static_cast<Eigen::Index>(n), 1);
  d.baseline_description = "the nominal circle with the bar's length free";
  Eigen::VectorXd wrapped = vec(in.angle_deg);
  for (auto& a : wrapped) a = std::fmod(std::fmod(a, 360.0) + 360.0, 360.0);
  d.fold = foldsByBlocks(wrapped, 8);
  d.fold_description = "eight 45 deg sectors (both directions), each left out in turn";
  const double r = in.radius_mm;
  const double v_mm_s = in.feed_mm_per_min / 60.0;
  d.candidates.push_back(candidate("eccentricity", "angle_deg", "the circle's centre is off the bar's pivot (set-up, or the tailstock/centre eccentricity m, n)",
                                   {shape("cos", {"angle_deg"}, 1.0, 0.0, 360.0), shape("sin", {"angle_deg"}, 1.0, 0.0, 360.0)},
                                   {{"m", "um", 1.0}, {"n", "um", 1.0}}));
  d.candidates.push_back(candidate("squareness", "angle_deg", "the two axes are out of square: the circle is an ellipse at 45 deg",
                                   {shape("sin", {"angle_deg"}, 1.0, 0.0, 180.0)}, {{"squareness", "urad", 2000.0 / r}}));
  d.candidates.push_back(candidate("scale_error", "angle_deg", "the two axes' scales differ: the circle is an ellipse along an axis",
                                   {shape("cos", {"angle_deg"}, 1.0, 0.0, 180.0)}, {{"scale_mismatch", "ppm", 2000.0 / r}}));
  d.candidates.push_back(candidate("backlash", "angle_deg", "reversal steps where an axis changes direction (lost motion)",
                                   {shape("sign_sin_cos", {"angle_deg"}), shape("sign_cos_sin", {"angle_deg"})},
                                   {{"reversal_x", "um", 2.0}, {"reversal_y", "um", -2.0}}));
  d.candidates.push_back(candidate("servo_mismatch", "angle_deg",
                                   "the position loops of the two axes lag differently: an ellipse at 45 deg that turns with the direction",
                                   {shape("sin*direction", {"angle_deg"}, 1.0, 0.0, 180.0)}, {{"lag_difference", "ms", 2.0 / v_mm_s}}));
  if (varies(d, "time_s")) d.candidates.push_back(linearDrift());
  return d;
}

// ---- thermal series ----

DiagnosisData thermalDiagnosisData(const ThermalRunInput& in) {
  const std::size_t n = in.time_s.size();
  checkSizes(n, {in.displacement_um.size()}, in.source);
  DiagnosisData d;
  d.kind = "thermal";
  d.source = in.source;
  d.main_variable = "time_s";
  d.value_name = "displacement";
  d.measured = vec(in.displacement_um);
  d.simulated = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(n));
  d.model_description = "no thermal model (the machine as cold)";
  d.variables = {{"time_s", "s", vec(in.time_s)}};
  addChannels(d, in.temperatures_c, n, "sensor");
  d.baseline = Eigen::MatrixXd::Ones(static_cast<Eigen::Index>(n), 1);
  d.baseline_description = "a constant displacement";
  d.fold = foldsByBlocks(vec(in.time_s), std::max(2, in.folds));
  d.fold_description = fmt::format("{} contiguous blocks of time, each left out in turn", std::max(2, in.folds));
  d.candidates.push_back(linearDrift());
  d.candidates.push_back(firstOrderDrift(d.variables.front().values));
  std::vector<std::string> sensors;
  for (std::size_t k = 1; k < d.variables.size(); ++k) {
    const auto& v = d.variables[k];
    if (!varies(d, v.name)) continue;
    sensors.push_back(v.name);
    d.candidates.push_back(candidate("thermal_drift", v.name, fmt::format("thermal drift following the temperature {}", v.name),
                                     {shape("linear", {v.name}, 1.0, mean(v.values))}, {{"sensitivity", "um/K", 1.0}}));
  }
  // The [6/7] model: the sensors its stepwise search keeps on the first 60 % of the series.
  if (sensors.size() >= 2 && n >= 30) {
    ThermalData td;
    td.sensors = sensors;
    td.time_s = vec(in.time_s);
    td.target_um = d.measured;
    td.temperature_c.resize(static_cast<Eigen::Index>(n), static_cast<Eigen::Index>(sensors.size()));
    for (std::size_t k = 0; k < sensors.size(); ++k) td.temperature_c.col(static_cast<Eigen::Index>(k)) = d.variable(sensors[k])->values;
    try {
      const auto model = fitThermalModel(td, ThermalFitOptions{});
      if (model.chosen.sensors.size() >= 2) {
        std::vector<ExtensionShape> shapes;
        std::vector<Candidate::Parameter> params;
        std::string names;
        for (const auto& s : model.chosen.sensors) {
          shapes.push_back(shape("linear", {s}, 1.0, mean(d.variable(s)->values)));
          params.push_back({s, "um/K", 1.0});
          names += (names.empty() ? "" : ", ") + s;
        }
        d.candidates.push_back(candidate("thermal_drift", names, fmt::format("thermal drift following the temperatures {} (the [6/7] stepwise model)", names), shapes, params));
      }
    } catch (const InputError& e) {
      d.notes.push_back(std::string("the [6/7] thermal model could not be fitted: ") + e.what());
    }
  }
  return d;
}

// ---- error separation ----

DiagnosisData estDiagnosisData(const EstRunInput& in) {
  const std::size_t steps = in.position_mm.size();
  if (in.v1_um.size() != steps || in.v2_um.size() != steps || in.v3_um.size() != steps) {
    throw InputError(fmt::format("{}: three probes needed at every step ({} steps, {} / {} / {} readings)", in.source, steps, in.v1_um.size(),
                                 in.v2_um.size(), in.v3_um.size()));
  }
  if (!(in.spacing_mm > 0.0)) throw InputError(fmt::format("{}: the probe spacing must be positive", in.source));
  for (std::size_t k = 1; k < steps; ++k) {
    if (std::abs(in.position_mm[k] - in.position_mm[k - 1] - in.spacing_mm) > 1e-6) {
      throw InputError(fmt::format("{}: step {} moves {} mm; the two-probe prediction needs steps of the probe spacing {} mm", in.source, k,
                                   in.position_mm[k] - in.position_mm[k - 1], in.spacing_mm));
    }
  }
  if (steps < 9) throw InputError(fmt::format("{}: {} steps; a diagnosis needs 9 or more", in.source, steps));
  const std::size_t n = steps - 1;
  const double d_mm = in.spacing_mm;
  // Two-probe profile: m(x_{k+1}) - m(x_k) = v2_k - v1_k; probe 3 reads m(x_k + 2d) - e_k.
  std::vector<double> profile(steps + 1, 0.0);
  for (std::size_t k = 0; k < steps; ++k) profile[k + 1] = profile[k] + in.v2_um[k] - in.v1_um[k];
  DiagnosisData data;
  data.kind = "est";
  data.source = in.source;
  data.main_variable = "position_mm";
  data.value_name = "probe 3 reading";
  data.measured.resize(static_cast<Eigen::Index>(n));
  data.simulated.resize(data.measured.size());
  Eigen::VectorXd x(data.measured.size()), next(x.size()), slope(x.size()), step(x.size());
  for (std::size_t k = 0; k < n; ++k) {
    const auto i = static_cast<Eigen::Index>(k);
    data.measured(i) = in.v3_um[k];
    data.simulated(i) = (in.v2_um[k] - in.v1_um[k]) + (in.v2_um[k + 1] - in.v1_um[k + 1]) + in.v1_um[k];
    x(i) = in.position_mm[k];
    next(i) = in.position_mm[k + 1];
    step(i) = static_cast<double>(k);
    // Slope of the profile at probe 3 (x_k + 2d), by the central difference.
    const std::size_t c = std::min(k + 2, steps);
    slope(i) = (profile[std::min(c + 1, steps)] - profile[c - 1]) / ((std::min(c + 1, steps) - (c - 1)) * d_mm);
  }
  data.model_description = "the two-probe separation of probes 1 and 2 (no carriage yaw, exact probe zeros and spacing)";
  data.variables = {{"position_mm", "mm", x}, {"step", "", step}, {"next_position_mm", "mm", next}, {"profile_slope", "um/mm", slope}};
  data.baseline = Eigen::MatrixXd(static_cast<Eigen::Index>(n), 0);
  data.baseline_description = "nothing free: the prediction of probe 3 is fixed by probes 1 and 2";
  // Interleaved folds: the extensions are local along the guideway (the yaw's spline), so a
  // block of steps left out would be extrapolated; every step's residual is independent of
  // its neighbours' (the carriage's motion cancels in the prediction).
  data.fold.resize(static_cast<Eigen::Index>(n));
  for (std::size_t k = 0; k < n; ++k) data.fold(static_cast<Eigen::Index>(k)) = static_cast<int>(k % 4);
  data.fold_description = "every fourth step (four interleaved sets), each set left out in turn";
  data.candidates.push_back(candidate("probe_offset", "step", "the probes' zeros are not equal: a constant c1 - 2 c2 + c3 on probe 3's prediction",
                                      {shape("constant", {})}, {{"zero_combination", "um", 1.0}}));
  data.candidates.push_back(candidate("scale_error", "profile_slope", "probe spacing error: probe 3 is not at twice the spacing, so its reading carries the profile's slope",
                                      {shape("linear", {"profile_slope"})}, {{"spacing_error", "mm", 1.0}}));
  auto yaw = candidate("carriage_yaw", "position_mm",
                       "the carriage turns (yaws) as it moves, which the two-probe method takes for straightness: probe 3 sees d times "
                       "the change of yaw per step",
                       {shape("step_difference", {"position_mm", "next_position_mm"}, d_mm * 1e-3)}, {});
  yaw.shapes.front().spans = std::clamp(static_cast<int>(n) / 5, 1, 12);
  yaw.shapes.front().range = {x.minCoeff(), next.maxCoeff()};
  data.candidates.push_back(yaw);
  return data;
}

// ---- laser tracker (gantry test) ----

namespace {

Eigen::Matrix3d skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return m;
}

/// The sweep's axial deviations (um) and angles (deg, from its first point) about its circle.
void sweepAxial(const std::vector<Eigen::Vector3d>& sweep, const char* what, std::vector<double>& axial_um, std::vector<double>& angle_deg) {
  const auto circle = fitCircle3d(sweep, what);
  Eigen::Vector3d e1 = sweep.front() - circle.centre;
  e1 -= e1.dot(circle.normal) * circle.normal;
  e1.normalize();
  const Eigen::Vector3d e2 = circle.normal.cross(e1);
  double previous = 0.0, turns = 0.0;
  for (std::size_t k = 0; k < sweep.size(); ++k) {
    const Eigen::Vector3d d = sweep[k] - circle.centre;
    axial_um.push_back(1000.0 * d.dot(circle.normal));
    double a = std::atan2(d.dot(e2), d.dot(e1)) * 180.0 / std::numbers::pi + turns;
    if (k > 0 && a < previous - 180.0) {
      turns += 360.0;
      a += 360.0;
    }
    previous = a;
    angle_deg.push_back(a);
  }
}

}  // namespace

DiagnosisData trackerDiagnosisData(const TrackerRunInput& in) {
  const std::size_t targets = in.initial_targets.size();
  if (targets < 3) throw InputError(fmt::format("{}: {} targets in the initial state; the rigid fit needs 3 or more", in.source, targets));
  std::vector<double> y, los, hole_of, sweep_c, sweep_a, angle_c, angle_a;
  int absorbed = 0;
  // Targets: the head's target pattern and its rigid motion into every set (the initial state
  // and each hole) by generalised Procrustes (the pattern the mean of all sets brought back,
  // so no one set's noise is taken as the truth); what is left in each set is projected off
  // its motion's (linearised) directions. The line-of-sight change of each target is treated
  // the same way: u_ik - R_k mean_k(R_k^T u_ik).
  std::vector<std::vector<Eigen::Vector3d>> sets{in.initial_targets};
  for (std::size_t j = 0; j < in.hole_targets.size(); ++j) {
    if (in.hole_targets[j].size() != targets) {
      throw InputError(fmt::format("{}: hole {} has {} targets, the initial state {}", in.source, j + 1, in.hole_targets[j].size(), targets));
    }
    sets.push_back(in.hole_targets[j]);
  }
  std::vector<Eigen::Vector3d> pattern = in.initial_targets;
  std::vector<Eigen::Isometry3d> motion(sets.size());
  for (int iteration = 0; iteration < 10; ++iteration) {
    std::vector<Eigen::Vector3d> mean(targets, Eigen::Vector3d::Zero());
    for (std::size_t k = 0; k < sets.size(); ++k) {
      motion[k] = rigidFit(pattern, sets[k]).transform;
      for (std::size_t i = 0; i < targets; ++i) mean[i] += motion[k].inverse() * sets[k][i] / static_cast<double>(sets.size());
    }
    pattern = mean;
  }
  std::vector<Eigen::Vector3d> mean_sight(targets, Eigen::Vector3d::Zero());
  for (std::size_t k = 0; k < sets.size(); ++k) {
    for (std::size_t i = 0; i < targets; ++i) mean_sight[i] += motion[k].linear().transpose() * sets[k][i].normalized() / static_cast<double>(sets.size());
  }
  if (!in.hole_targets.empty()) {
    for (std::size_t k = 0; k < sets.size(); ++k) {
      const auto rows = static_cast<Eigen::Index>(3 * targets);
      Eigen::MatrixXd jacobian(rows, 6);
      Eigen::VectorXd residual(rows), sight(rows);
      Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
      for (const auto& p : sets[k]) centroid += p / static_cast<double>(targets);
      for (std::size_t i = 0; i < targets; ++i) {
        const auto row = static_cast<Eigen::Index>(3 * i);
        const Eigen::Vector3d fitted = motion[k] * pattern[i];
        jacobian.block(row, 0, 3, 3) = Eigen::Matrix3d::Identity();
        jacobian.block(row, 3, 3, 3) = -skew(fitted - centroid) * 1000.0;
        residual.segment(row, 3) = 1000.0 * (sets[k][i] - fitted);
        sight.segment(row, 3) = sets[k][i].normalized() - motion[k].linear() * mean_sight[i];
      }
      const Eigen::MatrixXd q = jacobian.householderQr().householderQ() * Eigen::MatrixXd::Identity(rows, 6);
      residual -= q * (q.transpose() * residual);
      sight -= q * (q.transpose() * sight);
      for (Eigen::Index r = 0; r < rows; ++r) {
        y.push_back(residual(r));
        los.push_back(sight(r));
        hole_of.push_back(static_cast<double>(k));
        sweep_c.push_back(0.0);
        sweep_a.push_back(0.0);
        angle_c.push_back(0.0);
        angle_a.push_back(0.0);
      }
    }
    absorbed += static_cast<int>(6 * sets.size() + 3 * targets) - 6;  // motions and the pattern, less the common gauge
  }
  // Sweeps: the axial deviation from each circle's plane (the plane's 3 parameters fitted).
  std::vector<std::string> notes;
  for (const auto* sweep : {&in.c_sweep, &in.a_sweep}) {
    const bool c = sweep == &in.c_sweep;
    if (sweep->size() < 12) {
      if (!sweep->empty()) notes.push_back(fmt::format("the {} sweep has {} points: a wobble needs 12 or more to be tested", c ? "C" : "A", sweep->size()));
      continue;
    }
    std::vector<double> axial, angle;
    sweepAxial(*sweep, c ? "C sweep" : "A sweep", axial, angle);
    for (std::size_t k = 0; k < axial.size(); ++k) {
      y.push_back(axial[k]);
      los.push_back(0.0);
      hole_of.push_back(-1.0);
      sweep_c.push_back(c ? 1.0 : 0.0);
      sweep_a.push_back(c ? 0.0 : 1.0);
      angle_c.push_back(c ? angle[k] : 0.0);
      angle_a.push_back(c ? 0.0 : angle[k]);
    }
    absorbed += 3;
  }
  if (y.size() < 8) throw InputError(fmt::format("{}: {} residuals; a diagnosis needs 8 or more", in.source, y.size()));
  DiagnosisData d;
  d.kind = "tracker";
  d.source = in.source;
  d.value_name = "residual";
  d.main_variable = "hole";
  d.measured = vec(y);
  d.simulated = Eigen::VectorXd::Zero(d.measured.size());
  d.model_description = "rigid motion of the head's targets per hole; a circle per rotary sweep";
  d.baseline = Eigen::MatrixXd(d.measured.size(), 0);
  d.baseline_description = fmt::format("nothing more: {} parameters were fitted to make the residuals", absorbed);
  d.absorbed_dof = absorbed;
  d.notes = notes;
  d.variables = {{"hole", "", vec(hole_of)},
                 {"line_of_sight_change", "", vec(los)},
                 {"c_sweep", "", vec(sweep_c)},
                 {"a_sweep", "", vec(sweep_a)},
                 {"c_angle_deg", "deg", vec(angle_c)},
                 {"a_angle_deg", "deg", vec(angle_a)}};
  // Folds: five groups of holes, and five sectors of each sweep.
  d.fold.resize(d.measured.size());
  const double holes = static_cast<double>(std::max<std::size_t>(1, in.hole_targets.size() + 1));
  for (Eigen::Index i = 0; i < d.measured.size(); ++i) {
    if (hole_of[static_cast<std::size_t>(i)] >= 0.0) {
      d.fold(i) = static_cast<int>(5.0 * hole_of[static_cast<std::size_t>(i)] / holes);
    } else {
      const double a = sweep_c[static_cast<std::size_t>(i)] > 0.0 ? angle_c[static_cast<std::size_t>(i)] : angle_a[static_cast<std::size_t>(i)];
      const double span = sweep_c[static_cast<std::size_t>(i)] > 0.0 ? std::max(1e-9, *std::max_element(angle_c.begin(), angle_c.end()))
                                                                      : std::max(1e-9, *std::max_element(angle_a.begin(), angle_a.end()));
      d.fold(i) = std::min(4, static_cast<int>(5.0 * a / (span + 1e-9)));
    }
  }
  d.fold_description = "five groups of holes and five sectors of each sweep, each left out in turn";
  if (!in.hole_targets.empty()) {
    d.candidates.push_back(candidate("target_offset", "line_of_sight_change",
                                     "the reflector's optical centre is off its sphere's centre (SMR centring): every point reads shifted "
                                     "along the beam, which the targets' rigid motion cannot follow as the head turns",
                                     {shape("linear", {"line_of_sight_change"})}, {{"centring_error", "um", 1.0, 100.0}}));
  }
  for (const auto& [axis, name] : {std::pair{"C", "c"}, std::pair{"A", "a"}}) {
    const std::string sweep = std::string(name) + "_sweep", angle = std::string(name) + "_angle_deg";
    if (!varies(d, sweep)) continue;
    d.candidates.push_back(candidate("wobble", angle,
                                     fmt::format("the {} axis wobbles: its tilt changes twice per turn, moving the target out of the "
                                                 "circle's plane",
                                                 axis),
                                     {shape(std::string("harmonic*") + sweep, {angle}, 1.0, 0.0, 180.0)}, {{"sin", "um", 1.0}, {"cos", "um", 1.0}}));
  }
  return d;
}

}  // namespace mtcal::processing
