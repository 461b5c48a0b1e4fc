#include "mtcal/processing/error_model.h"

#include <algorithm>
#include <boost/math/distributions/students_t.hpp>
#include <cassert>
#include <cmath>
#include <functional>
#include <limits>
#include <nlohmann/json.hpp>
#include <numeric>

#include "json_number.h"
#include "mtcal/error.h"

namespace mtcal::processing {

namespace {

/// A curve's weights: 1 / s^2 of each node, s floored at 1 % of the pooled s (`pooled`, 0: none)
/// and at 1e-6: a node measured without scatter (identical repeats give s = 0) would get an
/// infinite weight.
Eigen::VectorXd fitWeights(const std::vector<double>& s, double pooled) {
  const double floor = std::max(0.01 * pooled, 1e-6);
  Eigen::VectorXd w(static_cast<Eigen::Index>(s.size()));
  for (std::size_t k = 0; k < s.size(); ++k) w(static_cast<Eigen::Index>(k)) = 1.0 / std::pow(std::max(s[k], floor), 2);
  return w;
}

/// The scatter pooled over the nodes that have one, sqrt(sum (r - 1) s^2 / sum (r - 1)), and its
/// degrees of freedom (0: none, and the scatter 0).
struct PooledScatter {
  double s = 0.0;
  std::int64_t dof = 0;
};
PooledScatter pooledScatter(const std::vector<std::optional<double>>& s, const std::vector<int>& repeats) {
  double sum_of_squares = 0.0;
  PooledScatter out;
  for (std::size_t i = 0; i < s.size(); ++i) {
    if (!s[i]) continue;
    sum_of_squares += (repeats[i] - 1) * *s[i] * *s[i];
    out.dof += repeats[i] - 1;
  }
  if (out.dof > 0) out.s = std::sqrt(sum_of_squares / static_cast<double>(out.dof));
  return out;
}

/// A curve's nodes' repeats where every node has one reading or more; else none (not known).
std::vector<int> knownRepeats(std::vector<int> repeats) {
  if (std::any_of(repeats.begin(), repeats.end(), [](int r) { return r < 1; })) return {};
  return repeats;
}

}  // namespace

ErrorFunction::ErrorFunction(std::string name, double value, double sigma)
    : name_(std::move(name)), constant_(value), nodes_{0.0}, node_sigmas_{sigma} {}

ErrorFunction::ErrorFunction(std::string name, std::optional<BSpline> spline, double constant_value,
                             std::vector<double> nodes, std::vector<double> node_sigmas, int dof,
                             std::vector<int> node_repeats)
    : name_(std::move(name)),
      spline_(std::move(spline)),
      constant_(constant_value),
      nodes_(std::move(nodes)),
      node_sigmas_(std::move(node_sigmas)),
      dof_(dof),
      node_repeats_(std::move(node_repeats)) {
  if (nodes_.empty() || nodes_.size() != node_sigmas_.size()) {
    throw InputError("error function " + name_ + ": nodes and sigmas must be given, one each");
  }
  if (!node_repeats_.empty() && node_repeats_.size() != nodes_.size())
    throw InputError("error function " + name_ + ": " + std::to_string(node_repeats_.size()) + " node repeats for " +
                     std::to_string(nodes_.size()) + " nodes");
  if (std::any_of(node_repeats_.begin(), node_repeats_.end(), [](int r) { return r < 1; }))
    throw InputError("error function " + name_ + ": a node's repeats must be 1 or more");
}

ErrorFunction ErrorFunction::fit(const ErrorCurveData& data, const ErrorFitOptions& options) {
  const std::size_t n = data.mean.size();
  if (n == 0 || data.s.size() != n || data.repeats.size() != n ||
      (!data.position_mm.empty() && data.position_mm.size() != n)) {
    throw InputError("error " + data.name + ": inconsistent node data");
  }
  const auto [pooled, pooled_dof] = pooledScatter(data.s, data.repeats);
  if (pooled_dof > 1'000'000'000) throw InputError("error " + data.name + ": more than 1e9 repeated readings");
  int dof = static_cast<int>(pooled_dof);
  const bool has_pooled = dof > 0;
  if (data.position_mm.size() <= 1) {
    return ErrorFunction(data.name, std::nullopt, data.mean[0], {data.position_mm.empty() ? 0.0 : data.position_mm[0]},
                         {data.s[0].value_or(pooled)}, dof, knownRepeats({data.repeats[0]}));
  }

  std::vector<std::size_t> order(n);
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](auto a, auto b) { return data.position_mm[a] < data.position_mm[b]; });
  Eigen::VectorXd x(static_cast<Eigen::Index>(n)), y(x.size());
  std::vector<double> nodes, sigmas;
  std::vector<int> repeats;
  for (std::size_t k = 0; k < n; ++k) {
    const std::size_t i = order[k];
    x(static_cast<Eigen::Index>(k)) = data.position_mm[i];
    y(static_cast<Eigen::Index>(k)) = data.mean[i];
    nodes.push_back(data.position_mm[i]);
    sigmas.push_back(data.s[i].value_or(has_pooled ? pooled : 1.0));
    repeats.push_back(data.repeats[i]);
  }
  const int degree = std::min<int>(options.degree, static_cast<int>(n) - 1);
  BSpline spline = BSpline::fit(degree, errorCurveKnots(nodes, degree, options.min_knot_spacing_mm), x, y,
                                fitWeights(sigmas, pooled));
  if (!has_pooled) {
    // No repeats anywhere: the residual of the fit is the only estimate of the scatter.
    const Eigen::Index coefficients = spline.coefficients().size();
    double ss = 0.0;
    for (Eigen::Index i = 0; i < x.size(); ++i) ss += std::pow(y(i) - spline(x(i)), 2);
    const int residual_dof = static_cast<int>(x.size() - coefficients);
    const double s = residual_dof > 0 ? std::sqrt(ss / residual_dof) : 0.0;
    std::fill(sigmas.begin(), sigmas.end(), s);
    dof = std::max(residual_dof, 0);
  }
  return ErrorFunction(data.name, std::move(spline), 0.0, std::move(nodes), std::move(sigmas), dof,
                       knownRepeats(std::move(repeats)));
}

Eigen::MatrixXd ErrorFunction::fitErrorFactor(const Eigen::VectorXd& coordinates) const {
  // Not known: the repeats, or the scatter (no degree of freedom: a constant or a curve through
  // nodes measured once each, whose s is a stand-in).
  if (node_repeats_.size() != nodes_.size() || dof_ == 0) return {};
  const auto m = static_cast<Eigen::Index>(nodes_.size());
  const auto pooled =
      pooledScatter(std::vector<std::optional<double>>(node_sigmas_.begin(), node_sigmas_.end()), node_repeats_);
  // Each node's mean has the pooled scatter over its repeats: a node's own s, of a few degrees of
  // freedom, would state some means far more precise than they are (without repeats, the s of
  // every node is the fit's residual's, pooled already).
  Eigen::VectorXd mean_sd(m);
  for (std::size_t k = 0; k < nodes_.size(); ++k) {
    mean_sd(static_cast<Eigen::Index>(k)) =
        (pooled.dof > 0 ? pooled.s : node_sigmas_[k]) / std::sqrt(static_cast<double>(node_repeats_[k]));
  }
  if (!spline_) return Eigen::MatrixXd::Constant(coordinates.size(), 1, mean_sd(0));
  // The curve a unit mean at one node and zeros at the others give, with the fit's weights.
  const Eigen::VectorXd x = Eigen::Map<const Eigen::VectorXd>(nodes_.data(), m);
  const Eigen::VectorXd w = fitWeights(node_sigmas_, pooled.s);
  Eigen::MatrixXd out(coordinates.size(), m);
  for (Eigen::Index k = 0; k < m; ++k) {
    const BSpline unit = BSpline::fit(spline_->degree(), spline_->knots(), x, Eigen::VectorXd::Unit(m, k), w);
    for (Eigen::Index i = 0; i < coordinates.size(); ++i) out(i, k) = unit(coordinates(i)) * mean_sd(k);
  }
  return out;
}

std::vector<double> errorCurveKnots(const std::vector<double>& nodes, int degree, double min_knot_spacing_mm) {
  // As many spans as the spacing allows, but never more coefficients than nodes.
  const double a = nodes.front(), b = nodes.back();
  const int max_spans = static_cast<int>(nodes.size()) - degree;
  // Clamped as a double: a span count beyond an int (1e12 mm of travel) is not converted.
  const int spans = static_cast<int>(
      std::clamp(std::floor((b - a) / min_knot_spacing_mm + 1e-9), 1.0, static_cast<double>(std::max(1, max_spans))));
  return BSpline::clampedKnots(a, b, degree, BSpline::averagedInteriorKnots(nodes, degree, spans));
}

nlohmann::json ErrorFunction::toJson() const {
  nlohmann::json j = {{"nodes", nodes_}, {"node_sigmas", node_sigmas_}, {"dof", dof_}};
  if (!node_repeats_.empty()) j["node_repeats"] = node_repeats_;
  if (spline_) {
    j["degree"] = spline_->degree();
    j["knots"] = spline_->knots();
    j["coefficients"] = std::vector<double>(spline_->coefficients().begin(), spline_->coefficients().end());
  } else {
    j["constant"] = constant_;
  }
  return j;
}

ErrorFunction ErrorFunction::fromJson(const std::string& name, const nlohmann::json& j) {
  try {
    std::optional<BSpline> spline;
    double constant = 0.0;
    if (j.contains("coefficients")) {
      const auto c = j.at("coefficients").get<std::vector<double>>();
      spline.emplace(wholeNumber(j.at("degree"), "degree", 0, 10), j.at("knots").get<std::vector<double>>(),
                     Eigen::Map<const Eigen::VectorXd>(c.data(), static_cast<Eigen::Index>(c.size())));
    } else {
      constant = j.at("constant").get<double>();
    }
    std::vector<int> repeats;
    if (j.contains("node_repeats")) {
      for (const auto& r : j.at("node_repeats")) repeats.push_back(wholeNumber(r, "node_repeats", 1, 1000000000));
    }
    return ErrorFunction(name, std::move(spline), constant, j.at("nodes").get<std::vector<double>>(),
                         j.at("node_sigmas").get<std::vector<double>>(), wholeNumber(j.at("dof"), "dof", 0, 1000000000),
                         std::move(repeats));
  } catch (const nlohmann::json::exception& e) {
    throw InputError("error function " + name + ": " + e.what());
  }
}

double ErrorFunction::value(double coordinate) const { return spline_ ? (*spline_)(coordinate) : constant_; }

double ErrorFunction::sigma(double coordinate) const {
  if (nodes_.size() == 1 || coordinate <= nodes_.front()) return node_sigmas_.front();
  if (coordinate >= nodes_.back()) return node_sigmas_.back();
  const auto it = std::upper_bound(nodes_.begin(), nodes_.end(), coordinate);
  const auto i = static_cast<std::size_t>(it - nodes_.begin());
  const double f = (coordinate - nodes_[i - 1]) / (nodes_[i] - nodes_[i - 1]);
  return node_sigmas_[i - 1] + f * (node_sigmas_[i] - node_sigmas_[i - 1]);
}

ErrorModel::ErrorModel(MultibodyModel kinematics, std::vector<ErrorFunction> functions)
    : kinematics_(std::move(kinematics)), functions_(std::move(functions)) {
  const auto& terms = kinematics_.terms();
  function_of_term_.assign(terms.size(), -1);
  for (std::size_t f = 0; f < functions_.size(); ++f) {
    const int t = kinematics_.termIndex(functions_[f].name());
    if (function_of_term_[static_cast<std::size_t>(t)] >= 0) {
      throw InputError("error model: " + functions_[f].name() + " is given twice");
    }
    function_of_term_[static_cast<std::size_t>(t)] = static_cast<int>(f);
  }
  const auto& coords = kinematics_.coordinates();
  for (const auto& term : terms) {
    const Joint& joint = kinematics_.joints()[static_cast<std::size_t>(term.joint)];
    const auto it = std::find(coords.begin(), coords.end(), joint.coordinate);
    coordinate_of_term_.push_back(term.motion && it != coords.end() ? static_cast<int>(it - coords.begin()) : -1);
    // A rotary axis' errors repeat every turn: its angle is read within the turn its nodes start.
    const int f = function_of_term_[turn_start_of_term_.size()];
    const bool periodic = term.motion && joint.type == JointType::kRevolute && f >= 0 &&
                          functions_[static_cast<std::size_t>(f)].nodes().size() > 1;
    turn_start_of_term_.push_back(periodic ? functions_[static_cast<std::size_t>(f)].nodes().front()
                                           : std::numeric_limits<double>::quiet_NaN());
  }
}

double ErrorModel::argumentAt(std::size_t term, const Eigen::VectorXd& q) const {
  return coordinate_of_term_[term] >= 0 ? argument(term, q(coordinate_of_term_[term])) : 0.0;
}

double ErrorModel::argument(std::size_t term, double coordinate) const {
  const double start = turn_start_of_term_[term];
  return std::isnan(start) ? coordinate : start + std::fmod(std::fmod(coordinate - start, 360.0) + 360.0, 360.0);
}

std::pair<double, double> ErrorModel::coordinateRange(int index) const {
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (std::size_t t = 0; t < function_of_term_.size(); ++t) {
    if (function_of_term_[t] < 0 || coordinate_of_term_[t] != index) continue;
    const auto& f = functions_[static_cast<std::size_t>(function_of_term_[t])];
    if (f.constant()) continue;
    lo = std::min(lo, f.nodes().front());
    hi = std::max(hi, f.nodes().back());
  }
  return std::isfinite(lo) ? std::pair{lo, hi} : std::pair{0.0, 0.0};
}

Eigen::VectorXd ErrorModel::workspaceCentre() const {
  Eigen::VectorXd q(static_cast<Eigen::Index>(kinematics_.coordinates().size()));
  for (Eigen::Index i = 0; i < q.size(); ++i) {
    const auto [lo, hi] = coordinateRange(static_cast<int>(i));
    q(i) = (lo + hi) / 2.0;
  }
  return q;
}

Eigen::VectorXd ErrorModel::perTerm(const Eigen::VectorXd& q, double (ErrorFunction::*get)(double) const) const {
  Eigen::VectorXd out = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(function_of_term_.size()));
  for (std::size_t t = 0; t < function_of_term_.size(); ++t) {
    if (function_of_term_[t] < 0) continue;
    out(static_cast<Eigen::Index>(t)) =
        (functions_[static_cast<std::size_t>(function_of_term_[t])].*get)(argumentAt(t, q));
  }
  return out;
}

Eigen::VectorXd ErrorModel::errorsAt(const Eigen::VectorXd& q) const { return perTerm(q, &ErrorFunction::value); }

Eigen::VectorXd ErrorModel::sigmasAt(const Eigen::VectorXd& q) const { return perTerm(q, &ErrorFunction::sigma); }

Eigen::MatrixXd ErrorModel::readingFitErrorFactor(const std::vector<Eigen::VectorXd>& q,
                                                  const Eigen::MatrixXd& sensitivity) const {
  const auto points = static_cast<Eigen::Index>(q.size());
  assert(sensitivity.rows() == points && sensitivity.cols() == static_cast<Eigen::Index>(function_of_term_.size()));
  std::vector<Eigen::MatrixXd> blocks(functions_.size());  // per function: points x its nodes
  Eigen::Index columns = 0;
  for (std::size_t t = 0; t < function_of_term_.size(); ++t) {
    const auto sensitivity_of_term = sensitivity.col(static_cast<Eigen::Index>(t));
    if (function_of_term_[t] < 0 || (sensitivity_of_term.array() == 0.0).all()) continue;
    const auto f = static_cast<std::size_t>(function_of_term_[t]);
    Eigen::VectorXd at(points);
    for (Eigen::Index i = 0; i < points; ++i) at(i) = argumentAt(t, q[static_cast<std::size_t>(i)]);
    const Eigen::MatrixXd factor = functions_[f].fitErrorFactor(at);
    if (factor.size() == 0) return {};  // a term the readings see whose error is not stated: not all of it is
    if (blocks[f].size() == 0) {
      blocks[f] = Eigen::MatrixXd::Zero(points, factor.cols());
      columns += factor.cols();
    }
    blocks[f] += sensitivity_of_term.asDiagonal() * factor;
  }
  Eigen::MatrixXd out(points, columns);
  Eigen::Index column = 0;
  for (const auto& b : blocks) {
    if (b.size() == 0) continue;
    out.middleCols(column, b.cols()) = b;
    column += b.cols();
  }
  return columns ? out : Eigen::MatrixXd();
}

Eigen::Vector3d ErrorModel::predictUm(const Eigen::VectorXd& q) const {
  return kinematics_.spatialErrorUm(q, errorsAt(q));
}

void ErrorModel::jointErrors(int joint, double value, Eigen::Matrix<double, 6, 1>& static_error,
                             Eigen::Matrix<double, 6, 1>& motion_error) const {
  static_error.setZero();
  motion_error.setZero();
  const auto& terms = kinematics_.terms();
  for (std::size_t t = 0; t < terms.size(); ++t) {
    if (terms[t].joint != joint || function_of_term_[t] < 0) continue;
    const auto& f = functions_[static_cast<std::size_t>(function_of_term_[t])];
    const double v = f.value(coordinate_of_term_[t] >= 0 ? argument(t, value) : 0.0);
    (terms[t].motion ? motion_error : static_error)(static_cast<int>(terms[t].component)) += v;
  }
}

std::vector<Eigen::Vector3d> ErrorModel::predictGridUm(const std::vector<std::vector<double>>& axis_values) const {
  const auto& kin = kinematics_;
  if (axis_values.size() != kin.coordinates().size()) {
    throw InputError("grid: one list of values per coordinate is needed");
  }
  // Per joint and per value of its coordinate: the actual and the ideal joint matrix.
  struct Table {
    int coordinate = -1;
    std::vector<Eigen::Matrix4d> actual, ideal;
  };
  const Eigen::Matrix<double, 6, 1> zero = Eigen::Matrix<double, 6, 1>::Zero();
  std::vector<Table> tables(kin.joints().size());
  for (std::size_t j = 0; j < tables.size(); ++j) {
    Table& t = tables[j];
    t.coordinate = kin.coordinateOfJoint(static_cast<int>(j));
    const std::vector<double> values =
        t.coordinate >= 0 ? axis_values[static_cast<std::size_t>(t.coordinate)] : std::vector<double>{0.0};
    for (double v : values) {
      Eigen::Matrix<double, 6, 1> se, me;
      jointErrors(static_cast<int>(j), v, se, me);
      t.actual.push_back(kin.jointMatrix(static_cast<int>(j), v, se, me));
      t.ideal.push_back(kin.jointMatrix(static_cast<int>(j), v, zero, zero));
    }
  }
  std::size_t total = 1;
  for (const auto& values : axis_values) total *= values.size();
  std::vector<Eigen::Vector3d> out;
  out.reserve(total);
  std::vector<std::size_t> index(axis_values.size(), 0);
  const Eigen::Vector4d p = kin.toolPoint().homogeneous();
  auto pick = [&](const Table& t, bool ideal) -> const Eigen::Matrix4d& {
    const std::size_t i = t.coordinate >= 0 ? index[static_cast<std::size_t>(t.coordinate)] : 0;
    return ideal ? t.ideal[i] : t.actual[i];
  };

  // Tool branch from the tool end: the vector F_k ... F_n p depends only on the coordinates
  // of joints k..n, so it is cached per combination of those (matrix products associate);
  // at the outermost joint one matrix-vector product per point remains.
  const auto& tool = kin.toolJoints();
  struct Suffix {
    std::vector<int> coords;  // coordinates it depends on
    std::size_t size = 1;
    std::vector<Eigen::Vector4d> actual, ideal;
    std::vector<char> filled;
  };
  constexpr std::size_t kMaxCache = 1 << 20;
  std::vector<Suffix> suffix(tool.size() + 1);
  for (std::size_t k = tool.size(); k-- > 0;) {
    suffix[k].coords = suffix[k + 1].coords;
    const int c = tables[static_cast<std::size_t>(tool[k])].coordinate;
    if (c >= 0 && std::find(suffix[k].coords.begin(), suffix[k].coords.end(), c) == suffix[k].coords.end()) {
      suffix[k].coords.push_back(c);
    }
    for (int cc : suffix[k].coords) suffix[k].size *= axis_values[static_cast<std::size_t>(cc)].size();
    if (suffix[k].size <= kMaxCache && suffix[k].size < total) {
      suffix[k].actual.resize(suffix[k].size);
      suffix[k].ideal.resize(suffix[k].size);
      suffix[k].filled.assign(suffix[k].size, 0);
    }
  }
  std::function<Eigen::Vector4d(std::size_t, bool)> through = [&](std::size_t k, bool ideal) -> Eigen::Vector4d {
    if (k == tool.size()) return p;
    Suffix& sfx = suffix[k];
    std::size_t key = 0;
    const bool cached = !sfx.filled.empty();
    if (cached) {
      for (int cc : sfx.coords)
        key = key * axis_values[static_cast<std::size_t>(cc)].size() + index[static_cast<std::size_t>(cc)];
      const char bit = ideal ? 2 : 1;
      if (sfx.filled[key] & bit) return ideal ? sfx.ideal[key] : sfx.actual[key];
      const Eigen::Vector4d v = pick(tables[static_cast<std::size_t>(tool[k])], ideal) * through(k + 1, ideal);
      (ideal ? sfx.ideal[key] : sfx.actual[key]) = v;
      sfx.filled[key] |= bit;
      return v;
    }
    return pick(tables[static_cast<std::size_t>(tool[k])], ideal) * through(k + 1, ideal);
  };

  // Workpiece branch: constant when none of its joints moves (inverted once).
  const auto& work = kin.workpieceJoints();
  const bool work_moves =
      std::any_of(work.begin(), work.end(), [&](int j) { return tables[static_cast<std::size_t>(j)].coordinate >= 0; });
  auto workInverse = [&](bool ideal) {
    Eigen::Matrix4d w = Eigen::Matrix4d::Identity();
    for (int j : work) w = w * pick(tables[static_cast<std::size_t>(j)], ideal);
    Eigen::Matrix4d inv = Eigen::Matrix4d::Identity();  // rigid: [R t]^-1 = [R^T, -R^T t]
    inv.block<3, 3>(0, 0) = w.block<3, 3>(0, 0).transpose();
    inv.block<3, 1>(0, 3) = -inv.block<3, 3>(0, 0) * w.block<3, 1>(0, 3);
    return inv;
  };
  Eigen::Matrix4d work_actual = workInverse(false), work_ideal = workInverse(true);
  for (std::size_t n = 0; n < total; ++n) {
    if (work_moves) {
      work_actual = workInverse(false);
      work_ideal = workInverse(true);
    }
    const Eigen::Vector4d ideal = work_ideal * through(0, true);
    const Eigen::Vector4d actual = work_actual * through(0, false);
    out.emplace_back((ideal - actual).head<3>() * 1000.0);
    for (std::size_t a = axis_values.size(); a-- > 0;) {
      if (++index[a] < axis_values[a].size()) break;
      index[a] = 0;
    }
  }
  return out;
}

Eigen::Vector3d ErrorModel::sigmaUm(const Eigen::VectorXd& q) const {
  const Eigen::Matrix3Xd jac = kinematics_.jacobian(q);
  const Eigen::VectorXd s = sigmasAt(q);
  return (jac.array().square().rowwise() * s.array().square().transpose()).rowwise().sum().sqrt();
}

std::vector<KeyError> ErrorModel::keyErrors(const Eigen::VectorXd& q) const {
  const Eigen::Matrix3Xd jac = kinematics_.jacobian(q);
  const Eigen::VectorXd s = sigmasAt(q);
  const Eigen::Matrix3Xd contribution = jac.array().square().rowwise() * s.array().square().transpose();
  const Eigen::Vector3d total = contribution.rowwise().sum();
  std::vector<KeyError> out;
  for (std::size_t t = 0; t < kinematics_.terms().size(); ++t) {
    KeyError k;
    k.name = kinematics_.terms()[t].name;
    for (int i = 0; i < 3; ++i) {
      k.share[static_cast<std::size_t>(i)] =
          total(i) > 0.0 ? contribution(i, static_cast<Eigen::Index>(t)) / total(i) : 0.0;
    }
    out.push_back(k);
  }
  std::stable_sort(out.begin(), out.end(), [](const KeyError& a, const KeyError& b) {
    return *std::max_element(a.share.begin(), a.share.end()) > *std::max_element(b.share.begin(), b.share.end());
  });
  return out;
}

double coverageFactor(double nominal_k, int dof) {
  if (dof <= 0) return nominal_k;
  const double coverage = std::erf(nominal_k / std::sqrt(2.0));  // two-sided, 0.9973 for 3
  const boost::math::students_t t(dof);
  return boost::math::quantile(t, 0.5 + coverage / 2.0);
}

}  // namespace mtcal::processing
