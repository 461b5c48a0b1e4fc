#pragma once
// The geometric error model of a machine: its kinematics (MultibodyModel) and, for every
// error term, a function of the joint coordinate with its uncertainty. Motion errors are
// B-splines fitted to node means with weights 1/s^2 (s from the repeats); static errors
// (squareness) are constants. Predicts the spatial error anywhere in the workspace, its
// standard deviation, and the share of each error term in it (patent CN104200063).
//
// Units: coordinates mm (rotary axes degrees), errors um / urad, E um. Thread-safe (const).

#include <array>
#include <nlohmann/json_fwd.hpp>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "mtcal/processing/bspline.h"
#include "mtcal/processing/multibody.h"

namespace mtcal::processing {

/// The measured values of one error term: nodes with the mean and the sample standard
/// deviation of the repeats (s is empty when a node was measured once).
struct ErrorCurveData {
  std::string name;
  std::vector<double> position_mm;  ///< empty for a static error (one node)
  std::vector<double> mean;
  std::vector<std::optional<double>> s;
  std::vector<int> repeats;
};

struct ErrorFitOptions {
  int degree = 3;
  /// Knots no closer than this (the patent's nodes are 20 mm apart: structure finer than the
  /// node spacing cannot be resolved and is left to the residual).
  double min_knot_spacing_mm = 20.0;
};

/// The clamped knots of an error curve over sorted, distinct nodes: as many spans as
/// `min_knot_spacing_mm` allows over their range, never more coefficients than nodes, interior
/// knots by de Boor's averaging (BSpline::averagedInteriorKnots).
std::vector<double> errorCurveKnots(const std::vector<double>& nodes, int degree, double min_knot_spacing_mm);

/// One error term as a function of its coordinate, with a standard deviation.
class ErrorFunction {
 public:
  /// A constant (static errors, or a motion error measured at one node).
  ErrorFunction(std::string name, double value, double sigma);
  /// Fits the curve: B-spline of the node means, weights 1/s^2; nodes without s take the
  /// pooled s of the others, or the fit residual when no node has one.
  /// @throws InputError when the nodes cannot determine the spline
  static ErrorFunction fit(const ErrorCurveData& data, const ErrorFitOptions& options);

  const std::string& name() const { return name_; }
  bool constant() const { return !spline_; }
  double value(double coordinate) const;
  /// Standard deviation of a single realisation at this coordinate (the repeatability of the
  /// error, linearly interpolated between nodes), um / urad.
  double sigma(double coordinate) const;
  const std::optional<BSpline>& spline() const { return spline_; }
  const std::vector<double>& nodes() const { return nodes_; }
  const std::vector<double>& nodeSigmas() const { return node_sigmas_; }
  /// Degrees of freedom of the sigma estimate (sum of repeats - 1 per node; 0 when unknown).
  int degreesOfFreedom() const { return dof_; }
  /// Each node's number of readings (empty: not known, as in a function stored without them).
  const std::vector<int>& nodeRepeats() const { return node_repeats_; }
  /// The function's own error from the scatter of the readings it was fitted to: its nodes'
  /// means, each of variance s^2 / repeats, through the weighted fit, which is linear in them.
  /// A factor F, one row per coordinate and one column per node: the covariance of the
  /// function's errors at two coordinates is the product of their rows (um^2 / urad^2). What
  /// the identification knows of its own error, not a change of the machine since. Empty where
  /// the nodes' repeats are not known, or their scatter (no degree of freedom).
  Eigen::MatrixXd fitErrorFactor(const Eigen::VectorXd& coordinates) const;

  /// Serialisation for storage: degree, knots, coefficients or constant, nodes, node sigmas, dof,
  /// node repeats.
  nlohmann::json toJson() const;
  /// @throws InputError naming what is missing
  static ErrorFunction fromJson(const std::string& name, const nlohmann::json& j);

  /// Rebuilds a stored function (storage round trip); `node_repeats` empty where not known.
  ErrorFunction(std::string name, std::optional<BSpline> spline, double constant_value, std::vector<double> nodes,
                std::vector<double> node_sigmas, int dof, std::vector<int> node_repeats = {});

 private:
  std::string name_;
  std::optional<BSpline> spline_;
  double constant_ = 0.0;
  std::vector<double> nodes_;  ///< positions where sigma is known (one entry for a constant)
  std::vector<double> node_sigmas_;
  int dof_ = 0;
  std::vector<int> node_repeats_;  ///< one per node, or empty
};

/// Share of one error term in the variance of the spatial error.
struct KeyError {
  std::string name;
  std::array<double, 3> share{};  ///< of Var(E_x), Var(E_y), Var(E_z), each direction summing to 1
};

class ErrorModel {
 public:
  /// @param functions one per error term of the kinematics, by name; terms without a
  ///        function are zero with zero sigma. @throws InputError for a name the machine lacks
  ErrorModel(MultibodyModel kinematics, std::vector<ErrorFunction> functions);

  const MultibodyModel& kinematics() const { return kinematics_; }
  const std::vector<ErrorFunction>& functions() const { return functions_; }

  /// Range of coordinate `index` covered by the measured nodes of its error functions
  /// ({0, 0} when none depends on it).
  std::pair<double, double> coordinateRange(int index) const;
  /// Midpoint of every coordinate's range: where key errors are reported by default.
  Eigen::VectorXd workspaceCentre() const;

  /// Error values of every term at q (one per kinematics().terms()). A rotary axis' motion
  /// errors repeat every turn: its angle is read within the turn its nodes start (here and in
  /// the grid prediction).
  Eigen::VectorXd errorsAt(const Eigen::VectorXd& q) const;
  Eigen::VectorXd sigmasAt(const Eigen::VectorXd& q) const;
  /// Predicted spatial error E = P_ideal - P (full model), um.
  Eigen::Vector3d predictUm(const Eigen::VectorXd& q) const;
  /// Predicted E on a regular grid: every combination of `axis_values` (one list per
  /// coordinate), the last coordinate varying fastest. The same values as predictUm() point
  /// by point, computed by evaluating every error function and joint matrix once per grid
  /// value of its coordinate and chaining matrix-vector products per point.
  std::vector<Eigen::Vector3d> predictGridUm(const std::vector<std::vector<double>>& axis_values) const;

  /// The functions' own errors (ErrorFunction::fitErrorFactor) in readings at points `q`, each
  /// reading's sensitivity to the terms a row of `sensitivity` (one column per term): one row per
  /// point, the nodes of every function that states its error side by side in the columns, so
  /// that the covariance of two readings' predicted errors is the product of their rows. Terms
  /// without a function are zero, as in the prediction. Empty where none states it, or where a
  /// function the readings are sensitive to states nothing (a part of the error unknown).
  Eigen::MatrixXd readingFitErrorFactor(const std::vector<Eigen::VectorXd>& q,
                                        const Eigen::MatrixXd& sensitivity) const;
  /// Standard deviation of E_x, E_y, E_z at q with independent error terms:
  /// Var(E_i) = sum_m J_im^2 sigma_m^2 (first order).
  Eigen::Vector3d sigmaUm(const Eigen::VectorXd& q) const;
  /// Variance shares of every term at q (the patent's normalised sensitivities), ranked by
  /// the largest share over the three directions.
  std::vector<KeyError> keyErrors(const Eigen::VectorXd& q) const;

 private:
  MultibodyModel kinematics_;
  std::vector<ErrorFunction> functions_;
  std::vector<int> function_of_term_;       ///< index into functions_ or -1
  std::vector<int> coordinate_of_term_;     ///< index into q for motion terms, -1 for static
  std::vector<double> turn_start_of_term_;  ///< rotary motion terms: first node (deg); NaN otherwise
  /// The coordinate a term's function is read at (rotary axes: within the measured turn).
  double argument(std::size_t term, double coordinate) const;
  /// The coordinate a term's function is read at for the point q (0 for a static term).
  double argumentAt(std::size_t term, const Eigen::VectorXd& q) const;
  /// One value per term from its function at q (value or sigma).
  Eigen::VectorXd perTerm(const Eigen::VectorXd& q, double (ErrorFunction::*get)(double) const) const;
  /// Static and motion error 6-vectors of a joint with its coordinate at `value`.
  void jointErrors(int joint, double value, Eigen::Matrix<double, 6, 1>& static_error,
                   Eigen::Matrix<double, 6, 1>& motion_error) const;
};

/// Coverage factor for a band of +-k s when s has `dof` degrees of freedom: the Student t
/// quantile of the same two-sided coverage as +-`nominal_k` sigma (3 sigma: 99.73 %).
/// For dof = 0 (unknown) returns nominal_k.
double coverageFactor(double nominal_k, int dof);

}  // namespace mtcal::processing
