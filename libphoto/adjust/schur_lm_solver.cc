// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/adjust/schur_lm_solver.h"

#include <ceres/cost_function.h>
#include <ceres/loss_function.h>
#include <ceres/manifold.h>

#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <Eigen/Core>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <memory>
#include <stdexcept>
#include <unordered_map>

#include "libphoto/adjust/dense_cholesky.h"
#include "libphoto/adjust/dense_schur_solver.h"
#include "libphoto/adjust/jacobian.h"
#include "libphoto/adjust/sparse_cholesky.h"
#include "libphoto/base/parallel.h"

namespace aerotri {
namespace {

using Clock = std::chrono::steady_clock;
double Since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }
using RowMajor = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

// A varying block of the reduced system.
struct FBlock {
  double* x = nullptr;
  int ambient = 0;
  int tangent = 0;
  int col = 0;  // first column in the reduced system
  const ceres::Manifold* manifold = nullptr;
};

// One residual block: its parameters, each a point (-2), a reduced block
// (index) or held (-1).
struct Term {
  const ceres::CostFunction* cost = nullptr;
  const ceres::LossFunction* loss = nullptr;
  std::vector<double*> params;
  std::vector<int> kind;
  int rows = 0;
};
constexpr int kPoint = -2;
constexpr int kHeld = -1;

// The problem's structure, read once.
struct Structure {
  std::vector<FBlock> blocks;
  std::vector<double*> points;
  std::vector<Term> terms;           // varying terms: each point's together, then the rest
  std::vector<int> point_begin;      // terms of point p: [point_begin[p], point_begin[p + 1])
  int first_other = 0;               // terms without a point start here
  std::vector<Term> fixed;           // terms with nothing varying (their cost only)
  int n = 0;                         // reduced columns
  int num_residuals = 0;
};

// Reads the problem: false with the reason where the solver does not apply.
bool ReadStructure(ceres::Problem& problem, const std::vector<double*>& points, Structure* s, std::string* why_not) {
  std::unordered_map<const double*, int> point_of;
  std::vector<double*> candidates;
  for (double* p : points) {
    if (!problem.HasParameterBlock(p) || problem.IsParameterBlockConstant(p)) continue;
    if (problem.ParameterBlockSize(p) != 3 || problem.GetManifold(p) != nullptr) {
      *why_not = "a point block is not a plain 3-vector";
      return false;
    }
    point_of.emplace(p, static_cast<int>(candidates.size()));
    candidates.push_back(p);
  }
  std::vector<ceres::ResidualBlockId> ids;
  problem.GetResidualBlocks(&ids);
  std::unordered_map<const double*, int> block_of;
  std::vector<std::vector<Term>> by_point(candidates.size());
  std::vector<Term> others;
  std::vector<double*> params;
  for (ceres::ResidualBlockId id : ids) {
    Term t;
    problem.GetParameterBlocksForResidualBlock(id, &params);
    t.cost = problem.GetCostFunctionForResidualBlock(id);
    t.loss = problem.GetLossFunctionForResidualBlock(id);
    t.rows = t.cost->num_residuals();
    t.params = params;
    int point = -1, varying = 0;
    for (double* b : params) {
      if (auto it = point_of.find(b); it != point_of.end()) {
        if (point >= 0 && point != it->second) {
          *why_not = "a residual holds two points";
          return false;
        }
        point = it->second;
        t.kind.push_back(kPoint);
        ++varying;
        continue;
      }
      if (problem.IsParameterBlockConstant(b) || problem.ParameterBlockTangentSize(b) == 0) {
        t.kind.push_back(kHeld);
        continue;
      }
      auto [it, fresh] = block_of.emplace(b, static_cast<int>(s->blocks.size()));
      if (fresh) {
        FBlock f;
        f.x = b;
        f.ambient = problem.ParameterBlockSize(b);
        f.tangent = problem.ParameterBlockTangentSize(b);
        f.col = s->n;
        f.manifold = problem.GetManifold(b);
        s->n += f.tangent;
        s->blocks.push_back(f);
      }
      t.kind.push_back(it->second);
      ++varying;
    }
    if (varying == 0) {
      s->fixed.push_back(std::move(t));
      continue;
    }
    s->num_residuals += t.rows;
    (point >= 0 ? by_point[point] : others).push_back(std::move(t));
  }
  s->point_begin.push_back(0);
  for (size_t p = 0; p < candidates.size(); ++p) {
    if (by_point[p].empty()) continue;
    s->points.push_back(candidates[p]);
    for (Term& t : by_point[p]) s->terms.push_back(std::move(t));
    s->point_begin.push_back(static_cast<int>(s->terms.size()));
  }
  s->first_other = static_cast<int>(s->terms.size());
  for (Term& t : others) s->terms.push_back(std::move(t));
  return true;
}

// Where the reduced system's cells live. Dense: an n x n column-major
// matrix, its lower triangle used. Sparse: only the blocks that share a point
// or a residual, compressed by columns as CHOLMOD takes them (a diagonal
// block whole; its upper half is not read). Either way the cell of row block
// a and column block b (a at or after b; the blocks' order is their
// columns') holds, for column k of b, a's rows one after another from
// start + k * stride.
class ReducedLayout {
 public:
  struct Span {
    long start = 0;
    long stride = 0;
  };

  ReducedLayout(const Structure& s, bool sparse) : sparse_(sparse), n_(s.n) {
    const int nb = static_cast<int>(s.blocks.size());
    col_.resize(nb);
    for (int b = 0; b < nb; ++b) col_[b] = s.blocks[b].col;
    if (!sparse_) {
      size_ = static_cast<long>(n_) * n_;
      return;
    }
    // The row blocks at or after each column block that share a residual
    // or a point with it.
    std::vector<std::vector<int>> below(nb);
    for (int b = 0; b < nb; ++b) below[b].push_back(b);
    std::vector<int> blocks;
    const auto pair_up = [&](int first, int last) {
      blocks.clear();
      for (int i = first; i < last; ++i) {
        for (int kind : s.terms[i].kind) {
          if (kind >= 0) blocks.push_back(kind);
        }
      }
      std::sort(blocks.begin(), blocks.end());
      blocks.erase(std::unique(blocks.begin(), blocks.end()), blocks.end());
      for (size_t i = 0; i < blocks.size(); ++i) {
        for (size_t j = i + 1; j < blocks.size(); ++j) below[blocks[i]].push_back(blocks[j]);
      }
    };
    for (size_t p = 0; p + 1 < s.point_begin.size(); ++p) pair_up(s.point_begin[p], s.point_begin[p + 1]);
    for (int i = s.first_other; i < static_cast<int>(s.terms.size()); ++i) pair_up(i, i + 1);
    rows_of_.resize(nb);
    offset_of_.resize(nb);
    base_.resize(nb);
    height_.resize(nb);
    diagonal_.resize(n_);
    colptr_.assign(1, 0);
    long size = 0;
    for (int b = 0; b < nb; ++b) {
      std::vector<int>& rows = below[b];
      std::sort(rows.begin(), rows.end());
      rows.erase(std::unique(rows.begin(), rows.end()), rows.end());
      int height = 0;
      for (int a : rows) {
        offset_of_[b].push_back(height);
        height += s.blocks[a].tangent;
      }
      rows_of_[b] = std::move(rows);
      base_[b] = size;
      height_[b] = height;
      for (int k = 0; k < s.blocks[b].tangent; ++k) {
        diagonal_[col_[b] + k] = size + k;  // the column's first rows are its own block's
        for (int a : rows_of_[b]) {
          for (int i = 0; i < s.blocks[a].tangent; ++i) rowidx_.push_back(col_[a] + i);
        }
        size += height;
        if (size > std::numeric_limits<int>::max()) {
          throw std::length_error("the reduced system has more than 2^31 nonzeros");
        }
        colptr_.push_back(static_cast<int>(size));
      }
    }
    size_ = size;
  }

  bool sparse() const { return sparse_; }
  long size() const { return size_; }
  // The cell of row block a and column block b (a >= b; a block's cells
  // with itself are its diagonal block).
  Span Cell(int a, int b) const {
    if (!sparse_) return {static_cast<long>(col_[b]) * n_ + col_[a], n_};
    const std::vector<int>& rows = rows_of_[b];
    const auto it = std::lower_bound(rows.begin(), rows.end(), a);
    return {base_[b] + offset_of_[b][it - rows.begin()], height_[b]};
  }
  long Diagonal(int c) const { return sparse_ ? diagonal_[c] : static_cast<long>(c) * n_ + c; }
  // The pattern, compressed by columns (sparse only).
  const std::vector<int>& colptr() const { return colptr_; }
  const std::vector<int>& rows() const { return rowidx_; }

 private:
  bool sparse_ = false;
  int n_ = 0;
  long size_ = 0;
  std::vector<int> col_;
  std::vector<std::vector<int>> rows_of_, offset_of_;
  std::vector<long> base_, diagonal_;
  std::vector<int> height_, colptr_, rowidx_;
};

using internal::LossCorrector;

class Solver {
 public:
  Solver(const ceres::Solver::Options& options, Structure* s, bool sparse)
      : options_(options), s_(*s), threads_(ThreadCount(options.num_threads)), layout_(s_, sparse) {
    if (layout_.sparse()) {
      cholesky_ = std::make_unique<internal::SparseCholesky>(s_.n, layout_.colptr(), layout_.rows());
    }
    const int np = static_cast<int>(s_.points.size());
    // Thread ranges of points with about equal numbers of terms.
    ranges_.push_back(0);
    for (unsigned t = 1; t < threads_; ++t) {
      const int target = static_cast<int>(static_cast<long>(s_.first_other) * t / threads_);
      int p = ranges_.back();
      while (p < np && s_.point_begin[p] < target) ++p;
      ranges_.push_back(p);
    }
    ranges_.push_back(np);
    v_.resize(np);
    vinv_.resize(np);
    gx_.resize(np);
    dx_.resize(np);
    w_.resize(np);
    cols_.resize(np);
    plus_.resize(s_.blocks.size());
    Resize(&u_);
    gf_.resize(s_.n);
    s_t_.assign(threads_, Eigen::MatrixXd());
    b_t_.assign(threads_, Eigen::VectorXd());
    fixed_cost_ = 0.0;
    std::vector<double> r;
    for (const Term& t : s_.fixed) {
      r.resize(t.rows);
      if (t.cost->Evaluate(t.params.data(), r.data(), nullptr)) {
        fixed_cost_ += LossCorrector(t.loss, r.data(), t.rows).cost;
      }
    }
  }

  void Solve(ceres::Solver::Summary* summary) {
    const auto start = Clock::now();
    ceres::Solver::Summary& out = *summary;
    out = ceres::Solver::Summary();
    out.linear_solver_type_given = out.linear_solver_type_used =
        layout_.sparse() ? ceres::SPARSE_SCHUR : ceres::DENSE_SCHUR;
    out.jacobian_evaluation_time_in_seconds = out.linear_solver_time_in_seconds = 0.0;
    out.residual_evaluation_time_in_seconds = 0.0;
    out.num_residual_blocks_reduced = static_cast<int>(s_.terms.size());
    out.num_residuals_reduced = s_.num_residuals;
    out.num_parameter_blocks_reduced = static_cast<int>(s_.blocks.size() + s_.points.size());
    out.num_effective_parameters_reduced = s_.n + 3 * static_cast<int>(s_.points.size());
    out.num_threads_given = out.num_threads_used = static_cast<int>(threads_);
    out.fixed_cost = fixed_cost_;

    double cost = 0.0;
    if (!Cost(&cost)) {
      out.termination_type = ceres::FAILURE;
      out.message = "the residuals cannot be evaluated at the start";
      out.initial_cost = out.final_cost = std::numeric_limits<double>::infinity();
      out.total_time_in_seconds = Since(start);
      return;
    }
    out.initial_cost = out.final_cost = cost + fixed_cost_;
    ceres::IterationSummary it0;
    it0.cost = cost + fixed_cost_;
    it0.step_is_valid = it0.step_is_successful = true;
    it0.cumulative_time_in_seconds = Since(start);
    out.iterations.push_back(it0);
    if (Callbacks(it0, &out)) return Finish(start, cost, &out);

    LmTrustRegion region(options_.initial_trust_region_radius, options_.max_trust_region_radius);
    bool relinearize = true;
    out.termination_type = ceres::NO_CONVERGENCE;
    out.message = "Maximum number of iterations reached. Number of iterations: " +
                  std::to_string(options_.max_num_iterations) + ".";
    int iteration = 0;
    while (iteration < options_.max_num_iterations) {
      if (Since(start) > options_.max_solver_time_in_seconds) {
        out.message = "Maximum solver time reached.";
        break;
      }
      if (relinearize) {
        const auto t = Clock::now();
        Linearize();
        out.jacobian_evaluation_time_in_seconds += Since(t);
        relinearize = false;
        if (max_gradient_ <= options_.gradient_tolerance) {
          out.termination_type = ceres::CONVERGENCE;
          out.message = "Gradient tolerance reached. Gradient max norm: " + std::to_string(max_gradient_);
          break;
        }
      }
      ++iteration;
      ceres::IterationSummary it;
      it.iteration = iteration;
      it.trust_region_radius = region.Radius();
      double predicted = 0.0, step_norm = 0.0, trial = std::numeric_limits<double>::infinity();
      auto t = Clock::now();
      Eliminate(region.Damping());
      const bool solved = SolveReduced(region.Damping(), &predicted, &step_norm);
      out.linear_solver_time_in_seconds += Since(t);
      bool evaluated = false;
      if (solved) {
        if (step_norm <= options_.parameter_tolerance * (StateNorm() + options_.parameter_tolerance)) {
          out.termination_type = ceres::CONVERGENCE;
          out.message = "Parameter tolerance reached. Relative step_norm: " + std::to_string(step_norm);
          break;
        }
        SaveAndStep();
        t = Clock::now();
        evaluated = Cost(&trial);
        out.residual_evaluation_time_in_seconds += Since(t);
      }
      const double rho = (evaluated && predicted > 0.0) ? (cost - trial) / predicted : -1.0;
      it.step_norm = step_norm;
      it.relative_decrease = rho;
      it.step_is_valid = solved && evaluated;
      if (rho > options_.min_relative_decrease) {
        const double old_cost = cost;
        cost = trial;
        region.Accept(rho);
        relinearize = true;
        it.step_is_successful = true;
        it.cost = cost + fixed_cost_;
        it.cost_change = old_cost - cost;
        it.cumulative_time_in_seconds = Since(start);
        out.iterations.push_back(it);
        if (Callbacks(it, &out)) return Finish(start, cost, &out);
        if (std::abs(old_cost - cost) <= options_.function_tolerance * old_cost) {
          out.termination_type = ceres::CONVERGENCE;
          out.message = "Function tolerance reached. |cost_change|/cost: " +
                        std::to_string(std::abs(old_cost - cost) / old_cost);
          break;
        }
      } else {
        if (solved) Restore();
        region.Reject();
        it.cost = cost + fixed_cost_;
        it.cumulative_time_in_seconds = Since(start);
        out.iterations.push_back(it);
        if (Callbacks(it, &out)) return Finish(start, cost, &out);
        // As Ceres checks every step it could evaluate, taken or not: a
        // trial within the function tolerance of the cost means the cost
        // cannot move by more (near the optimum such trials differ from it
        // by rounding alone, and the rejections would only shrink the
        // region until its minimum).
        if (evaluated && std::abs(cost - trial) <= options_.function_tolerance * cost) {
          out.termination_type = ceres::CONVERGENCE;
          out.message = "Function tolerance reached. |cost_change|/cost: " +
                        std::to_string(std::abs(cost - trial) / cost) + " (a rejected step)";
          break;
        }
        if (region.Radius() < options_.min_trust_region_radius) {
          out.termination_type = ceres::CONVERGENCE;
          out.message =
              "Minimum trust region radius reached. Trust region radius: " + std::to_string(region.Radius());
          break;
        }
      }
    }
    Finish(start, cost, &out);
  }

 private:
  void Finish(Clock::time_point start, double cost, ceres::Solver::Summary* out) const {
    out->final_cost = cost + fixed_cost_;
    out->total_time_in_seconds = out->minimizer_time_in_seconds = Since(start);
  }

  // The options' callbacks; true when one ends the solve.
  bool Callbacks(const ceres::IterationSummary& it, ceres::Solver::Summary* out) const {
    for (ceres::IterationCallback* callback : options_.callbacks) {
      const ceres::CallbackReturnType r = (*callback)(it);
      if (r == ceres::SOLVER_TERMINATE_SUCCESSFULLY) {
        out->termination_type = ceres::USER_SUCCESS;
        out->message = "User callback returned SOLVER_TERMINATE_SUCCESSFULLY.";
        return true;
      }
      if (r == ceres::SOLVER_ABORT) {
        out->termination_type = ceres::USER_FAILURE;
        out->message = "User callback returned SOLVER_ABORT.";
        return true;
      }
    }
    return false;
  }

  // One term's residual and, with `jac`, its Jacobians in tangent
  // coordinates (rows x tangent, row-major, per parameter; none for held
  // ones), the loss's correction applied. False where it cannot be evaluated.
  struct Scratch {
    std::vector<double> r;
    std::vector<RowMajor> ambient, tangent;
    std::vector<double*> ptrs;
  };
  bool Evaluate(const Term& t, Scratch* sc, bool jac, double* cost) const {
    sc->r.resize(t.rows);
    const size_t k = t.params.size();
    if (jac) {
      sc->ambient.resize(k);
      sc->tangent.resize(k);
      sc->ptrs.assign(k, nullptr);
      for (size_t i = 0; i < k; ++i) {
        if (t.kind[i] == kHeld) continue;
        const int ambient = t.kind[i] == kPoint ? 3 : s_.blocks[t.kind[i]].ambient;
        sc->ambient[i].resize(t.rows, ambient);
        sc->ptrs[i] = sc->ambient[i].data();
      }
    }
    if (!t.cost->Evaluate(t.params.data(), sc->r.data(), jac ? sc->ptrs.data() : nullptr)) return false;
    for (double v : sc->r) {
      if (!std::isfinite(v)) return false;
    }
    const LossCorrector c(t.loss, sc->r.data(), t.rows);
    *cost = c.cost;
    if (!jac) return true;
    Eigen::Map<Eigen::VectorXd> r(sc->r.data(), t.rows);
    for (size_t i = 0; i < k; ++i) {
      if (t.kind[i] == kHeld) continue;
      RowMajor& j = sc->tangent[i];
      if (t.kind[i] == kPoint || s_.blocks[t.kind[i]].manifold == nullptr) {
        j = sc->ambient[i];
      } else {
        j.noalias() = sc->ambient[i] * plus_[t.kind[i]];
      }
      if (!c.Identity()) {
        if (c.alpha_sq_norm != 0.0) j -= c.alpha_sq_norm * r * (r.transpose() * j);
        j *= c.sqrt_rho1;
      }
    }
    if (!c.Identity()) r *= c.residual_scaling;
    return true;
  }

  // ½Σρ at the problem's current values (held terms apart).
  bool Cost(double* cost) const {
    const int nt = static_cast<int>(s_.terms.size());
    std::vector<double> part(threads_, 0.0);
    std::vector<char> ok(threads_, 1);
    ParallelFor(threads_, threads_, [&](size_t th) {
      Scratch sc;
      double sum = 0.0, c = 0.0;
      const int begin = static_cast<int>(static_cast<long>(nt) * th / threads_);
      const int end = static_cast<int>(static_cast<long>(nt) * (th + 1) / threads_);
      for (int i = begin; i < end; ++i) {
        if (!Evaluate(s_.terms[i], &sc, false, &c)) {
          ok[th] = 0;
          return;
        }
        sum += c;
      }
      part[th] = sum;
    });
    *cost = 0.0;
    for (unsigned th = 0; th < threads_; ++th) {
      if (!ok[th]) return false;
      *cost += part[th];
    }
    return std::isfinite(*cost);
  }

  // JᵀJ and Jᵀr of one term's reduced cells into (u, g), lower triangle:
  // entry by entry over its few rows, no temporaries.
  void AddReduced(const Term& t, Scratch* sc, Eigen::MatrixXd* u, Eigen::VectorXd* g) const {
    const double* r = sc->r.data();
    const int rows = t.rows;
    double* const ud = u->data();
    for (size_t a = 0; a < t.params.size(); ++a) {
      if (t.kind[a] < 0) continue;
      const FBlock& fa = s_.blocks[t.kind[a]];
      const RowMajor& ja = sc->tangent[a];
      for (int i = 0; i < fa.tangent; ++i) {
        double gi = 0.0;
        for (int q = 0; q < rows; ++q) gi += ja(q, i) * r[q];
        (*g)(fa.col + i) += gi;
      }
      for (size_t b = 0; b <= a; ++b) {
        if (t.kind[b] < 0) continue;
        // The cell of the later block's rows and the earlier's columns: the
        // lower triangle either way.
        const bool later = t.kind[a] >= t.kind[b];
        const int hi = later ? t.kind[a] : t.kind[b], lo = later ? t.kind[b] : t.kind[a];
        const RowMajor& jh = later ? ja : sc->tangent[b];
        const RowMajor& jl = later ? sc->tangent[b] : ja;
        const ReducedLayout::Span span = layout_.Cell(hi, lo);
        const int hi_tangent = s_.blocks[hi].tangent, lo_tangent = s_.blocks[lo].tangent;
        for (int k = 0; k < lo_tangent; ++k) {
          double* column = ud + span.start + k * span.stride;
          for (int i = hi == lo ? k : 0; i < hi_tangent; ++i) {
            double d = 0.0;
            for (int q = 0; q < rows; ++q) d += jh(q, i) * jl(q, k);
            column[i] += d;
          }
        }
      }
    }
  }

  // The normal equations' blocks at the current values: U and g_f of the
  // reduced system, and per point V, g_x and W (3 x its reduced columns).
  void Linearize() {
    for (size_t b = 0; b < s_.blocks.size(); ++b) {
      const FBlock& f = s_.blocks[b];
      if (f.manifold == nullptr) continue;
      plus_[b].resize(f.ambient, f.tangent);
      f.manifold->PlusJacobian(f.x, plus_[b].data());
    }
    ParallelFor(threads_, threads_, [&](size_t th) {
      Eigen::MatrixXd& u = s_t_[th];
      Eigen::VectorXd& g = b_t_[th];
      ZeroLower(&u);
      g.setZero(s_.n);
      Scratch sc;
      std::vector<int> local(s_.blocks.size(), -1);
      double c = 0.0;
      for (int p = ranges_[th]; p < ranges_[th + 1]; ++p) {
        // The point's reduced blocks in the reduced system's column order,
        // so that W's lower triangle is the reduced system's (Eliminate).
        std::vector<int>& cols = cols_[p];
        cols.clear();
        for (int i = s_.point_begin[p]; i < s_.point_begin[p + 1]; ++i) {
          for (int kind : s_.terms[i].kind) {
            if (kind >= 0 && local[kind] < 0) {
              local[kind] = 0;
              cols.push_back(kind);
            }
          }
        }
        std::sort(cols.begin(), cols.end(), [&](int a, int b) { return s_.blocks[a].col < s_.blocks[b].col; });
        int width = 0;
        for (int kind : cols) {
          local[kind] = width;
          width += s_.blocks[kind].tangent;
        }
        Eigen::Matrix3d v = Eigen::Matrix3d::Zero();
        Eigen::Vector3d gx = Eigen::Vector3d::Zero();
        Eigen::Matrix<double, 3, Eigen::Dynamic>& w = w_[p];
        w.setZero(3, width);
        for (int i = s_.point_begin[p]; i < s_.point_begin[p + 1]; ++i) {
          const Term& t = s_.terms[i];
          // Evaluated when its state was accepted: defined here.
          Evaluate(t, &sc, true, &c);
          const Eigen::Map<const Eigen::VectorXd> r(sc.r.data(), t.rows);
          int x = -1;
          for (size_t a = 0; a < t.params.size(); ++a) {
            if (t.kind[a] == kPoint) x = static_cast<int>(a);
          }
          const RowMajor& jx = sc.tangent[x];
          for (int q = 0; q < t.rows; ++q) {
            for (int i = 0; i < 3; ++i) {
              gx(i) += jx(q, i) * r(q);
              for (int k = 0; k < 3; ++k) v(i, k) += jx(q, i) * jx(q, k);
            }
          }
          for (size_t a = 0; a < t.params.size(); ++a) {
            if (t.kind[a] < 0) continue;
            const RowMajor& ja = sc.tangent[a];
            const int at = local[t.kind[a]];
            for (int k = 0; k < s_.blocks[t.kind[a]].tangent; ++k) {
              for (int i = 0; i < 3; ++i) {
                double d = 0.0;
                for (int q = 0; q < t.rows; ++q) d += jx(q, i) * ja(q, k);
                w(i, at + k) += d;
              }
            }
          }
          AddReduced(t, &sc, &u, &g);
        }
        for (int kind : cols) local[kind] = -1;
        v_[p] = v;
        gx_[p] = gx;
      }
    });
    Scratch sc;
    double c = 0.0;
    for (size_t i = s_.first_other; i < s_.terms.size(); ++i) {
      Evaluate(s_.terms[i], &sc, true, &c);
      AddReduced(s_.terms[i], &sc, &s_t_[0], &b_t_[0]);
    }
    Resize(&u_);
    SumLower(0, nullptr, &u_);
    gf_ = b_t_[0];
    for (unsigned th = 1; th < threads_; ++th) gf_ += b_t_[th];
    max_gradient_ = gf_.size() > 0 ? gf_.cwiseAbs().maxCoeff() : 0.0;
    for (const Eigen::Vector3d& g : gx_) max_gradient_ = std::max(max_gradient_, g.cwiseAbs().maxCoeff());
  }

  // A matrix of the layout's values: n x n, or the pattern's as a column.
  void Resize(Eigen::MatrixXd* m) const {
    const long rows = layout_.sparse() ? layout_.size() : s_.n, cols = layout_.sparse() ? 1 : s_.n;
    if (m->rows() != rows || m->cols() != cols) m->resize(rows, cols);
  }

  // The lower triangle zeroed (the upper is never read: half the memory to
  // write each step); a pattern's values all.
  void ZeroLower(Eigen::MatrixXd* m) const {
    Resize(m);
    if (layout_.sparse()) {
      m->setZero();
      return;
    }
    const int n = s_.n;
    for (int c = 0; c < n; ++c) m->col(c).tail(n - c).setZero();
  }

  // out's lower triangle = the threads' matrices from `first` on summed
  // (plus `extra`), added to out's own where first is 1 (out is thread 0's):
  // by column blocks (a pattern's values by stretches) on every thread.
  void SumLower(unsigned first, const Eigen::MatrixXd* extra, Eigen::MatrixXd* out) {
    if (layout_.sparse()) {
      const long size = layout_.size(), chunk = 1 << 16;
      ParallelFor(static_cast<std::size_t>((size + chunk - 1) / chunk), threads_, [&](std::size_t k) {
        const long begin = static_cast<long>(k) * chunk, len = std::min(chunk, size - begin);
        auto stretch = out->col(0).segment(begin, len);
        if (first == 0) stretch = s_t_[0].col(0).segment(begin, len);
        for (unsigned th = 1; th < threads_; ++th) stretch += s_t_[th].col(0).segment(begin, len);
        if (extra != nullptr) stretch += extra->col(0).segment(begin, len);
      });
      return;
    }
    const int n = s_.n, width = 64;
    ParallelFor(static_cast<std::size_t>((n + width - 1) / width), threads_, [&](std::size_t k) {
      for (int c = static_cast<int>(k) * width; c < std::min(n, static_cast<int>(k + 1) * width); ++c) {
        auto column = out->col(c).tail(n - c);
        if (first == 0) column = s_t_[0].col(c).tail(n - c);
        for (unsigned th = 1; th < threads_; ++th) column += s_t_[th].col(c).tail(n - c);
        if (extra != nullptr) column += extra->col(c).tail(n - c);
      }
    });
  }

  static double Damp(double diagonal, double lambda) {
    return std::clamp(diagonal, 1e-6, 1e32) * lambda;
  }

  // S = U* − Σ Wᵀ V*⁻¹ W and b = −g_f + Σ Wᵀ V*⁻¹ g_x, damped by lambda
  // (lower triangle of S).
  void Eliminate(double lambda) {
    ParallelFor(threads_, threads_, [&](size_t th) {
      Eigen::MatrixXd& s = s_t_[th];
      Eigen::VectorXd& b = b_t_[th];
      ZeroLower(&s);
      b.setZero(s_.n);
      Eigen::Matrix<double, 3, Eigen::Dynamic> y;
      std::vector<int> local;  // W's first column of each of the point's blocks
      double* const sd = s.data();
      for (int p = ranges_[th]; p < ranges_[th + 1]; ++p) {
        Eigen::Matrix3d v = v_[p];
        for (int i = 0; i < 3; ++i) v(i, i) += Damp(v(i, i), lambda);
        vinv_[p] = v.inverse();
        const auto& w = w_[p];
        y.noalias() = vinv_[p] * w;
        const std::vector<int>& cols = cols_[p];
        local.clear();
        int width = 0;
        for (int kind : cols) {
          const FBlock& f = s_.blocks[kind];
          local.push_back(width);
          for (int k = 0; k < f.tangent; ++k) b(f.col + k) += y.col(width + k).dot(gx_[p]);
          width += f.tangent;
        }
        // Wᵀ V⁻¹ W's lower triangle straight into S's, cell by cell (W's
        // columns are in S's order), three products an entry: no width²
        // temporary.
        for (size_t cb = 0; cb < cols.size(); ++cb) {
          const int lo_tangent = s_.blocks[cols[cb]].tangent;
          for (size_t ca = cb; ca < cols.size(); ++ca) {
            const ReducedLayout::Span span = layout_.Cell(cols[ca], cols[cb]);
            const int hi_tangent = s_.blocks[cols[ca]].tangent, la = local[ca];
            for (int k = 0; k < lo_tangent; ++k) {
              const int j = local[cb] + k;
              const double y0 = y(0, j), y1 = y(1, j), y2 = y(2, j);
              double* column = sd + span.start + k * span.stride;
              for (int i = ca == cb ? k : 0; i < hi_tangent; ++i) {
                column[i] -= w(0, la + i) * y0 + w(1, la + i) * y1 + w(2, la + i) * y2;
              }
            }
          }
        }
      }
    });
    for (unsigned th = 1; th < threads_; ++th) b_t_[0] += b_t_[th];
    SumLower(1, &u_, &s_t_[0]);
    double* const sd = s_t_[0].data();
    const double* const ud = u_.data();
    for (int i = 0; i < s_.n; ++i) sd[layout_.Diagonal(i)] += Damp(ud[layout_.Diagonal(i)], lambda);
    b_t_[0] -= gf_;
  }

  // The reduced step by Cholesky, the points' back-substitution; the model's
  // predicted decrease ½(−gᵀδ + λ δᵀDδ) and |δ|. False where S is not
  // positive definite.
  bool SolveReduced(double lambda, double* predicted, double* step_norm) {
    df_ = Eigen::VectorXd::Zero(s_.n);
    if (s_.n > 0) {
      if (layout_.sparse()) {
        if (!cholesky_->Factorize(s_t_[0].data())) return false;
        df_ = cholesky_->Solve(b_t_[0]);
      } else {
        if (!internal::CholeskyInPlace(&s_t_[0], threads_)) return false;
        df_ = internal::CholeskySolve(s_t_[0], b_t_[0]);
      }
      if (!df_.allFinite()) return false;
    }
    std::vector<double> part(threads_, 0.0), norm2(threads_, 0.0);
    ParallelFor(threads_, threads_, [&](size_t th) {
      double pred = 0.0, n2 = 0.0;
      Eigen::VectorXd local;
      for (int p = ranges_[th]; p < ranges_[th + 1]; ++p) {
        const std::vector<int>& cols = cols_[p];
        local.resize(w_[p].cols());
        for (size_t a = 0, la = 0; a < cols.size(); la += s_.blocks[cols[a]].tangent, ++a) {
          const FBlock& f = s_.blocks[cols[a]];
          local.segment(la, f.tangent) = df_.segment(f.col, f.tangent);
        }
        dx_[p] = vinv_[p] * (-gx_[p] - w_[p] * local);
        for (int i = 0; i < 3; ++i) pred += -gx_[p](i) * dx_[p](i) + Damp(v_[p](i, i), lambda) * dx_[p](i) * dx_[p](i);
        n2 += dx_[p].squaredNorm();
      }
      part[th] = pred;
      norm2[th] = n2;
    });
    double pred = 0.0, n2 = 0.0;
    for (unsigned th = 0; th < threads_; ++th) {
      pred += part[th];
      n2 += norm2[th];
    }
    for (int i = 0; i < s_.n; ++i) {
      pred += -gf_(i) * df_(i) + Damp(u_.data()[layout_.Diagonal(i)], lambda) * df_(i) * df_(i);
      n2 += df_(i) * df_(i);
    }
    *predicted = 0.5 * pred;
    *step_norm = std::sqrt(n2);
    return std::isfinite(*predicted);
  }

  double StateNorm() const {
    double n2 = 0.0;
    for (const FBlock& f : s_.blocks) {
      for (int k = 0; k < f.ambient; ++k) n2 += f.x[k] * f.x[k];
    }
    for (const double* p : s_.points) n2 += p[0] * p[0] + p[1] * p[1] + p[2] * p[2];
    return std::sqrt(n2);
  }

  // The step applied in place, the values it replaced kept.
  void SaveAndStep() {
    saved_.clear();
    for (const FBlock& f : s_.blocks) saved_.insert(saved_.end(), f.x, f.x + f.ambient);
    for (const double* p : s_.points) saved_.insert(saved_.end(), p, p + 3);
    std::vector<double> next;
    size_t k = 0;
    for (const FBlock& f : s_.blocks) {
      const double* from = &saved_[k];
      if (f.manifold != nullptr) {
        f.manifold->Plus(from, df_.data() + f.col, f.x);
      } else {
        for (int i = 0; i < f.ambient; ++i) f.x[i] = from[i] + df_(f.col + i);
      }
      k += f.ambient;
    }
    for (size_t p = 0; p < s_.points.size(); ++p) {
      for (int i = 0; i < 3; ++i) s_.points[p][i] = saved_[k + 3 * p + i] + dx_[p](i);
    }
  }

  void Restore() {
    size_t k = 0;
    for (const FBlock& f : s_.blocks) {
      std::copy(&saved_[k], &saved_[k] + f.ambient, f.x);
      k += f.ambient;
    }
    for (double* p : s_.points) {
      std::copy(&saved_[k], &saved_[k] + 3, p);
      k += 3;
    }
  }

  const ceres::Solver::Options& options_;
  Structure& s_;
  unsigned threads_;
  ReducedLayout layout_;
  std::unique_ptr<internal::SparseCholesky> cholesky_;  // the sparse layout's
  std::vector<int> ranges_;
  std::vector<Eigen::Matrix3d> v_, vinv_;
  std::vector<Eigen::Vector3d> gx_, dx_;
  std::vector<Eigen::Matrix<double, 3, Eigen::Dynamic>> w_;
  std::vector<std::vector<int>> cols_;
  std::vector<RowMajor> plus_;
  Eigen::MatrixXd u_;
  Eigen::VectorXd gf_, df_;
  std::vector<Eigen::MatrixXd> s_t_;
  std::vector<Eigen::VectorXd> b_t_;
  std::vector<double> saved_;
  double fixed_cost_ = 0.0;
  double max_gradient_ = 0.0;
};

}  // namespace

bool SolveSchurLm(const ceres::Solver::Options& options, ceres::Problem* problem, const std::vector<double*>& points,
                  ceres::Solver::Summary* summary, std::string* why_not, ReducedStorage storage) {
  Structure s;
  if (!ReadStructure(*problem, points, &s, why_not)) return false;
  const bool sparse = storage == ReducedStorage::kSparse ||
                      (storage == ReducedStorage::kAuto && s.n > kMaxSchurLmDenseSize);
  Solver solver(options, &s, sparse);
  solver.Solve(summary);
  return true;
}

}  // namespace aerotri
