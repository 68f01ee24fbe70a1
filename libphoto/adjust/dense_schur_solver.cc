// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/adjust/dense_schur_solver.h"

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <sstream>

#include "camera_models/camera.h"
#include "libphoto/base/error.h"
#include "libphoto/base/parallel.h"

namespace aerotri {

bool BundleStopRule::Accepted(double cost) {
  if (last_cost_ >= 0.0) {
    const double decrease = std::max(0.0, last_cost_ - cost);
    if (last_decrease_ > 0.0) {
      const double ratio = decrease / last_decrease_;
      // Geometric extrapolation of the remaining decrease with the slower of
      // the last two contraction ratios, never below the last decrease: a
      // decrease that shrinks fast once may slow again.
      const double rho = std::max(ratio, last_ratio_);
      const double ahead = rho < 1.0 ? decrease * rho / (1.0 - rho) : 1e300;
      estimate_ = cost > 0.0 ? std::max(decrease, ahead) / cost : 0.0;
      last_ratio_ = ratio;
    }
    last_decrease_ = decrease;
  }
  last_cost_ = cost;
  return gap_ > 0.0 && estimate_ <= gap_;
}

void LmTrustRegion::Accept(double rho) {
  radius_ = std::min(max_radius_, radius_ / std::max(1.0 / 3.0, 1.0 - std::pow(2.0 * rho - 1.0, 3)));
  decrease_factor_ = 2.0;
}

void LmTrustRegion::Reject() {
  radius_ /= decrease_factor_;
  decrease_factor_ *= 2.0;
}

std::string DenseSchurSummary::Report() const {
  std::ostringstream out;
  out << "aerotri dense-Schur Levenberg-Marquardt: " << num_residuals << " residuals, " << num_parameters
      << " parameters\n"
      << "  cost " << initial_cost << " -> " << final_cost << ", " << iterations << " iterations (" << accepted
      << " accepted)\n"
      << "  time " << time_s << " s: linearise " << linearize_s << ", eliminate points " << eliminate_s
      << ", factor and back-substitute " << factor_s << ", evaluate steps " << evaluate_s << "\n"
      << "  termination: " << termination << ": " << message << "\n";
  return out.str();
}

namespace {

using Clock = std::chrono::steady_clock;
double Since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

constexpr double kMinDiagonal = 1e-6;
constexpr double kMaxDiagonal = 1e32;
constexpr double kMaxRadius = 1e16;
constexpr double kMinRadius = 1e-32;
constexpr double kMinRelativeDecrease = 1e-3;

template <typename Model>
class Solver {
 public:
  static constexpr int N = Model::kNumParams;
  static constexpr int P = 6 + N;
  static constexpr int kBlock = 7 + N;  // stored camera block: q, C, intrinsics
  using CamMat = Eigen::Matrix<double, P, P>;
  using CamVec = Eigen::Matrix<double, P, 1>;
  using CamPt = Eigen::Matrix<double, P, 3>;

  Solver(const DenseSchurProblem& problem, const DenseSchurOptions& options)
      : problem_(problem), options_(options), threads_(ThreadCount(options.num_threads)) {
    nc_ = static_cast<int>(problem.cameras.size());
    np_ = static_cast<int>(problem.points.size());
    // Observations grouped by point (the elimination's unit of work).
    point_begin_.assign(np_ + 1, 0);
    for (const auto& o : problem.observations) ++point_begin_[o.point + 1];
    for (int p = 0; p < np_; ++p) point_begin_[p + 1] += point_begin_[p];
    order_.resize(problem.observations.size());
    std::vector<int> fill(point_begin_.begin(), point_begin_.end() - 1);
    for (size_t k = 0; k < problem.observations.size(); ++k) {
      order_[fill[problem.observations[k].point]++] = static_cast<int>(k);
    }
    // Thread ranges of points with about equal observation counts.
    const size_t nobs = problem.observations.size();
    ranges_.push_back(0);
    for (unsigned t = 1; t < threads_; ++t) {
      const size_t target = nobs * t / threads_;
      int p = ranges_.back();
      while (p < np_ && static_cast<size_t>(point_begin_[p]) < target) ++p;
      ranges_.push_back(p);
    }
    ranges_.push_back(np_);

    cams_.resize(static_cast<size_t>(nc_) * kBlock);
    for (int c = 0; c < nc_; ++c) std::copy(problem.cameras[c], problem.cameras[c] + kBlock, &cams_[c * kBlock]);
    pts_.resize(static_cast<size_t>(np_) * 3);
    for (int p = 0; p < np_; ++p) std::copy(problem.points[p], problem.points[p] + 3, &pts_[3 * p]);
    held_.assign(nc_, CamVec::Ones());
    for (int c = 0; c < nc_; ++c) {
      for (int k = 0; k < N; ++k) {
        held_[c](6 + k) = (k < static_cast<int>(problem.refined[c].size()) && problem.refined[c][k]) ? 1.0 : 0.0;
      }
    }
    w_.resize(nobs);
    v_.resize(np_);
    vinv_.resize(np_);
    gx_.resize(np_);
    dx_.resize(np_);
    u_.resize(nc_);
    gc_.resize(nc_);
    rot_.resize(nc_);
  }

  DenseSchurSummary Solve() {
    const auto start = Clock::now();
    DenseSchurSummary s;
    s.num_residuals = 2 * static_cast<int>(problem_.observations.size());
    int varying = 3 * np_;
    for (int c = 0; c < nc_; ++c) varying += static_cast<int>(held_[c].sum());
    s.num_parameters = varying;

    double cost = 0.0;
    if (!Evaluate(cams_, pts_, &cost)) {
      s.usable = false;
      s.termination = "FAILURE";
      s.message = "a point lies on a camera plane at the start: the projection is undefined";
      s.time_s = Since(start);
      return s;
    }
    s.initial_cost = s.final_cost = cost;
    if (options_.iteration_callback) options_.iteration_callback(0, cost, Since(start));
    BundleStopRule stop(options_.optimality_gap);
    stop.Accepted(cost);

    LmTrustRegion region(1e4, kMaxRadius);
    bool relinearize = true;
    std::vector<double> trial_cams(cams_.size()), trial_pts(pts_.size());
    s.termination = "NO_CONVERGENCE";
    s.message = "maximum number of iterations reached (" + std::to_string(options_.max_iterations) + ")";
    while (s.iterations < options_.max_iterations) {
      if (options_.max_time_s > 0.0 && Since(start) > options_.max_time_s) {
        s.message = "time limit reached";
        break;
      }
      auto t = Clock::now();
      if (relinearize) {
        Linearize();
        s.linearize_s += Since(t);
        if (max_gradient_ <= options_.gradient_tolerance) {
          s.termination = "CONVERGENCE";
          s.message = "gradient tolerance reached: max |g| " + std::to_string(max_gradient_);
          s.converged = true;
          break;
        }
        relinearize = false;
      }
      ++s.iterations;
      t = Clock::now();
      EliminatePoints(region.Damping());
      s.eliminate_s += Since(t);
      t = Clock::now();
      double predicted = 0.0, step_norm = 0.0;
      const bool solved = SolveCameras(region.Damping(), &predicted, &step_norm);
      s.factor_s += Since(t);
      double trial_cost = std::numeric_limits<double>::infinity();
      bool evaluated = false;
      if (solved) {
        double x_norm = 0.0;
        for (double v : pts_) x_norm += v * v;
        for (int c = 0; c < nc_; ++c) {
          for (int k = 4; k < kBlock; ++k) x_norm += cams_[c * kBlock + k] * cams_[c * kBlock + k];
        }
        x_norm = std::sqrt(x_norm);
        if (step_norm <= options_.parameter_tolerance * (x_norm + options_.parameter_tolerance)) {
          s.termination = "CONVERGENCE";
          s.message = "parameter tolerance reached: |step| " + std::to_string(step_norm);
          s.converged = true;
          break;
        }
        t = Clock::now();
        Apply(&trial_cams, &trial_pts);
        evaluated = Evaluate(trial_cams, trial_pts, &trial_cost);
        s.evaluate_s += Since(t);
      }
      const double rho = (evaluated && predicted > 0.0) ? (cost - trial_cost) / predicted : -1.0;
      if (rho > kMinRelativeDecrease) {
        cams_.swap(trial_cams);
        pts_.swap(trial_pts);
        const double old_cost = cost;
        cost = trial_cost;
        ++s.accepted;
        region.Accept(rho);
        relinearize = true;
        if (options_.iteration_callback) options_.iteration_callback(s.iterations, cost, Since(start));
        if (stop.Accepted(cost)) {
          s.termination = "CONVERGENCE";
          s.message = "estimated within " + std::to_string(stop.EstimatedGap()) + " of the optimum (gap " +
                      std::to_string(options_.optimality_gap) + ")";
          s.converged = true;
          break;
        }
        if (std::abs(old_cost - cost) <= options_.function_tolerance * old_cost) {
          s.termination = "CONVERGENCE";
          s.message = "function tolerance reached: |Δcost|/cost " + std::to_string(std::abs(old_cost - cost) / old_cost);
          s.converged = true;
          break;
        }
      } else {
        region.Reject();
        if (region.Radius() < kMinRadius) {
          s.termination = "CONVERGENCE";
          s.message = "trust region radius below its minimum: no step decreases the cost";
          s.converged = true;
          break;
        }
      }
    }
    s.final_cost = cost;
    for (int c = 0; c < nc_; ++c) std::copy(&cams_[c * kBlock], &cams_[(c + 1) * kBlock], problem_.cameras[c]);
    for (int p = 0; p < np_; ++p) std::copy(&pts_[3 * p], &pts_[3 * p + 3], problem_.points[p]);
    s.time_s = Since(start);
    return s;
  }

 private:
  static Eigen::Matrix3d Rotation(const double* q) {
    return Eigen::Quaterniond(q[0], q[1], q[2], q[3]).normalized().toRotationMatrix();
  }

  // Residual (2) of one observation, and optionally its Jacobians (2xP
  // camera, 2x3 point). False where the projection is undefined.
  bool Residual(const Eigen::Matrix3d& r, const double* cam, const double* pt,
                const DenseSchurProblem::Observation& o, double* res, Eigen::Matrix<double, 2, P>* jc,
                Eigen::Matrix<double, 2, 3>* jx) const {
    const Eigen::Vector3d d(pt[0] - cam[4], pt[1] - cam[5], pt[2] - cam[6]);
    const Eigen::Vector3d p = r * d;
    if (!(std::abs(p.z()) > 1e-12 * (1.0 + d.norm()))) return false;
    const double inv_z = 1.0 / p.z();
    const double u = p.x() * inv_z, v = p.y() * inv_z;
    double xy[2], d_uv[4], d_k[2 * N];
    Model::ImageFromNormalizedWithJacobian(cam + 7, u, v, xy, jc ? d_uv : nullptr, jc ? d_k : nullptr);
    res[0] = (xy[0] - o.x) * o.inv_sigma;
    res[1] = (xy[1] - o.y) * o.inv_sigma;
    if (jc == nullptr) return true;
    const Eigen::Map<const Eigen::Matrix<double, 2, 2, Eigen::RowMajor>> j_uv(d_uv);
    Eigen::Matrix<double, 2, 3> duv_dp;
    duv_dp << inv_z, 0.0, -u * inv_z, 0.0, inv_z, -v * inv_z;
    const Eigen::Matrix<double, 2, 3> a = o.inv_sigma * (j_uv * duv_dp);
    Eigen::Matrix3d minus_p_cross;  // ∂(Exp(θ) p)/∂θ at θ = 0
    minus_p_cross << 0.0, p.z(), -p.y(), -p.z(), 0.0, p.x(), p.y(), -p.x(), 0.0;
    const Eigen::Matrix<double, 2, 3> ar = a * r;
    jc->template block<2, 3>(0, 0) = a * minus_p_cross;
    jc->template block<2, 3>(0, 3) = -ar;
    const Eigen::Map<const Eigen::Matrix<double, 2, N, Eigen::RowMajor>> jk(d_k);
    jc->template block<2, N>(0, 6) = o.inv_sigma * jk;
    *jx = ar;
    return true;
  }

  bool Evaluate(const std::vector<double>& cams, const std::vector<double>& pts, double* cost) {
    std::vector<Eigen::Matrix3d> rot(nc_);
    for (int c = 0; c < nc_; ++c) rot[c] = Rotation(&cams[c * kBlock]);
    std::vector<double> part(threads_, 0.0);
    std::vector<char> ok(threads_, 1);
    ParallelFor(threads_, threads_, [&](size_t t) {
      double sum = 0.0;
      for (int p = ranges_[t]; p < ranges_[t + 1]; ++p) {
        for (int k = point_begin_[p]; k < point_begin_[p + 1]; ++k) {
          const auto& o = problem_.observations[order_[k]];
          double res[2];
          if (!Residual(rot[o.camera], &cams[o.camera * kBlock], &pts[3 * p], o, res, nullptr, nullptr)) {
            ok[t] = 0;
            return;
          }
          sum += res[0] * res[0] + res[1] * res[1];
        }
      }
      part[t] = 0.5 * sum;
    });
    *cost = 0.0;
    for (unsigned t = 0; t < threads_; ++t) {
      if (!ok[t]) return false;
      *cost += part[t];
    }
    return std::isfinite(*cost);
  }

  // Residuals and Jacobians at the current state: U, gc per camera; V, gx per
  // point; W per observation.
  void Linearize() {
    for (int c = 0; c < nc_; ++c) rot_[c] = Rotation(&cams_[c * kBlock]);
    std::vector<std::vector<CamMat>> u_t(threads_, std::vector<CamMat>(nc_, CamMat::Zero()));
    std::vector<std::vector<CamVec>> g_t(threads_, std::vector<CamVec>(nc_, CamVec::Zero()));
    ParallelFor(threads_, threads_, [&](size_t t) {
      auto& u = u_t[t];
      auto& g = g_t[t];
      Eigen::Matrix<double, 2, P> jc;
      Eigen::Matrix<double, 2, 3> jx;
      for (int p = ranges_[t]; p < ranges_[t + 1]; ++p) {
        Eigen::Matrix3d v = Eigen::Matrix3d::Zero();
        Eigen::Vector3d gx = Eigen::Vector3d::Zero();
        for (int k = point_begin_[p]; k < point_begin_[p + 1]; ++k) {
          const auto& o = problem_.observations[order_[k]];
          double res[2];
          // The state was evaluated before it was accepted: defined here.
          Residual(rot_[o.camera], &cams_[o.camera * kBlock], &pts_[3 * p], o, res, &jc, &jx);
          for (int i = 6; i < P; ++i) jc.col(i) *= held_[o.camera](i);
          const Eigen::Map<const Eigen::Vector2d> r(res);
          u[o.camera].noalias() += jc.transpose().lazyProduct(jc);
          g[o.camera].noalias() += jc.transpose() * r;
          w_[k].noalias() = jc.transpose() * jx;
          v.noalias() += jx.transpose() * jx;
          gx.noalias() += jx.transpose() * r;
        }
        v_[p] = v;
        gx_[p] = gx;
      }
    });
    max_gradient_ = 0.0;
    for (int c = 0; c < nc_; ++c) {
      u_[c] = u_t[0][c];
      gc_[c] = g_t[0][c];
      for (unsigned t = 1; t < threads_; ++t) {
        u_[c] += u_t[t][c];
        gc_[c] += g_t[t][c];
      }
      max_gradient_ = std::max(max_gradient_, gc_[c].cwiseAbs().maxCoeff());
    }
    for (int p = 0; p < np_; ++p) max_gradient_ = std::max(max_gradient_, gx_[p].cwiseAbs().maxCoeff());
  }

  static double Damp(double diagonal, double lambda) {
    return std::clamp(diagonal, kMinDiagonal, kMaxDiagonal) * lambda;
  }

  // Index of block (r, c), r >= c, in the packed lower block triangle.
  static size_t Packed(int r, int c) { return static_cast<size_t>(r) * (r + 1) / 2 + c; }

  // S = U* − Σ W V*⁻¹ Wᵀ and b = −gc + Σ W V*⁻¹ gx with damping lambda (1/μ);
  // the lower triangle of S is filled. Each thread accumulates into its own
  // packed lower block triangle of fixed-size blocks, summed into the dense
  // S afterwards. The small products are lazy (coefficient-based): Eigen
  // would send a 9x3 · 3x9 product through its general GEMM kernel, with
  // packing, at several times the cost.
  void EliminatePoints(double lambda) {
    const int n = nc_ * P;
    const size_t num_blocks = Packed(nc_, 0);
    if (blocks_t_.size() != threads_) {
      blocks_t_.assign(threads_, std::vector<CamMat>(num_blocks));
      b_t_.assign(threads_, Eigen::VectorXd(n));
      s_.resize(n, n);
    }
    ParallelFor(threads_, threads_, [&](size_t t) {
      std::vector<CamMat>& s = blocks_t_[t];
      Eigen::VectorXd& b = b_t_[t];
      for (CamMat& m : s) m.setZero();
      b.setZero();
      std::vector<CamPt> y;
      std::vector<int> cam;
      for (int p = ranges_[t]; p < ranges_[t + 1]; ++p) {
        Eigen::Matrix3d v = v_[p];
        for (int i = 0; i < 3; ++i) v(i, i) += Damp(v(i, i), lambda);
        const Eigen::Matrix3d vinv = v.inverse();
        vinv_[p] = vinv;
        const int begin = point_begin_[p], k = point_begin_[p + 1] - begin;
        y.resize(k);
        cam.resize(k);
        for (int j = 0; j < k; ++j) {
          cam[j] = problem_.observations[order_[begin + j]].camera;
          y[j].noalias() = w_[begin + j].lazyProduct(vinv);
          b.template segment<P>(cam[j] * P).noalias() += y[j] * gx_[p];
        }
        for (int j = 0; j < k; ++j) {
          for (int l = 0; l <= j; ++l) {
            const int cj = cam[j], cl = cam[l];
            if (cj > cl) {
              s[Packed(cj, cl)].noalias() -= y[j].lazyProduct(w_[begin + l].transpose());
            } else if (cj < cl) {
              s[Packed(cl, cj)].noalias() -= w_[begin + l].lazyProduct(y[j].transpose());
            } else {
              CamMat& d = s[Packed(cj, cj)];
              d.noalias() -= y[j].lazyProduct(w_[begin + l].transpose());
              // The same camera twice on one point: the pair counts both ways.
              if (l != j) d.noalias() -= w_[begin + l].lazyProduct(y[j].transpose());
            }
          }
        }
      }
    });
    for (unsigned t = 1; t < threads_; ++t) {
      for (size_t i = 0; i < num_blocks; ++i) blocks_t_[0][i] += blocks_t_[t][i];
      b_t_[0] += b_t_[t];
    }
    for (int c = 0; c < nc_; ++c) {
      CamMat u = u_[c];
      for (int i = 0; i < P; ++i) {
        if (held_[c](i) == 0.0) {
          u.row(i).setZero();
          u.col(i).setZero();
          u(i, i) = 1.0;
        } else {
          u(i, i) += Damp(u(i, i), lambda);
        }
      }
      blocks_t_[0][Packed(c, c)] += u;
      b_t_[0].template segment<P>(c * P) -= gc_[c];
    }
    for (int r = 0; r < nc_; ++r) {
      for (int c = 0; c <= r; ++c) s_.template block<P, P>(r * P, c * P) = blocks_t_[0][Packed(r, c)];
    }
  }

  // Cholesky of S, the camera step, the points' back-substitution; the
  // model's predicted decrease ½(−gᵀδ + δᵀDδ λ) and |δ|.
  bool SolveCameras(double lambda, double* predicted, double* step_norm) {
    Eigen::LLT<Eigen::Ref<Eigen::MatrixXd>, Eigen::Lower> llt(s_);
    if (llt.info() != Eigen::Success) return false;
    dc_ = llt.solve(b_t_[0]);
    if (!dc_.allFinite()) return false;
    std::vector<double> part(threads_, 0.0), norm2(threads_, 0.0);
    ParallelFor(threads_, threads_, [&](size_t t) {
      double pred = 0.0, n2 = 0.0;
      for (int p = ranges_[t]; p < ranges_[t + 1]; ++p) {
        Eigen::Vector3d rhs = -gx_[p];
        for (int j = point_begin_[p]; j < point_begin_[p + 1]; ++j) {
          const int c = problem_.observations[order_[j]].camera;
          rhs.noalias() -= w_[j].transpose() * dc_.template segment<P>(c * P);
        }
        dx_[p] = vinv_[p] * rhs;
        for (int i = 0; i < 3; ++i) pred += -gx_[p](i) * dx_[p](i) + Damp(v_[p](i, i), lambda) * dx_[p](i) * dx_[p](i);
        n2 += dx_[p].squaredNorm();
      }
      part[t] = pred;
      norm2[t] = n2;
    });
    double pred = 0.0, n2 = 0.0;
    for (unsigned t = 0; t < threads_; ++t) {
      pred += part[t];
      n2 += norm2[t];
    }
    for (int c = 0; c < nc_; ++c) {
      for (int i = 0; i < P; ++i) {
        if (held_[c](i) == 0.0) continue;
        const double d = dc_(c * P + i);
        pred += -gc_[c](i) * d + Damp(u_[c](i, i), lambda) * d * d;
        n2 += d * d;
      }
    }
    *predicted = 0.5 * pred;
    *step_norm = std::sqrt(n2);
    return std::isfinite(*predicted) && dx_.size() == static_cast<size_t>(np_);
  }

  void Apply(std::vector<double>* cams, std::vector<double>* pts) const {
    for (int c = 0; c < nc_; ++c) {
      const double* from = &cams_[c * kBlock];
      double* to = &(*cams)[c * kBlock];
      const Eigen::Vector3d theta = dc_.template segment<3>(c * P);
      const double angle = theta.norm();
      const Eigen::Quaterniond dq =
          angle > 0.0 ? Eigen::Quaterniond(Eigen::AngleAxisd(angle, theta / angle)) : Eigen::Quaterniond::Identity();
      const Eigen::Quaterniond q = (dq * Eigen::Quaterniond(from[0], from[1], from[2], from[3])).normalized();
      to[0] = q.w();
      to[1] = q.x();
      to[2] = q.y();
      to[3] = q.z();
      for (int k = 0; k < 3; ++k) to[4 + k] = from[4 + k] + dc_(c * P + 3 + k);
      for (int k = 0; k < N; ++k) to[7 + k] = from[7 + k] + held_[c](6 + k) * dc_(c * P + 6 + k);
    }
    for (int p = 0; p < np_; ++p) {
      for (int k = 0; k < 3; ++k) (*pts)[3 * p + k] = pts_[3 * p + k] + dx_[p](k);
    }
  }

  const DenseSchurProblem& problem_;
  const DenseSchurOptions& options_;
  unsigned threads_;
  int nc_ = 0, np_ = 0;
  std::vector<int> point_begin_, order_, ranges_;
  std::vector<double> cams_, pts_;
  std::vector<CamVec> held_;
  std::vector<Eigen::Matrix3d> rot_;
  std::vector<CamPt> w_;
  std::vector<Eigen::Matrix3d> v_, vinv_;
  std::vector<Eigen::Vector3d> gx_, dx_;
  std::vector<CamMat> u_;
  std::vector<CamVec> gc_;
  std::vector<std::vector<CamMat>> blocks_t_;
  Eigen::MatrixXd s_;
  std::vector<Eigen::VectorXd> b_t_;
  Eigen::VectorXd dc_;
  double max_gradient_ = 0.0;
};

}  // namespace

DenseSchurSummary SolveDenseSchur(const DenseSchurProblem& problem, const DenseSchurOptions& options) {
  AEROTRI_CHECK(problem.refined.size() == problem.cameras.size());
  return VisitCameraModel(problem.model, [&](auto m) {
    using Model = decltype(m);
    AEROTRI_CHECK(static_cast<int>(problem.cameras.size()) * (6 + Model::kNumParams) <= kMaxDenseSchurSize);
    Solver<Model> solver(problem, options);
    return solver.Solve();
  });
}

}  // namespace aerotri
