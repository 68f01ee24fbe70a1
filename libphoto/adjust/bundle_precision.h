// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// Precision of a solved bundle from its normal equations, through the
// reduced camera system (the same Schur elimination the solver uses):
//
//   N = JᵀJ = [V W; Wᵀ U]   V: the points' 3x3 blocks, U: everything else
//   S = U − Wᵀ V⁻¹ W        dense, one row per camera / intrinsic / offset
//   Σ_U = S⁻¹,   Σ_p = V_p⁻¹ + T_p Σ_U T_pᵀ,   Σ_pU = −T_p Σ_U,   T = V⁻¹ W
//
// J is Ceres' Jacobian of the weighted residuals (robust loss applied, as in
// the solve) in the tangent space of every varying block, so Σ is the
// a-priori covariance (unit weight); callers scale it by σ0².
//
// Two more products of the same inverse:
//  - points outside the adjustment (independent check points), triangulated
//    with the cameras held: Σ_X = (AᵀA)⁻¹ + G Σ_U Gᵀ, G = (AᵀA)⁻¹ Aᵀ B, where
//    A, B are their rows' Jacobians in the point and in the reduced blocks;
//  - the cofactor of the residuals of chosen observations (target marks),
//    Q_vv = I − J_i Σ J_iᵀ with J_i the row's Jacobian without the loss, for
//    Baarda's w-test w = v / √q_vv;
//  - per group of the adjustment's rows (ties, marks, GPS, control), the
//    sum of squared residuals vᵀPv and of the leverages h_i = J_i Σ J_iᵀ
//    (loss applied, as in N), whose complement r_g = n_g − Σh_i is the
//    group's share of the redundancy (Σ over all rows of h_i is the number
//    of parameters): vᵀPv / r_g is the group's variance component
//    (Förstner 1979), 1 when its stated sigmas describe its data.
// And a point withheld, exactly to first order from the same inverse (the
// block-deletion update): its rows leave the normal equations, which at the
// optimum leaves the rest a gradient g_k. With s the reduced columns the
// point's rows touch, C = Σ_U[s,s] and S_k the point's share of S,
//
//   Δ_s = (C⁻¹ − S_k)⁻¹ g_k,  S_k = U_k − W_kᵀ V_k⁻¹ W_k,  g_k = b_kᵀ r − W_kᵀ V_k⁻¹ a_kᵀ r
//
// the Gauss-Newton step of the blocks in s without the point's rows (the
// Schur complement of S − S_k onto s is that of S less S_k); with only its
// prior rows withheld (the point stays, free) the same with V_k less the
// prior's, and the point's own step besides. One step from the optimum: the
// nonlinearity left is that of a move of a few millimetres.
// A 600-image block (3,700 reduced parameters) takes a few seconds: the
// dense inverse of S dominates.

#include <ceres/problem.h>

#include <Eigen/Core>
#include <string>
#include <vector>

namespace aerotri {
namespace internal {

struct PrecisionProblem {
  ceres::Problem* problem = nullptr;
  std::vector<double*> points;   // 3-vectors eliminated first (no manifold)
  std::vector<double*> reduced;  // the other varying blocks, in this order
  std::vector<ceres::ResidualBlockId> adjusted;  // the adjustment's residuals
  struct Rows {
    std::vector<ceres::ResidualBlockId> ids;
    int point = -1;            // index into points (marks), or -1
    double* position = nullptr;  // the point's block (outside points, for checks)
  };
  std::vector<Rows> marks;   // one residual block each, of a point in `points`
  std::vector<Rows> checks;  // residual blocks added after the solve, not in `adjusted`
  // Groups of rows of `adjusted`: each entry a residual block and the mask of
  // its residual components that belong to the group (bit k: component k).
  struct Group {
    std::vector<std::pair<ceres::ResidualBlockId, unsigned>> rows;
  };
  std::vector<Group> groups;
  // Points (indices into `points`) to withhold, each on its own: all their
  // rows, or with withhold_marks false only their prior's (the rows that
  // hold no reduced column).
  std::vector<int> withheld;
  bool withhold_marks = true;
  int num_threads = 1;
};

// One withheld point's update: the tangent step of every reduced block its
// rows touch (columns `cols` of Σ_U, whole blocks), and with its marks kept
// the point's own step.
struct WithheldUpdate {
  bool ok = false;
  std::string note;  // why not, when !ok
  std::vector<int> cols;
  Eigen::VectorXd delta;
  Eigen::Vector3d point_delta = Eigen::Vector3d::Zero();
};

struct MarkCofactor {
  Eigen::Vector2d residual = Eigen::Vector2d::Zero();  // weighted, no loss
  Eigen::Vector2d qvv = Eigen::Vector2d::Zero();       // redundancy numbers
};

struct GroupRedundancy {
  int rows = 0;               // residual components in the group
  double sum_squares = 0.0;   // vᵀPv (weighted, loss applied)
  double leverage = 0.0;      // Σ h_i; redundancy = rows − leverage
};

struct PrecisionSolution {
  bool ok = false;
  std::string note;  // why not, when !ok
  std::vector<int> reduced_offset;  // first column of each reduced block in reduced_cov
  Eigen::MatrixXd reduced_cov;      // Σ_U, tangent coordinates
  std::vector<Eigen::Matrix3d> point_cov;  // index-aligned with points
  // Points whose rays are (nearly) parallel: not determined along them, so
  // without a finite covariance (point_cov is then meaningless); the
  // cameras' covariance is exact all the same.
  std::vector<char> point_undetermined;  // index-aligned with points
  int undetermined_points = 0;
  std::vector<Eigen::Matrix3d> check_cov;  // with checks
  std::vector<MarkCofactor> marks;
  std::vector<GroupRedundancy> groups;  // with PrecisionProblem::groups
  std::vector<WithheldUpdate> withheld;  // with PrecisionProblem::withheld
  int num_rows = 0;    // rows of the adjustment
  int num_params = 0;  // its tangent parameters (points and reduced)
};

PrecisionSolution SolvePrecision(const PrecisionProblem& p);

}  // namespace internal
}  // namespace aerotri
