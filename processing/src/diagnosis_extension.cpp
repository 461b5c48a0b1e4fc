// The extension algebra: the columns a shape adds on a data set's variables, an accepted
// finding in its stored form (ModelExtension) with its JSON, and extensions re-applied with
// their coefficients fixed to other data (values, application, validation on another run).
#include <fmt/format.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <deque>
#include <nlohmann/json.hpp>
#include <numbers>
#include <string>
#include <utility>
#include <vector>

#include "diagnosis_internal.h"
#include "json_number.h"
#include "mtcal/error.h"
#include "mtcal/processing/bspline.h"
#include "mtcal/processing/diagnosis.h"

namespace mtcal::processing {

namespace detail {

namespace {
bool reversalKind(const std::string& kind) { return kind == "sign_sin_cos" || kind == "sign_cos_sin"; }
}  // namespace

ShapeKind shapeKind(const std::string& kind) {
  const auto star = kind.find('*');
  ShapeKind out{kind.substr(0, star), star == std::string::npos ? std::string() : kind.substr(star + 1)};
  if (reversalKind(out.kind) && out.multiplier.empty()) out.multiplier = "direction";
  return out;
}

std::string shapeKindText(const ShapeKind& kind) {
  const bool implied = reversalKind(kind.kind) && kind.multiplier == "direction";
  return kind.multiplier.empty() || implied ? kind.kind : kind.kind + "*" + kind.multiplier;
}

BSpline basisSpline(std::pair<double, double> range, int spans) {
  const int degree = 3;
  std::vector<double> interior;
  for (int k = 1; k < spans; ++k) interior.push_back(range.first + (range.second - range.first) * k / spans);
  const auto knots = BSpline::clampedKnots(range.first, range.second, degree, interior);
  return BSpline(degree, knots, Eigen::VectorXd::Zero(static_cast<Eigen::Index>(knots.size()) - degree - 1));
}

}  // namespace detail

using detail::basisSpline;
using detail::leastSquares;
using detail::rmsOf;
using detail::vec;

namespace {

constexpr double kTwoPi = 2.0 * std::numbers::pi;

}  // namespace

nlohmann::json ExtensionShape::toJson() const {
  nlohmann::json j = {
      {"kind", kind}, {"variables", variables}, {"reference", reference}, {"searched", searched}, {"scale", scale}};
  if (spans > 0) j["spans"] = spans;
  if (spans > 0 || range.second > range.first) j["range"] = {range.first, range.second};
  if (into >= 0) j["into"] = into;
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
    s.spans = j.contains("spans") ? wholeNumber(j["spans"], "spans", 0, 100000) : 0;
    if (j.contains("range")) s.range = {j.at("range").at(0).get<double>(), j.at("range").at(1).get<double>()};
    s.into = j.contains("into") ? wholeNumber(j["into"], "into", 0, 1000) : -1;
    return s;
  } catch (const nlohmann::json::exception& e) {
    throw InputError(std::string("model extension shape: ") + e.what());
  }
}

Eigen::MatrixXd extensionColumns(const std::vector<ExtensionShape>& shapes, const DiagnosisData& data) {
  const Eigen::Index n = data.measured.size();
  std::vector<Eigen::VectorXd> cols;
  for (const auto& s : shapes) {
    // "kind*variable": the kind's columns times that variable.
    const detail::ShapeKind parsed = detail::shapeKind(s.kind);
    const std::string& kind = parsed.kind;
    const std::string& multiplier = parsed.multiplier;
    // A point where a variable is unknown (another run's rows in a fit of runs of different
    // kinds) gets nothing from the shape: its variables read 0 there, its columns are 0.
    std::deque<Eigen::VectorXd> known;
    Eigen::ArrayXd defined;  // empty: every point
    const auto valuesOf = [&](const std::string& name) -> const Eigen::VectorXd* {
      const auto* var = data.variable(name);
      if (!var)
        throw InputError(fmt::format("{}: the extension '{}' needs the variable {}, which the data lack", data.source,
                                     s.kind, name));
      if (!var->values.array().isNaN().any()) return &var->values;
      if (!defined.size()) defined = Eigen::ArrayXd::Ones(n);
      defined *= (!var->values.array().isNaN()).cast<double>();
      return &known.emplace_back(var->values.array().isNaN().select(0.0, var->values));
    };
    std::vector<const Eigen::VectorXd*> v;
    for (const auto& name : s.variables) v.push_back(valuesOf(name));
    const Eigen::VectorXd* factor = multiplier.empty() ? nullptr : valuesOf(multiplier);
    auto need = [&](std::size_t count) {
      if (v.size() < count) throw InputError(fmt::format("extension '{}' needs {} variables", s.kind, count));
    };
    std::vector<Eigen::VectorXd> out;
    // A column about its mean over the points where the shape's variables are known (elsewhere
    // it is 0).
    const auto aboutMean = [&](const Eigen::ArrayXd& c) -> Eigen::VectorXd {
      const double mean = defined.size() ? (c * defined).sum() / std::max(1.0, defined.sum()) : c.mean();
      return (c - mean).matrix();
    };
    const Eigen::ArrayXd phase = (kind == "sin" || kind == "cos" || kind == "harmonic") && s.searched > 0.0
                                     ? Eigen::ArrayXd(kTwoPi * v.at(0)->array() / s.searched)
                                     : Eigen::ArrayXd();
    if (kind == "linear") {
      need(1);
      out.push_back((v[0]->array() - s.reference).matrix());
    } else if (kind == "quadratic") {
      need(1);
      if (!(s.range.second > s.range.first)) throw InputError("quadratic extension without a range");
      const Eigen::ArrayXd u = v[0]->array().max(s.range.first).min(s.range.second) - s.reference;
      out.push_back(u.matrix());
      out.push_back(u.square().matrix());
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
    } else if (kind == "harmonic_difference" || kind == "harmonic_difference_about_mean") {
      need(2);
      if (!(s.searched > 0.0)) throw InputError("harmonic-difference extension without a period");
      const Eigen::ArrayXd from = kTwoPi * v[0]->array() / s.searched, to = kTwoPi * v[1]->array() / s.searched;
      for (const Eigen::ArrayXd& change :
           {Eigen::ArrayXd(to.sin() - from.sin()), Eigen::ArrayXd(to.cos() - from.cos())})
        out.push_back(kind == "harmonic_difference" ? Eigen::VectorXd(change) : aboutMean(change));
    } else if (kind == "constant") {
      out.push_back(Eigen::VectorXd::Ones(n));
    } else if (kind == "sign_sin_cos" || kind == "sign_cos_sin") {
      need(1);
      const Eigen::ArrayXd a = v[0]->array() * std::numbers::pi / 180.0;
      const Eigen::ArrayXd first = kind == "sign_sin_cos" ? Eigen::ArrayXd(a.sin()) : Eigen::ArrayXd(a.cos());
      const Eigen::ArrayXd second = kind == "sign_sin_cos" ? Eigen::ArrayXd(a.cos()) : Eigen::ArrayXd(a.sin());
      Eigen::ArrayXd step = first.sign() * second;
      if (s.reference > 0.0 && factor) {
        // The take-up: within `reference` degrees after the axis reverses (in the direction of
        // travel) the lost motion is being crossed, and the step is not read there.
        const double reverses_at = kind == "sign_sin_cos" ? 0.0 : 90.0;
        for (Eigen::Index i = 0; i < n; ++i) {
          const double turned = (*factor)(i) >= 0.0 ? (*v[0])(i)-reverses_at : reverses_at - (*v[0])(i);
          const double since = std::fmod(std::fmod(turned, 180.0) + 180.0, 180.0);
          if (since < s.reference) step(i) = 0.0;
        }
      }
      out.push_back(step.matrix());
    } else if (kind == "spline" || kind == "step_difference") {
      need(kind == "spline" ? 1 : 2);
      const auto spline = basisSpline(s.range, std::max(1, s.spans));
      const Eigen::Index m = spline.coefficients().size();
      Eigen::MatrixXd b(n, m);
      for (Eigen::Index i = 0; i < n; ++i) {
        const double x0 = std::clamp((*v[0])(i), s.range.first, s.range.second);
        b.row(i) = spline.basis(x0).transpose();
        if (kind == "step_difference")
          b.row(i) = spline.basis(std::clamp((*v[1])(i), s.range.first, s.range.second)).transpose() - b.row(i);
      }
      // A spline's constant is the baseline's: its last coefficient is left out (held at 0).
      // A difference of one has no constant, and a yaw growing at a constant rate reads as a
      // constant on probe 3, which the probes' zeros are too: the differences are taken about
      // their mean, so that constant is the zeros' (probe_offset), and the first two
      // coefficients are left out, which no straight line can be made without (with one, the
      // line's columns would be zero and the fit's covariance singular).
      for (Eigen::Index j = kind == "spline" ? 0 : 2; j < (kind == "spline" ? m - 1 : m); ++j) {
        out.push_back(kind == "spline" ? Eigen::VectorXd(b.col(j)) : aboutMean(b.col(j).array()));
      }
    } else {
      throw InputError(fmt::format("unknown extension shape '{}'", s.kind));
    }
    if (s.into >= 0 && (out.size() != 1 || static_cast<std::size_t>(s.into) >= cols.size()))
      throw InputError(fmt::format("extension '{}': adds into column {} of {}", s.kind, s.into, cols.size()));
    for (auto& c : out) {
      if (factor) c = c.cwiseProduct(*factor);
      if (defined.size()) c = c.cwiseProduct(defined.matrix());
      c *= s.scale;
      if (s.into >= 0) {
        cols[static_cast<std::size_t>(s.into)] += c;
      } else {
        cols.push_back(c);
      }
    }
  }
  Eigen::MatrixXd x(n, static_cast<Eigen::Index>(cols.size()));
  for (std::size_t j = 0; j < cols.size(); ++j) x.col(static_cast<Eigen::Index>(j)) = cols[j];
  if (!x.allFinite()) throw InputError(fmt::format("{}: an extension's variable has unknown values", data.source));
  return x;
}

nlohmann::json ModelExtension::toJson() const {
  nlohmann::json shapes_json = nlohmann::json::array();
  for (const auto& s : shapes) shapes_json.push_back(s.toJson());
  nlohmann::json params = nlohmann::json::object();
  for (const auto& p : parameters)
    params[p.name] = {{"value", p.value}, {"unit", p.unit}, {"standard_error", p.standard_error}};
  return {{"effect", effect},
          {"cause", cause},
          {"variable", variable},
          {"shapes", shapes_json},
          {"coefficients", coefficients},
          {"parameters", params}};
}

namespace {

/// A step_difference extension stored with one basis function left out (spans + 2
/// coefficients: a column combination of them was zero, a yaw at a constant rate) in the
/// layout of two left out (spans + 1): the same curve's differences. The zero combination has
/// the coefficients of the straight line x - xi_0 (xi the Greville abscissae), which is taken
/// off so that the second basis function's coefficient is 0.
void stepDifferenceWithTwoLeftOut(ModelExtension& e) {
  if (e.shapes.size() != 1 || e.shapes.front().kind != "step_difference") return;
  const auto& shape = e.shapes.front();
  const int spans = std::max(1, shape.spans);
  if (e.coefficients.size() != static_cast<std::size_t>(spans) + 2) return;
  const BSpline spline = basisSpline(shape.range, spans);
  const auto& knots = spline.knots();
  const auto greville = [&](std::size_t j) { return (knots[j + 1] + knots[j + 2] + knots[j + 3]) / 3.0; };
  // e.coefficients[k] is basis function k + 1's.
  const double line_to_first = e.coefficients.front() / (greville(1) - greville(0));
  std::vector<double> kept;
  for (std::size_t k = 1; k < e.coefficients.size(); ++k)
    kept.push_back(e.coefficients[k] - line_to_first * (greville(k + 1) - greville(0)));
  e.coefficients = std::move(kept);
}

}  // namespace

ModelExtension ModelExtension::fromJson(const nlohmann::json& j) {
  try {
    ModelExtension e;
    e.effect = j.at("effect").get<std::string>();
    e.cause = j.value("cause", "");
    e.variable = j.value("variable", "");
    for (const auto& s : j.at("shapes")) e.shapes.push_back(ExtensionShape::fromJson(s));
    e.coefficients = j.at("coefficients").get<std::vector<double>>();
    stepDifferenceWithTwoLeftOut(e);
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
  return {f.candidate.effect,
          f.candidate.cause,
          f.candidate.variable,
          f.candidate.shapes,
          std::vector<double>(f.coefficients.data(), f.coefficients.data() + f.coefficients.size()),
          f.parameters};
}

Eigen::VectorXd extensionValues(const std::vector<ModelExtension>& extensions, const DiagnosisData& data) {
  Eigen::VectorXd sum = Eigen::VectorXd::Zero(data.measured.size());
  for (const auto& e : extensions) {
    const Eigen::MatrixXd cols = extensionColumns(e.shapes, data);
    if (static_cast<std::size_t>(cols.cols()) != e.coefficients.size()) {
      throw InputError(fmt::format("model extension {}: {} coefficients for {} columns", e.effect,
                                   e.coefficients.size(), cols.cols()));
    }
    sum += cols * vec(e.coefficients);
  }
  return sum;
}

AppliedExtensions applyExtensions(const std::vector<ModelExtension>& extensions, const DiagnosisData& data) {
  AppliedExtensions a;
  a.values = Eigen::VectorXd::Zero(data.measured.size());
  for (const auto& e : extensions) {
    // A finding of the set-up where the model was made (a circle's centre, a probe's zero) that a
    // version stored before such findings were kept out of it still holds: not this run's.
    const bool of_setup = std::any_of(data.candidates.begin(), data.candidates.end(),
                                      [&](const Candidate& c) { return c.of_setup && c.effect == e.effect; });
    if (of_setup) {
      a.left_out.push_back(e.effect);
      a.why.push_back(
          fmt::format("{} is the set-up's where the model was made (where the instrument sat), not the "
                      "machine's: not applied",
                      e.effect));
      continue;
    }
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

}  // namespace mtcal::processing
