// The least-squares fit and its held-out cross-validation, shared by the candidate search
// (diagnosis.cpp) and the validation of stored extensions on other runs (diagnosis_extension.cpp).
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <numeric>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "diagnosis_internal.h"
#include "in_parallel.h"

namespace mtcal::processing::detail {

double negligibleColumnNorm(Eigen::Index rows) { return 1e-9 * std::sqrt(static_cast<double>(rows)); }

namespace {

/// Rows per block of a tall matrix's QR: a block stays in cache.
constexpr Eigen::Index kBlockRows = 512;

/// Unit-norm scales of x's columns: a column that is numerically zero (a sinusoid sampled at
/// its zeros) keeps scale 1 and is set to zero rather than blown up to a unit column of
/// rounding errors (`zero`).
struct ColumnScales {
  Eigen::VectorXd norms;
  std::vector<bool> zero;
};
ColumnScales columnScales(const Eigen::MatrixXd& x) {
  const double negligible = negligibleColumnNorm(x.rows());
  ColumnScales s{x.colwise().norm().transpose(), std::vector<bool>(static_cast<std::size_t>(x.cols()))};
  for (Eigen::Index j = 0; j < x.cols(); ++j) {
    if (!(s.norms(j) > negligible)) {
      s.norms(j) = 1.0;
      s.zero[static_cast<std::size_t>(j)] = true;
    }
  }
  return s;
}

/// Rows `rows` (every row when empty) of [x scaled, y]: [first, first + count) of them.
Eigen::MatrixXd scaledRows(const Eigen::MatrixXd& x, const Eigen::VectorXd& y, const ColumnScales& s,
                           const std::vector<Eigen::Index>& rows, Eigen::Index first, Eigen::Index count) {
  Eigen::MatrixXd a(count, x.cols() + 1);
  const auto copy = [&](const auto& from, auto&& to) {
    if (rows.empty()) {
      to = from.segment(first, count);
    } else {
      for (Eigen::Index k = 0; k < count; ++k) to(k) = from(rows[static_cast<std::size_t>(first + k)]);
    }
  };
  for (Eigen::Index j = 0; j < x.cols(); ++j) {
    if (s.zero[static_cast<std::size_t>(j)]) {
      a.col(j).setZero();
    } else {
      copy(x.col(j), a.col(j));
      a.col(j) /= s.norms(j);
    }
  }
  copy(y, a.col(x.cols()));
  return a;
}

/// A tall matrix of `n` rows in blocks of rows that stay in cache (`block(first, count)` gives
/// them), each reduced to its triangle, then the triangles stacked and reduced (a tall-skinny
/// QR): the same triangle up to rounding and the rows' signs, without sweeping every
/// Householder reflection over all the rows, and without a copy of all of them.
template <class Block>
Eigen::MatrixXd reduceInBlocks(Eigen::Index n, Eigen::Index columns, const Block& block) {
  const auto blocks = static_cast<std::size_t>((n + kBlockRows - 1) / kBlockRows);
  const auto rowsOf = [&](std::size_t b) {
    return std::min(kBlockRows, n - static_cast<Eigen::Index>(b) * kBlockRows);
  };
  // Each block's triangle (as many rows as the block has, up to the columns) in its own rows of
  // the stack, the blocks side by side.
  std::vector<Eigen::Index> at(blocks + 1, 0);
  for (std::size_t b = 0; b < blocks; ++b) at[b + 1] = at[b] + std::min(rowsOf(b), columns);
  Eigen::MatrixXd stacked(at.back(), columns);
  inParallel(blocks, [&](std::size_t b) {
    stacked.middleRows(at[b], at[b + 1] - at[b]) =
        reduceRows(block(static_cast<Eigen::Index>(b) * kBlockRows, rowsOf(b)));
  });
  return reduceRows(std::move(stacked));
}

/// Rows up to which a tall problem is copied whole before it is reduced (reduceSparseRows).
constexpr Eigen::Index kSparseCheckedRows = 16 * kBlockRows;

bool tall(Eigen::Index rows, Eigen::Index columns) { return rows > 4 * kBlockRows && rows > 8 * columns; }

/// The triangle R of the Householder QR of [x scaled, y] over `rows` (every row when empty):
/// the least-squares problem of those rows in p + 1 numbers per row. Q is orthogonal, so the
/// problem R[:, :p] b ~ R[:, p] has the same solutions, and the same singular values, as
/// x b ~ y; triangles of row blocks stacked and reduced again give the triangle of their union.
/// A tall problem's rows are scaled block by block as they are reduced: a copy of all of them
/// per fit cost as much as the arithmetic at 1e5 readings (the kernel handing out its memory).
Eigen::MatrixXd triangleOf(const Eigen::MatrixXd& x, const Eigen::VectorXd& y, const ColumnScales& s,
                           const std::vector<Eigen::Index>& rows = {}) {
  const Eigen::Index n = rows.empty() ? x.rows() : static_cast<Eigen::Index>(rows.size());
  const auto block = [&](Eigen::Index first, Eigen::Index count) { return scaledRows(x, y, s, rows, first, count); };
  // (Rows of a few thousand are copied whole: reduceRows sees whether they are zero in most
  // columns, as several runs in one fit are.)
  return tall(n, x.cols() + 1) && n > kSparseCheckedRows ? reduceInBlocks(n, x.cols() + 1, block)
                                                         : reduceRows(block(0, n));
}

/// The least-squares solution of a triangle in x's units (0 for a numerically zero column), of
/// least norm when columns are dependent, with the decomposition that found it (of the scaled
/// columns).
struct TriangleSolution {
  Eigen::VectorXd coefficients;
  Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd> cod;
};
TriangleSolution solveTriangle(const Eigen::MatrixXd& t, const ColumnScales& s) {
  const Eigen::Index p = t.cols() - 1;
  // The complete orthogonal decomposition gives the least-squares solution of least norm even
  // when columns are dependent (column-pivoting QR's basic solution then misses the minimum).
  // The threshold is set before the decomposition: compute() builds Z for the rank it sees
  // then, and a threshold set afterwards changes rank() alone, so that solve() would apply
  // Householder coefficients of Z that were never computed (uninitialised memory).
  TriangleSolution out{Eigen::VectorXd(), Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd>(t.rows(), p)};
  out.cod.setThreshold(1e-10);
  out.cod.compute(t.leftCols(p));
  out.coefficients = out.cod.solve(t.col(p)).cwiseQuotient(s.norms);
  for (Eigen::Index j = 0; j < p; ++j) {
    if (s.zero[static_cast<std::size_t>(j)]) out.coefficients(j) = 0.0;
  }
  return out;
}

/// The triangle of a's Householder QR, in place.
Eigen::MatrixXd householderTriangle(Eigen::MatrixXd& a) {
  const Eigen::Index m = std::min(a.rows(), a.cols());
  Eigen::HouseholderQR<Eigen::Ref<Eigen::MatrixXd>> qr(a);
  Eigen::MatrixXd t = a.topRows(m).triangularView<Eigen::Upper>();
  return t;
}

/// The triangle of `a` where its rows are zero in most columns (several runs in one fit: a
/// run's own columns are zero on the other runs' rows): the rows grouped by their first
/// nonzero column, each group's rows reduced over the columns they touch, and the groups'
/// triangles stacked and reduced. Rows are not reordered within a group; a group closes once
/// it has four times as many rows as columns it touches. Nothing where that saves less than
/// half the arithmetic of reducing every row over every column.
std::optional<Eigen::MatrixXd> reduceSparseRows(const Eigen::MatrixXd& a) {
  const Eigen::Index n = a.rows(), m = a.cols();
  if (n <= kBlockRows || n > kSparseCheckedRows || m < 16) return std::nullopt;
  // Mostly nonzero (a run of its own): nothing to gain, and nothing spent beyond this count.
  if (2 * (a.array() == 0.0).count() < n * m) return std::nullopt;
  std::vector<Eigen::Index> first(static_cast<std::size_t>(n), m);
  Eigen::Index unset = n;
  for (Eigen::Index j = 0; j < m && unset > 0; ++j) {
    for (Eigen::Index i = 0; i < n; ++i) {
      auto& f = first[static_cast<std::size_t>(i)];
      if (f == m && a(i, j) != 0.0) {
        f = j;
        --unset;
      }
    }
  }
  std::vector<Eigen::Index> order(static_cast<std::size_t>(n));
  std::iota(order.begin(), order.end(), Eigen::Index{0});
  std::stable_sort(order.begin(), order.end(), [&](Eigen::Index x, Eigen::Index y) {
    return first[static_cast<std::size_t>(x)] < first[static_cast<std::size_t>(y)];
  });
  struct Group {
    std::vector<Eigen::Index> rows, columns;
  };
  std::vector<Group> groups;
  std::vector<char> touched(static_cast<std::size_t>(m), 0);
  Group group;
  double sparse_cost = 0.0;
  // A group closed: its reduction's cost, and that of its triangle's rows in the stack's.
  const auto close = [&] {
    if (group.rows.empty()) return;
    const auto rows = static_cast<double>(group.rows.size()), columns = static_cast<double>(group.columns.size());
    sparse_cost += rows * columns * columns + std::min(rows, columns) * static_cast<double>(m * m);
    for (const Eigen::Index j : group.columns) touched[static_cast<std::size_t>(j)] = 0;
    std::sort(group.columns.begin(), group.columns.end());
    groups.push_back(std::move(group));
    group = Group{};
  };
  for (const Eigen::Index i : order) {
    group.rows.push_back(i);
    for (Eigen::Index j = first[static_cast<std::size_t>(i)]; j < m; ++j) {
      if (a(i, j) != 0.0 && !touched[static_cast<std::size_t>(j)]) {
        touched[static_cast<std::size_t>(j)] = 1;
        group.columns.push_back(j);
      }
    }
    const auto rows = static_cast<Eigen::Index>(group.rows.size()),
               columns = static_cast<Eigen::Index>(group.columns.size());
    if (rows >= 4 * columns || rows >= kBlockRows) close();
  }
  close();
  if (!(sparse_cost < 0.5 * static_cast<double>(n) * static_cast<double>(m * m))) return std::nullopt;
  std::vector<Eigen::MatrixXd> triangles(groups.size());
  inParallel(groups.size(), [&](std::size_t g) {
    Eigen::MatrixXd part = a(groups[g].rows, groups[g].columns);
    triangles[g] = householderTriangle(part);
  });
  Eigen::Index stacked_rows = 0;
  for (const auto& t : triangles) stacked_rows += t.rows();
  Eigen::MatrixXd stacked = Eigen::MatrixXd::Zero(stacked_rows, m);
  Eigen::Index at = 0;
  for (std::size_t g = 0; g < groups.size(); ++g) {
    stacked(Eigen::seqN(at, triangles[g].rows()), groups[g].columns) = triangles[g];
    at += triangles[g].rows();
  }
  return householderTriangle(stacked);
}

}  // namespace

Eigen::MatrixXd reduceRows(Eigen::MatrixXd a) {
  if (auto t = reduceSparseRows(a)) return std::move(*t);
  if (tall(a.rows(), a.cols())) {
    return reduceInBlocks(a.rows(), a.cols(), [&](Eigen::Index first, Eigen::Index count) {
      return Eigen::MatrixXd(a.middleRows(first, count));
    });
  }
  return householderTriangle(a);
}

LeastSquares leastSquares(const Eigen::MatrixXd& x, const Eigen::VectorXd& y, bool standard_errors) {
  LeastSquares f;
  if (x.cols() == 0) {
    f.residual = y;
    f.rss = y.squaredNorm();
    return f;
  }
  const ColumnScales scales = columnScales(x);
  const TriangleSolution solution = solveTriangle(triangleOf(x, y, scales), scales);
  const auto& cod = solution.cod;
  f.rank = static_cast<int>(cod.rank());
  f.coefficients = solution.coefficients;
  for (int k = 0; k < f.rank; ++k) f.independent.push_back(cod.colsPermutation().indices()(k));
  f.residual = y - x * f.coefficients;
  f.rss = f.residual.squaredNorm();
  f.standard_error = Eigen::VectorXd::Zero(x.cols());
  const Eigen::Index dof = x.rows() - f.rank;
  if (standard_errors && dof > 0 && f.rank == x.cols()) {
    // At full rank the decomposition's T is the column-pivoting QR's R (no Z is applied), and
    // x's scaled columns have the triangle's R^T R as their Gram matrix.
    const Eigen::MatrixXd r = cod.matrixT().topLeftCorner(f.rank, f.rank).triangularView<Eigen::Upper>();
    const Eigen::MatrixXd rinv = r.triangularView<Eigen::Upper>().solve(Eigen::MatrixXd::Identity(f.rank, f.rank));
    const Eigen::MatrixXd covariance_scaled = rinv * rinv.transpose();
    const double s2 = f.rss / static_cast<double>(dof);
    const auto& order = cod.colsPermutation().indices();
    f.covariance.resize(x.cols(), x.cols());
    for (Eigen::Index a = 0; a < f.rank; ++a) {
      for (Eigen::Index b = 0; b < f.rank; ++b) {
        f.covariance(order(a), order(b)) =
            s2 * covariance_scaled(a, b) / (scales.norms(order(a)) * scales.norms(order(b)));
      }
    }
    f.standard_error = f.covariance.diagonal().cwiseSqrt();
  }
  return f;
}

Eigen::MatrixXd orthonormalBasis(const Eigen::MatrixXd& x, const std::vector<Eigen::Index>& columns) {
  // Q = x R^-1 with R the triangle of x's tall-skinny QR (in blocks that stay in cache, as the
  // fits' triangles are made) is orthonormal to about the rounding times x's condition; one
  // Cholesky QR step (Q'Q = U'U, Q U^-1) takes it to the rounding. Blocked products throughout:
  // a Householder Q formed reflector by reflector sweeps all the rows once per column.
  Eigen::MatrixXd q = x(Eigen::all, columns);
  if (q.cols() == 0) return q;
  q.array().rowwise() /= q.colwise().norm().array();  // unit columns: R's diagonal is relative
  const Eigen::MatrixXd r = reduceRows(q);
  // A column within rounding of the others' span (not what a fit calls independent) has no
  // inverse to take: the Householder Q of the columns, formed in full, spans them then.
  const auto householder = [&] {
    const Eigen::HouseholderQR<Eigen::MatrixXd> qr(x(Eigen::all, columns));
    return Eigen::MatrixXd(qr.householderQ() * Eigen::MatrixXd::Identity(x.rows(), q.cols()));
  };
  if (r.rows() < q.cols() || !(r.diagonal().cwiseAbs().minCoeff() > 1e-13)) return householder();
  r.triangularView<Eigen::Upper>().solveInPlace<Eigen::OnTheRight>(q);
  const Eigen::LLT<Eigen::MatrixXd> gram(q.transpose() * q);
  if (gram.info() != Eigen::Success) return householder();
  gram.matrixU().solveInPlace<Eigen::OnTheRight>(q);
  return q;
}

HeldOut crossValidate(const Eigen::MatrixXd& x, const Eigen::VectorXd& y, const Eigen::VectorXi& fold) {
  HeldOut h;
  h.residual = Eigen::VectorXd::Zero(y.size());
  const int folds = fold.size() ? fold.maxCoeff() + 1 : 0;
  if (x.cols() == 0) {
    h.residual = y;
  } else {
    // Each fold's rows reduced to their triangle once; a fold's fit is the triangle of the
    // others' triangles stacked: the same solution as a fit of their rows, at the cost of one
    // pass over the readings for all folds together.
    const ColumnScales scales = columnScales(x);
    std::vector<std::vector<Eigen::Index>> rows(static_cast<std::size_t>(folds));
    for (Eigen::Index i = 0; i < y.size(); ++i) rows[static_cast<std::size_t>(fold(i))].push_back(i);
    // The folds side by side, each in rows of its own.
    std::vector<Eigen::MatrixXd> triangles(rows.size());
    inParallel(rows.size(), [&](std::size_t f) {
      triangles[f] = rows[f].empty() ? Eigen::MatrixXd(0, x.cols() + 1) : triangleOf(x, y, scales, rows[f]);
    });
    inParallel(rows.size(), [&](std::size_t fold_index) {
      const int f = static_cast<int>(fold_index);
      const auto& test = rows[fold_index];
      if (test.empty()) return;
      Eigen::Index stacked_rows = 0;
      for (int g = 0; g < folds; ++g) stacked_rows += g == f ? 0 : triangles[static_cast<std::size_t>(g)].rows();
      Eigen::MatrixXd stacked(stacked_rows, x.cols() + 1);
      Eigen::Index at = 0;
      for (int g = 0; g < folds; ++g) {
        if (g == f) continue;
        const auto& t = triangles[static_cast<std::size_t>(g)];
        stacked.middleRows(at, t.rows()) = t;
        at += t.rows();
      }
      const Eigen::VectorXd b = solveTriangle(reduceRows(std::move(stacked)), scales).coefficients;
      for (Eigen::Index i : test) h.residual(i) = y(i) - x.row(i).dot(b);
    });
  }
  h.rms = std::sqrt(h.residual.squaredNorm() / static_cast<double>(std::max<Eigen::Index>(1, y.size())));
  h.peak = h.residual.size() ? h.residual.cwiseAbs().maxCoeff() : 0.0;
  return h;
}

double rmsOf(const Eigen::VectorXd& r) {
  return r.size() ? std::sqrt(r.squaredNorm() / static_cast<double>(r.size())) : 0.0;
}

std::vector<double> distinct(const Eigen::VectorXd& v) {
  std::vector<double> s;
  for (const double x : v) {
    if (!std::isnan(x)) s.push_back(x);
  }
  std::sort(s.begin(), s.end());
  s.erase(std::unique(s.begin(), s.end(), [](double a, double b) { return std::abs(a - b) < 1e-9; }), s.end());
  return s;
}

}  // namespace mtcal::processing::detail

namespace mtcal::processing::detail {

namespace {
constexpr std::string_view kScopeSeparator = ": ";
}

std::string baseName(const std::string& variable) {
  const auto at = variable.rfind(kScopeSeparator);
  return at == std::string::npos ? variable : variable.substr(at + kScopeSeparator.size());
}

std::string scopeOf(const std::string& variable) {
  const auto at = variable.rfind(kScopeSeparator);
  return at == std::string::npos ? std::string() : variable.substr(0, at);
}

std::string scopedName(const std::string& source, const std::string& variable) {
  return source + std::string(kScopeSeparator) + variable;
}

}  // namespace mtcal::processing::detail
