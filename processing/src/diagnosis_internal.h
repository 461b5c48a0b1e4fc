#pragma once
// What the diagnosis's source files share and nothing outside them needs: the least-squares
// fit and its held-out cross-validation (diagnosis_fit.cpp), the B-spline basis behind the
// spline shapes (diagnosis_extension.cpp) and the building blocks of the per-kind candidate
// catalogues (diagnosis_catalogue.cpp). Not installed: the public API is diagnosis.h.

#include <Eigen/Core>
#include <cstddef>
#include <initializer_list>
#include <string>
#include <utility>
#include <vector>

#include "mtcal/processing/bspline.h"
#include "mtcal/processing/diagnosis.h"

namespace mtcal::processing::detail {

inline Eigen::VectorXd vec(const std::vector<double>& v) {
  return Eigen::Map<const Eigen::VectorXd>(v.data(), static_cast<Eigen::Index>(v.size()));
}

// ---- fitting (diagnosis_fit.cpp) ----

/// Least squares of y on the columns of x (rank revealing, columns scaled to unit norm); the
/// coefficients' standard errors when asked (and x has full rank).
struct LeastSquares {
  Eigen::VectorXd coefficients;  ///< 0 for columns left out as dependent
  Eigen::VectorXd residual;
  Eigen::VectorXd standard_error;
  Eigen::MatrixXd covariance;  ///< of the coefficients, at full rank with standard errors asked
  int rank = 0;
  double rss = 0.0;
  std::vector<Eigen::Index> independent;  ///< `rank` columns of x that span its columns' space
};
/// The norm at or below which a column of `rows` values is rounding alone: a least-squares fit
/// sets it aside (a zero coefficient) rather than scale it up to a unit column.
double negligibleColumnNorm(Eigen::Index rows);
LeastSquares leastSquares(const Eigen::MatrixXd& x, const Eigen::VectorXd& y, bool standard_errors = true);
/// The upper triangle (min(rows, cols) rows) of a's Householder QR: the same least-squares
/// problems, and the same Gram matrix, in fewer rows.
Eigen::MatrixXd reduceRows(Eigen::MatrixXd a);
/// An orthonormal basis (x's rows by columns.size()) of the span of x's `columns`, which must
/// be independent (a fit's LeastSquares::independent).
Eigen::MatrixXd orthonormalBasis(const Eigen::MatrixXd& x, const std::vector<Eigen::Index>& columns);

struct HeldOut {
  Eigen::VectorXd residual;
  double rms = 0.0, peak = 0.0;
};
/// Every fold left out in turn: fitted on the others, its residuals predicted.
HeldOut crossValidate(const Eigen::MatrixXd& x, const Eigen::VectorXd& y, const Eigen::VectorXi& fold);

double rmsOf(const Eigen::VectorXd& r);

/// The sorted values, those closer than 1e-9 merged (unknown ones, NaN, left out).
std::vector<double> distinct(const Eigen::VectorXd& v);

/// A variable's own name and the run it belongs to in a fit of runs of different kinds
/// ("run 3: time_s": time_s, run 3; "time_s": time_s, none).
std::string baseName(const std::string& variable);
std::string scopeOf(const std::string& variable);
/// The name of a run's variable in a fit of runs of different kinds ("run 3: time_s").
std::string scopedName(const std::string& source, const std::string& variable);

// ---- shapes (diagnosis_extension.cpp) ----

/// A shape's kind apart from the variable its columns are multiplied by ("sin*direction": sin,
/// direction); the reversal kinds (sign_sin_cos, sign_cos_sin) are times the direction unless
/// another variable is named (a run's own in a fit of several).
struct ShapeKind {
  std::string kind, multiplier;
};
ShapeKind shapeKind(const std::string& kind);
/// The kind written back, its multiplier left out where it is the one implied.
std::string shapeKindText(const ShapeKind& kind);

/// The clamped cubic (or lower, with few sites) B-spline basis of `spans` spans over `range`.
BSpline basisSpline(std::pair<double, double> range, int spans);

// ---- candidate catalogues (diagnosis_catalogue.cpp) ----

ExtensionShape shape(const std::string& kind, std::vector<std::string> variables, double scale = 1.0,
                     double reference = 0.0, double searched = 0.0);
Candidate candidate(std::string effect, std::string variable, std::string cause, std::vector<ExtensionShape> shapes,
                    std::vector<Candidate::Parameter> parameters);

/// The quantity a drive's lost motion is (Candidate::Parameter::quantity): "lost_motion_X".
std::string lostMotion(const std::string& axis);

/// "The residual depends on <variable>": a smooth function of one variable (cubic B-spline).
Candidate genericCandidate(const DiagnosisVariable& v);
/// Log-spaced time constants over the run and a first-order drift candidate.
Candidate firstOrderDrift(const Eigen::VectorXd& time_s);
Candidate linearDrift();
/// Growth along the travel (position x time, and position x a first-order response in time)
/// with the datum's drift of the same time course (linear runs).
std::vector<Candidate> thermalGrowth(const Eigen::VectorXd& time_s);

double mean(const Eigen::VectorXd& v);
/// Whether the data have the variable, known everywhere and not constant.
bool varies(const DiagnosisData& d, const std::string& name);

/// `blocks` contiguous blocks of the points in the order of `order_by`.
Eigen::VectorXi foldsByBlocks(const Eigen::VectorXd& order_by, int blocks);
/// Channels become variables; one with a missing value is left out (noted), never filled.
void addChannels(DiagnosisData& d, const std::vector<DiagnosisVariable>& channels, std::size_t n, const char* what);
/// @throws InputError unless every size is n and n is 8 or more
void checkSizes(std::size_t n, std::initializer_list<std::size_t> sizes, const std::string& what);

}  // namespace mtcal::processing::detail
