// What the per-kind candidate catalogues share: the shape and candidate constructors, the
// generic "depends on this variable" candidate, the drift candidates of any timed data, and the
// checks, channels and folds every kind's data builder needs.
#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <numeric>
#include <string>
#include <vector>

#include "diagnosis_internal.h"
#include "mtcal/error.h"

namespace mtcal::processing::detail {

std::string lostMotion(const std::string& axis) {
  std::string upper = axis;
  for (auto& ch : upper) ch = static_cast<char>(std::toupper(static_cast<unsigned char>(ch)));
  return "lost_motion_" + upper;
}

Candidate genericCandidate(const DiagnosisVariable& v) {
  Candidate c;
  c.effect = "generic";
  c.variable = v.name;
  c.cause = fmt::format("the residual depends on {} in a way none of the named causes describes", v.name);
  const auto values = distinct(v.values);  // where it is known
  ExtensionShape s{"spline", {v.name}};
  s.spans = std::clamp(static_cast<int>(values.size()) / 6, 1, 4);
  s.range = {values.front(), values.back()};
  c.shapes = {s};
  return c;
}

ExtensionShape shape(const std::string& kind, std::vector<std::string> variables, double scale, double reference,
                     double searched) {
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

namespace {

/// The time constant of a first-order response, searched over log-spaced values from a
/// twentieth of the run to twice it (every shape of the candidate shares it).
Candidate& searchTimeConstant(Candidate& c, const Eigen::VectorXd& time_s) {
  const double span = time_s.maxCoeff() - time_s.minCoeff();
  for (int k = 0; k < 12; ++k) c.search.push_back(span * std::pow(40.0, k / 11.0) / 20.0);
  for (auto& s : c.shapes) s.searched = c.search.front();
  c.independent_tries = 4.0;
  c.searched_name = "time_constant";
  c.searched_unit = "s";
  return c;
}

}  // namespace

Candidate firstOrderDrift(const Eigen::VectorXd& time_s) {
  auto c = candidate("thermal_drift", "time_s",
                     "the machine drifts with time towards a new thermal state (first-order response)",
                     {shape("first_order", {"time_s"}, 1.0, time_s.minCoeff())}, {{"amplitude", "um", 1.0}});
  return searchTimeConstant(c, time_s);
}

Candidate linearDrift() {
  return candidate("thermal_drift", "time_s", "the machine drifts steadily with time (warm-up or room temperature)",
                   {shape("linear", {"time_s"}, 1.0 / 3600.0)}, {{"drift_rate", "um/h", 1.0}});
}

std::vector<Candidate> thermalGrowth(const Eigen::VectorXd& time_s) {
  const double t0 = time_s.minCoeff();
  auto first_order = candidate(
      "thermal_growth", "time_s",
      "the axis grows along its travel as it warms (first-order response in time), its datum drifting with it",
      {shape("first_order", {"time_s"}, 1.0, t0), shape("first_order*position_mm", {"time_s"}, 1e-3, t0)},
      {{"amplitude", "um", 1.0}, {"growth", "ppm", 1.0}});
  return {
      candidate(
          "thermal_growth", "time_s", "the axis grows steadily along its travel with time, its datum drifting with it",
          {shape("linear", {"time_s"}, 1.0 / 3600.0), shape("product", {"position_mm", "time_s"}, 1e-3 / 3600.0, t0)},
          {{"drift_rate", "um/h", 1.0}, {"growth_rate", "ppm/h", 1.0}}),
      searchTimeConstant(first_order, time_s)};
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

void addChannels(DiagnosisData& d, const std::vector<DiagnosisVariable>& channels, std::size_t n, const char* what) {
  for (const auto& c : channels) {
    if (c.values.size() != static_cast<Eigen::Index>(n)) {
      throw InputError(
          fmt::format("{}: {} {} has {} values for {} points", d.source, what, c.name, c.values.size(), n));
    }
    if (!c.values.allFinite()) {
      const auto missing = (!c.values.array().isFinite()).count();
      d.notes.push_back(fmt::format("{} {} lacks {} of its {} values: not used (its candidates need every point's)",
                                    what, c.name, missing, n));
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

}  // namespace mtcal::processing::detail
