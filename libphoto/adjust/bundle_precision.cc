// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/adjust/bundle_precision.h"

#include <ceres/cost_function.h>
#include <ceres/crs_matrix.h>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <Eigen/SparseCore>
#include <algorithm>
#include <map>
#include <unordered_map>

#include "libphoto/adjust/dense_cholesky.h"
#include "libphoto/adjust/jacobian.h"
#include "libphoto/base/parallel.h"

namespace aerotri {
namespace internal {
namespace {

using RowSparse = Eigen::SparseMatrix<double, Eigen::RowMajor, int>;

using RowView = Eigen::Map<const RowSparse>;

// Ceres's Jacobian seen as an Eigen row-major matrix, without a copy: at
// 1.2 million observations (513 photos) it is 40 million entries, and a
// copy through triplets held three of it at once (1.6 GB).
RowView View(const ceres::CRSMatrix& crs) {
  return RowView(crs.num_rows, crs.num_cols, static_cast<int>(crs.values.size()), crs.rows.data(), crs.cols.data(),
                 crs.values.data());
}

// Rows of a row-major matrix split into the columns [c0, c0+3) (dense,
// rows x 3) and the columns from `first` on (dense over the listed columns
// `cols`, which the function fills in ascending order).
void SplitRows(const RowView& j, const std::vector<int>& rows, int c0, int first, Eigen::MatrixXd* a,
               std::vector<int>* cols, Eigen::MatrixXd* b) {
  cols->clear();
  for (int r : rows) {
    for (RowView::InnerIterator it(j, r); it; ++it) {
      if (it.col() >= first) cols->push_back(it.col() - first);
    }
  }
  std::sort(cols->begin(), cols->end());
  cols->erase(std::unique(cols->begin(), cols->end()), cols->end());
  auto index = [&](int c) { return std::lower_bound(cols->begin(), cols->end(), c) - cols->begin(); };
  a->setZero(static_cast<Eigen::Index>(rows.size()), 3);
  b->setZero(static_cast<Eigen::Index>(rows.size()), static_cast<Eigen::Index>(cols->size()));
  for (size_t k = 0; k < rows.size(); ++k) {
    for (RowView::InnerIterator it(j, rows[k]); it; ++it) {
      if (it.col() >= first) {
        (*b)(k, index(it.col() - first)) = it.value();
      } else if (it.col() >= c0 && it.col() < c0 + 3) {
        (*a)(k, it.col() - c0) = it.value();
      }
    }
  }
}

// The rows [r0, r1).
void SplitRows(const RowView& j, int r0, int r1, int c0, int first, Eigen::MatrixXd* a, std::vector<int>* cols,
               Eigen::MatrixXd* b) {
  std::vector<int> rows;
  for (int r = r0; r < r1; ++r) rows.push_back(r);
  SplitRows(j, rows, c0, first, a, cols, b);
}

Eigen::MatrixXd Gather(const Eigen::MatrixXd& m, const std::vector<int>& rows, const std::vector<int>& cols) {
  Eigen::MatrixXd out(rows.size(), cols.size());
  for (size_t a = 0; a < rows.size(); ++a) {
    for (size_t b = 0; b < cols.size(); ++b) out(a, b) = m(rows[a], cols[b]);
  }
  return out;
}

// Columns of the 3 rows of T for one point, with their values.
struct PointCoupling {
  std::vector<int> rows;  // the rows of J that hold the point
  std::vector<int> cols;  // reduced columns
  Eigen::MatrixXd t;      // 3 x cols: V_p⁻¹ W_p
  Eigen::Matrix3d v_inv = Eigen::Matrix3d::Zero();  // V_p⁻¹, or its pseudo-inverse
  bool undetermined = false;                        // V_p singular (rays parallel)
};

// S⁻¹ of a symmetric positive definite S, in place, through S = L Lᵀ: L
// over S's lower triangle, L⁻¹ by column blocks (each block's trailing
// triangle only, nc³/3), then S⁻¹ = L⁻ᵀ L⁻¹ by tiles of the lower triangle
// (nc³/3) over S, both on `threads` threads; about a quarter of the work of
// solving against the identity. Two n x n matrices at most (S and L⁻¹)
// where a copy of S for the factor and another for the inverse made four:
// at 1,000 photos (6,000 reduced parameters) each is 288 MB.
bool InverseByCholesky(Eigen::MatrixXd* s_inout, int threads) {
  Eigen::MatrixXd& s = *s_inout;
  // In place: S's lower triangle becomes L.
  if (!CholeskyInPlace(&s, ThreadCount(threads))) return false;
  const Eigen::MatrixXd& l = s;
  const Eigen::Index n = s.rows();
  const Eigen::Index b = 96;
  const Eigen::Index blocks = (n + b - 1) / b;
  Eigen::MatrixXd l_inv = Eigen::MatrixXd::Zero(n, n);
  const unsigned t = ThreadCount(threads);
  ParallelFor(static_cast<std::size_t>(blocks), t, [&](std::size_t k) {
    const Eigen::Index c0 = static_cast<Eigen::Index>(k) * b;
    const Eigen::Index w = std::min(b, n - c0);
    const Eigen::Index m = n - c0;
    Eigen::MatrixXd x = Eigen::MatrixXd::Identity(m, w);
    l.block(c0, c0, m, m).triangularView<Eigen::Lower>().solveInPlace(x);
    l_inv.block(c0, c0, m, w) = x;
  });
  // L is no longer needed: S⁻¹ overwrites it.
  Eigen::MatrixXd* inverse = s_inout;
  std::vector<std::pair<Eigen::Index, Eigen::Index>> tiles;
  for (Eigen::Index i = 0; i < blocks; ++i) {
    for (Eigen::Index j = 0; j <= i; ++j) tiles.emplace_back(i, j);
  }
  ParallelFor(tiles.size(), t, [&](std::size_t k) {
    const Eigen::Index r0 = tiles[k].first * b, c0 = tiles[k].second * b;
    const Eigen::Index wr = std::min(b, n - r0), wc = std::min(b, n - c0);
    // Rows of L⁻¹ below r0 only: above them column r0.. is zero.
    const Eigen::MatrixXd tile =
        l_inv.block(r0, r0, n - r0, wr).transpose() * l_inv.block(r0, c0, n - r0, wc);
    inverse->block(r0, c0, wr, wc) = tile;
    inverse->block(c0, r0, wc, wr) = tile.transpose();
  });
  return inverse->allFinite();
}

}  // namespace

namespace {

// Jrᵀ Jr of the reduced columns (from n3 on), row by row (a row holds at
// most a camera's, its intrinsics' and a prior's few columns): no
// column-major copy of J.
void AddReducedProduct(const RowView& j, int n3, Eigen::MatrixXd* s_out) {
  Eigen::MatrixXd& s = *s_out;
  // Jrᵀ Jr row by row (a row holds at most a camera's, its intrinsics'
  // and a prior's few columns): no column-major copy of J.
  std::vector<std::pair<int, double>> reduced;
  for (int r = 0; r < j.rows(); ++r) {
    reduced.clear();
    for (RowView::InnerIterator it(j, r); it; ++it) {
      if (it.col() >= n3) reduced.emplace_back(it.col() - n3, it.value());
    }
    for (const auto& [a, va] : reduced) {
      for (const auto& [b, vb] : reduced) s(a, b) += va * vb;
    }
  }
}

// Each point eliminated: V_p and W_p from the rows of J that hold it,
// V_p⁻¹ (a pseudo-inverse where its rays are nearly parallel) and
// T_p = V_p⁻¹ W_p kept, S -= W_pᵀ T_p.
//
// Two passes on every thread, no copy of S: the points' couplings first,
// in shares of points; then S's update, each thread owning a range of S's
// columns (cut where the work, Σ over the points of their columns, halves)
// and writing only there, for every point. W_pᵀ T_p = T_pᵀ V_p T_p (also
// with the pseudo-inverse: V⁺ V V⁺ = V⁺), so the second pass needs only T_p
// and V_p. Before, each thread subtracted into a copy of S of its own (two
// 76 MB copies at 513 photos), and beyond 4,000 columns, where a copy costs
// 128 MB or more, the elimination ran on one thread.
std::vector<PointCoupling> EliminatePoints(const RowView& j, int np, int n3, int threads, Eigen::MatrixXd* s_out,
                                           int* undetermined_points) {
  Eigen::MatrixXd& s = *s_out;
  const int nc = static_cast<int>(s.cols());
  std::vector<std::vector<int>> rows_of_point(np);
  for (int r = 0; r < j.rows(); ++r) {
    for (RowView::InnerIterator it(j, r); it; ++it) {
      if (it.col() < n3) {
        rows_of_point[it.col() / 3].push_back(r);
        break;
      }
    }
  }
  std::vector<PointCoupling> coupling(np);
  std::vector<Eigen::Matrix3d> v(np);
  const unsigned t = std::max(1u, std::min(ThreadCount(threads), static_cast<unsigned>(std::max(np, 1))));
  std::vector<int> undetermined(t, 0);
  ParallelFor(t, t, [&](std::size_t th) {
    Eigen::MatrixXd a, b;
    const int begin = static_cast<int>(static_cast<long>(np) * th / t);
    const int end = static_cast<int>(static_cast<long>(np) * (th + 1) / t);
    for (int pt = begin; pt < end; ++pt) {
      PointCoupling& c = coupling[pt];
      c.rows = std::move(rows_of_point[pt]);
      SplitRows(j, c.rows, 3 * pt, n3, &a, &c.cols, &b);
      const Eigen::Matrix3d vp = a.transpose() * a;
      v[pt] = vp;
      Eigen::FullPivLU<Eigen::Matrix3d> lu(vp);
      if (lu.rank() < 3) {
        // Rays (nearly) parallel: the point slides along them. Its
        // undetermined direction is one the residuals do not see (to first
        // order), so the pseudo-inverse gives the cameras' marginal exactly
        // (W's columns lie in V's range); the point itself has no finite
        // covariance and is left out of the points' (point_undetermined).
        const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(vp);
        const Eigen::Vector3d values = eigen.eigenvalues();
        const double floor = 1e-10 * std::max(values.maxCoeff(), 0.0);
        Eigen::Vector3d inv = Eigen::Vector3d::Zero();
        for (int k = 0; k < 3; ++k) inv(k) = values(k) > floor ? 1.0 / values(k) : 0.0;
        c.v_inv = eigen.eigenvectors() * inv.asDiagonal() * eigen.eigenvectors().transpose();
        c.undetermined = true;
        ++undetermined[th];
      } else {
        c.v_inv = lu.inverse();
      }
      c.t = c.v_inv * (a.transpose() * b);
    }
  });
  for (int u : undetermined) *undetermined_points += u;
  // The columns' cut: each column's work is the number of columns beside it
  // in the points that hold it.
  std::vector<double> work(nc + 1, 0.0);
  for (const PointCoupling& c : coupling) {
    for (int col : c.cols) work[col + 1] += static_cast<double>(c.cols.size());
  }
  for (int col = 0; col < nc; ++col) work[col + 1] += work[col];
  std::vector<int> cut(t + 1, nc);
  cut[0] = 0;
  for (unsigned th = 1; th < t; ++th) {
    cut[th] = static_cast<int>(std::lower_bound(work.begin(), work.end(), work[nc] * th / t) - work.begin());
    cut[th] = std::clamp(cut[th], cut[th - 1], nc);
  }
  ParallelFor(t, t, [&](std::size_t th) {
    const int lo = cut[th], hi = cut[th + 1];
    if (lo >= hi) return;
    Eigen::Matrix<double, 3, Eigen::Dynamic> vt;
    for (int pt = 0; pt < np; ++pt) {
      const PointCoupling& c = coupling[pt];
      const auto first = std::lower_bound(c.cols.begin(), c.cols.end(), lo);
      const auto last = std::lower_bound(first, c.cols.end(), hi);
      if (first == last) continue;
      vt.noalias() = v[pt] * c.t;
      for (auto y = first; y != last; ++y) {
        const Eigen::Index yk = y - c.cols.begin();
        double* column = s.col(*y).data();
        const double t0 = c.t(0, yk), t1 = c.t(1, yk), t2 = c.t(2, yk);
        for (size_t x = 0; x < c.cols.size(); ++x) {
          column[c.cols[x]] -= vt(0, x) * t0 + vt(1, x) * t1 + vt(2, x) * t2;
        }
      }
    }
  });
  return coupling;
}

// Each row of J's observation group (an index into p.groups; -1: none).
std::vector<signed char> RowGroups(const PrecisionProblem& p, int num_rows) {
  ceres::Problem& problem = *p.problem;
  std::unordered_map<ceres::ResidualBlockId, int> first_row;
  first_row.reserve(p.adjusted.size());
  int row = 0;
  for (ceres::ResidualBlockId id : p.adjusted) {
    first_row.emplace(id, row);
    row += problem.GetCostFunctionForResidualBlock(id)->num_residuals();
  }
  std::vector<signed char> group(num_rows, -1);
  for (size_t g = 0; g < p.groups.size(); ++g) {
    for (const auto& [id, mask] : p.groups[g].rows) {
      const auto it = first_row.find(id);
      if (it == first_row.end()) continue;
      const int nr = problem.GetCostFunctionForResidualBlock(id)->num_residuals();
      for (int q = 0; q < nr; ++q) {
        if (mask & (1u << q)) group[it->second + q] = static_cast<signed char>(g);
      }
    }
  }
  return group;
}

// Each point's covariance, and each group's residuals and leverages (the
// diagonal of J Σ Jᵀ over its rows). For the rows of point p, with G_p the
// reduced covariance over the point's columns and Σ_pU = −T_p G_p:
//   h = a Σ_pp aᵀ − 2 a T_p G_p bᵀ + b G_p bᵀ,
// G_p gathered and T_p G_p formed once for the point and all its rows
// (Σ_pp = V_p⁻¹ + T_p G_p T_pᵀ is the point's covariance); b's few nonzero
// columns taken as they are. Rows that hold no point: b Σ_UU bᵀ.
void PointsAndGroups(const PrecisionProblem& p, const RowView& j, int n3, const std::vector<PointCoupling>& coupling,
                     const std::vector<double>& residuals, PrecisionSolution* solution) {
  PrecisionSolution& out = *solution;
  const int np = static_cast<int>(coupling.size());
  const size_t ng = p.groups.size();
  const std::vector<signed char> row_group = RowGroups(p, static_cast<int>(j.rows()));
  const unsigned t = ThreadCount(p.num_threads);
  std::vector<std::vector<GroupRedundancy>> part(t, std::vector<GroupRedundancy>(ng));
  auto add = [&](std::vector<GroupRedundancy>& sums, int r, double h) {
    GroupRedundancy& g = sums[row_group[r]];
    ++g.rows;
    g.sum_squares += residuals[r] * residuals[r];
    g.leverage += h;
  };
  out.point_cov.resize(np);
  out.point_undetermined.resize(np);
  ParallelFor(t, t, [&](std::size_t th) {
    std::vector<GroupRedundancy>& sums = part[th];
    Eigen::MatrixXd a, b, g, tg;
    std::vector<int> cols, nz;
    for (int pt = static_cast<int>(static_cast<long>(np) * th / t); pt < static_cast<long>(np) * (th + 1) / t;
         ++pt) {
      const PointCoupling& c = coupling[pt];
      out.point_undetermined[pt] = c.undetermined ? 1 : 0;
      Eigen::Matrix3d& cov = out.point_cov[pt];
      cov = c.v_inv;
      if (!c.cols.empty()) {
        g = Gather(out.reduced_cov, c.cols, c.cols);
        tg.noalias() = c.t * g;
        cov.noalias() += tg * c.t.transpose();
      }
      if (ng == 0) continue;
      bool any = false;
      for (int r : c.rows) any = any || row_group[r] >= 0;
      if (!any) continue;
      SplitRows(j, c.rows, 3 * pt, n3, &a, &cols, &b);  // cols: c.cols
      for (size_t k = 0; k < c.rows.size(); ++k) {
        const int r = c.rows[k];
        if (row_group[r] < 0) continue;
        const Eigen::RowVector3d ar = a.row(k);
        double h = ar * cov * ar.transpose();
        nz.clear();
        for (int x = 0; x < b.cols(); ++x) {
          if (b(k, x) != 0.0) nz.push_back(x);
        }
        if (!nz.empty()) {
          const Eigen::RowVectorXd atg = ar * tg;
          for (int x : nz) {
            h -= 2.0 * atg(x) * b(k, x);
            for (int y : nz) h += b(k, x) * g(x, y) * b(k, y);
          }
        }
        add(sums, r, h);
      }
    }
  });
  // The rows that hold no point.
  const int rows = static_cast<int>(j.rows());
  ParallelFor(t, t, [&](std::size_t th) {
    std::vector<GroupRedundancy>& sums = part[th];
    std::vector<int> cols;
    std::vector<double> values;
    for (int r = static_cast<int>(static_cast<long>(rows) * th / t); r < static_cast<long>(rows) * (th + 1) / t;
         ++r) {
      if (row_group[r] < 0) continue;
      cols.clear();
      values.clear();
      bool point = false;
      for (RowView::InnerIterator it(j, r); it; ++it) {
        if (it.col() < n3) {
          point = true;
          break;
        }
        cols.push_back(it.col() - n3);
        values.push_back(it.value());
      }
      if (point) continue;
      double h = 0.0;
      for (size_t x = 0; x < cols.size(); ++x) {
        for (size_t y = 0; y < cols.size(); ++y) h += values[x] * out.reduced_cov(cols[x], cols[y]) * values[y];
      }
      add(sums, r, h);
    }
  });
  out.groups.assign(ng, GroupRedundancy());
  for (const std::vector<GroupRedundancy>& sums : part) {
    for (size_t k = 0; k < ng; ++k) {
      out.groups[k].rows += sums[k].rows;
      out.groups[k].sum_squares += sums[k].sum_squares;
      out.groups[k].leverage += sums[k].leverage;
    }
  }
}

// Points triangulated with the cameras held (independent check points);
// false when their Jacobian cannot be evaluated.
bool CheckCovariances(const PrecisionProblem& p, ceres::Problem::EvaluateOptions eval, PrecisionSolution* solution) {
  ceres::Problem& problem = *p.problem;
  PrecisionSolution& out = *solution;
  ceres::CRSMatrix crs;
  std::vector<double*> check_blocks;
  std::vector<ceres::ResidualBlockId> ids;
  std::vector<int> first_row;
  for (const auto& rows : p.checks) {
    check_blocks.push_back(rows.position);
    first_row.push_back(2 * static_cast<int>(ids.size()));
    ids.insert(ids.end(), rows.ids.begin(), rows.ids.end());
  }
  first_row.push_back(2 * static_cast<int>(ids.size()));
  const int nk3 = 3 * static_cast<int>(check_blocks.size());
  check_blocks.insert(check_blocks.end(), p.reduced.begin(), p.reduced.end());
  eval.parameter_blocks = check_blocks;
  eval.residual_blocks = ids;
  if (!problem.Evaluate(eval, nullptr, nullptr, nullptr, &crs)) {
    out.note = "the check points' Jacobian could not be evaluated";
    return false;
  }
  const RowView jk = View(crs);
  for (size_t k = 0; k < p.checks.size(); ++k) {
    Eigen::MatrixXd a, b;
    std::vector<int> cols;
    SplitRows(jk, first_row[k], first_row[k + 1], 3 * static_cast<int>(k), nk3, &a, &cols, &b);
    const Eigen::Matrix3d ata_inv = (a.transpose() * a).inverse();
    Eigen::Matrix3d cov = ata_inv;
    if (!cols.empty()) {
      const Eigen::MatrixXd g = ata_inv * a.transpose() * b;
      cov += g * Gather(out.reduced_cov, cols, cols) * g.transpose();
    }
    out.check_cov.push_back(cov);
  }
  return true;
}

// Cofactors of the target marks' residuals; false when their Jacobian
// cannot be evaluated.
bool MarkCofactors(const PrecisionProblem& p, ceres::Problem::EvaluateOptions eval, const std::vector<double*>& blocks,
                   const std::vector<PointCoupling>& coupling, int n3, PrecisionSolution* solution) {
  ceres::Problem& problem = *p.problem;
  PrecisionSolution& out = *solution;
  ceres::CRSMatrix crs;
  std::vector<ceres::ResidualBlockId> ids;
  for (const auto& rows : p.marks) ids.push_back(rows.ids.at(0));
  eval.parameter_blocks = blocks;
  eval.residual_blocks = ids;
  eval.apply_loss_function = false;
  std::vector<double> residuals;
  if (!problem.Evaluate(eval, nullptr, &residuals, nullptr, &crs)) {
    out.note = "the marks' Jacobian could not be evaluated";
    return false;
  }
  const RowView jm = View(crs);
  for (size_t m = 0; m < p.marks.size(); ++m) {
    const int pt = p.marks[m].point;
    const PointCoupling& c = coupling.at(pt);
    Eigen::MatrixXd a, b;
    std::vector<int> cols;
    SplitRows(jm, 2 * static_cast<int>(m), 2 * static_cast<int>(m) + 2, 3 * pt, n3, &a, &cols, &b);
    // g = a T_p − b over the union of both column sets.
    std::vector<int> all = c.cols;
    all.insert(all.end(), cols.begin(), cols.end());
    std::sort(all.begin(), all.end());
    all.erase(std::unique(all.begin(), all.end()), all.end());
    Eigen::MatrixXd g = Eigen::MatrixXd::Zero(2, static_cast<Eigen::Index>(all.size()));
    auto at = [&](int col) { return static_cast<int>(std::lower_bound(all.begin(), all.end(), col) - all.begin()); };
    const Eigen::MatrixXd at_p = a * c.t;
    for (size_t k = 0; k < c.cols.size(); ++k) g.col(at(c.cols[k])) += at_p.col(k);
    for (size_t k = 0; k < cols.size(); ++k) g.col(at(cols[k])) -= b.col(k);
    Eigen::Matrix2d q = a * c.v_inv * a.transpose();
    if (!all.empty()) q += g * Gather(out.reduced_cov, all, all) * g.transpose();
    MarkCofactor mc;
    mc.residual = Eigen::Vector2d(residuals[2 * m], residuals[2 * m + 1]);
    mc.qvv = Eigen::Vector2d(std::max(0.0, 1.0 - q(0, 0)), std::max(0.0, 1.0 - q(1, 1)));
    out.marks.push_back(mc);
  }
  return true;
}

// Each withheld point's one-step update (bundle_precision.h). `residuals`
// are the adjusted rows', in J's order.
void WithholdPoints(const PrecisionProblem& p, const RowView& j, int n3, const std::vector<double>& residuals,
                    PrecisionSolution* solution) {
  PrecisionSolution& out = *solution;
  const int nc = static_cast<int>(out.reduced_cov.rows());
  std::vector<int> want(n3 / 3, -1);
  for (size_t k = 0; k < p.withheld.size(); ++k) want.at(p.withheld[k]) = static_cast<int>(k);
  std::vector<std::vector<int>> rows(p.withheld.size());
  for (int r = 0; r < j.rows(); ++r) {
    for (RowView::InnerIterator it(j, r); it; ++it) {
      if (it.col() < n3) {
        if (want[it.col() / 3] >= 0) rows[want[it.col() / 3]].push_back(r);
        break;
      }
    }
  }
  // The reduced block of each column: a step is taken by whole blocks.
  auto block_of = [&](int col) {
    return static_cast<int>(std::upper_bound(out.reduced_offset.begin(), out.reduced_offset.end(), col) -
                            out.reduced_offset.begin()) - 1;
  };
  for (size_t k = 0; k < p.withheld.size(); ++k) {
    WithheldUpdate u;
    const int pt = p.withheld[k];
    Eigen::MatrixXd a, b;
    std::vector<int> touched;
    SplitRows(j, rows[k], 3 * pt, n3, &a, &touched, &b);
    Eigen::VectorXd r(static_cast<Eigen::Index>(rows[k].size()));
    for (size_t i = 0; i < rows[k].size(); ++i) r(i) = residuals[rows[k][i]];
    // Whole blocks: b's columns spread over them.
    for (int c : touched) {
      const int slot = block_of(c);
      const int end = slot + 1 < static_cast<int>(out.reduced_offset.size()) ? out.reduced_offset[slot + 1] : nc;
      for (int col = out.reduced_offset[slot]; col < end; ++col) u.cols.push_back(col);
    }
    std::sort(u.cols.begin(), u.cols.end());
    u.cols.erase(std::unique(u.cols.begin(), u.cols.end()), u.cols.end());
    Eigen::MatrixXd bw = Eigen::MatrixXd::Zero(b.rows(), static_cast<Eigen::Index>(u.cols.size()));
    for (size_t c = 0; c < touched.size(); ++c) {
      const auto at = std::lower_bound(u.cols.begin(), u.cols.end(), touched[c]) - u.cols.begin();
      bw.col(at) = b.col(static_cast<Eigen::Index>(c));
    }
    const Eigen::Matrix3d v = a.transpose() * a;
    const Eigen::MatrixXd w = a.transpose() * bw;  // 3 x s
    const Eigen::Vector3d g_p = a.transpose() * r;
    const Eigen::MatrixXd c = Gather(out.reduced_cov, u.cols, u.cols);
    const Eigen::LDLT<Eigen::MatrixXd> c_ldlt(c);
    if (u.cols.empty() || c_ldlt.info() != Eigen::Success) {
      u.note = "the point's cameras have no marginal covariance";
      out.withheld.push_back(u);
      continue;
    }
    const Eigen::MatrixXd c_inv = c_ldlt.solve(Eigen::MatrixXd::Identity(c.rows(), c.cols()));
    const Eigen::FullPivLU<Eigen::Matrix3d> v_lu(v);
    if (v_lu.rank() < 3) {
      u.note = "the point is not determined by its own rows";
      out.withheld.push_back(u);
      continue;
    }
    Eigen::MatrixXd m;   // the marginal information of s without the rows
    Eigen::VectorXd rhs;  // Δ_s = m⁻¹ rhs
    Eigen::Matrix3d v_kept = Eigen::Matrix3d::Zero();  // V without the prior (marks kept)
    Eigen::Vector3d g_kept = Eigen::Vector3d::Zero();
    if (p.withhold_marks) {
      const Eigen::MatrixXd t = v_lu.solve(w);  // V⁻¹ W
      m = c_inv - (bw.transpose() * bw - w.transpose() * t);
      rhs = bw.transpose() * r - t.transpose() * g_p;
    } else {
      // The prior's rows: those without a reduced column.
      Eigen::MatrixXd a_prior(0, 3);
      Eigen::VectorXd r_prior(0);
      for (Eigen::Index i = 0; i < a.rows(); ++i) {
        if (bw.row(i).isZero(0.0)) {
          a_prior.conservativeResize(a_prior.rows() + 1, 3);
          a_prior.row(a_prior.rows() - 1) = a.row(i);
          r_prior.conservativeResize(r_prior.size() + 1);
          r_prior(r_prior.size() - 1) = r(i);
        }
      }
      v_kept = v - a_prior.transpose() * a_prior;
      g_kept = g_p - a_prior.transpose() * r_prior;
      const Eigen::FullPivLU<Eigen::Matrix3d> kept_lu(v_kept);
      if (a_prior.rows() == 0 || kept_lu.rank() < 3) {
        u.note = a_prior.rows() == 0 ? "the point has no prior to withhold" : "the point's marks do not determine it";
        out.withheld.push_back(u);
        continue;
      }
      // S' = S − W'ᵀ(V'⁻¹ − V⁻¹)W; the reduced gradient gains the point's
      // old elimination term and loses the new one.
      const Eigen::MatrixXd t_old = v_lu.solve(w), t_new = kept_lu.solve(w);
      m = c_inv - w.transpose() * (t_new - t_old);
      rhs = -(t_old.transpose() * g_p - t_new.transpose() * g_kept);
      v_kept = kept_lu.inverse();  // from here on V'⁻¹
    }
    const Eigen::LLT<Eigen::MatrixXd> m_llt(m);
    if (m_llt.info() != Eigen::Success) {
      u.note = "the block without the point does not determine its cameras";
      out.withheld.push_back(u);
      continue;
    }
    u.delta = m_llt.solve(rhs);
    if (!p.withhold_marks) u.point_delta = -v_kept * (g_kept + w * u.delta);
    u.ok = u.delta.allFinite() && u.point_delta.allFinite();
    if (!u.ok) u.note = "the update is not finite";
    out.withheld.push_back(u);
  }
}

}  // namespace

PrecisionSolution SolvePrecision(const PrecisionProblem& p) {
  PrecisionSolution out;
  ceres::Problem& problem = *p.problem;
  const int np = static_cast<int>(p.points.size());
  const int n3 = 3 * np;
  int nc = 0;
  for (double* block : p.reduced) {
    out.reduced_offset.push_back(nc);
    nc += problem.ParameterBlockTangentSize(block);
  }
  std::vector<double*> blocks = p.points;
  blocks.insert(blocks.end(), p.reduced.begin(), p.reduced.end());

  ceres::Problem::EvaluateOptions eval;
  eval.parameter_blocks = blocks;
  eval.residual_blocks = p.adjusted;
  eval.apply_loss_function = true;
  eval.num_threads = std::max(1, p.num_threads);
  ceres::CRSMatrix crs_main;  // the adjusted rows' Jacobian (viewed by j)
  std::vector<double> adjusted_residuals;
  if (!EvaluateJacobian(problem, p.adjusted, blocks, p.num_threads, &adjusted_residuals, &crs_main)) {
    out.note = "the Jacobian could not be evaluated at the solution";
    return out;
  }
  const RowView j = View(crs_main);
  out.num_rows = static_cast<int>(j.rows());
  out.num_params = n3 + nc;
  // S = Jrᵀ Jr − Σ_p W_pᵀ V_p⁻¹ W_p. V_p and W_p are accumulated from the
  // rows of J that hold point p (a residual holds at most one point), never
  // as sparse products over all points: Eigen's pruned sparse product costs
  // a pass over every point column per column (hours at 100,000 points).
  Eigen::MatrixXd s = Eigen::MatrixXd::Zero(nc, nc);
  AddReducedProduct(j, n3, &s);
  const std::vector<PointCoupling> coupling =
      EliminatePoints(j, np, n3, p.num_threads, &s, &out.undetermined_points);

  if (nc > 0) {
    out.reduced_cov = std::move(s);
    if (!InverseByCholesky(&out.reduced_cov, p.num_threads)) {
      out.note = "the reduced normal equations are singular: the datum or some intrinsics are not determined";
      return out;
    }
    if (!out.reduced_cov.allFinite() || (out.reduced_cov.diagonal().array() <= 0.0).any()) {
      out.note = "the reduced normal equations are numerically singular";
      return out;
    }
  }

  PointsAndGroups(p, j, n3, coupling, adjusted_residuals, &out);
  if (!p.withheld.empty()) WithholdPoints(p, j, n3, adjusted_residuals, &out);

  if (!p.checks.empty() && !CheckCovariances(p, eval, &out)) return out;

  if (!p.marks.empty() && !MarkCofactors(p, eval, blocks, coupling, n3, &out)) return out;
  out.ok = true;
  return out;
}

}  // namespace internal
}  // namespace aerotri
