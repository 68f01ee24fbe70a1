// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// aerotri's Levenberg–Marquardt over a Ceres problem as the survey
// adjustment builds it: every residual the problem holds (reprojections,
// target marks, GPS, control, attitude, intrinsics and readout priors, with
// their losses), every manifold and held block, the points eliminated by an
// explicit Schur complement and the reduced system — cameras, intrinsics per
// camera group, GNSS offsets and drift, readouts, control points — solved by
// Cholesky, dense or sparse by its size.
//
// Why not ceres::Solve here: a survey's residuals differ in size (a control
// prior has three rows, a mark two) and its camera blocks too (rotation,
// centre, a camera group's intrinsics), so Ceres' Schur eliminator runs its
// fully dynamic variant and locks a mutex per reduced block it updates; the
// intrinsics block, which every observation touches, serialises the threads.
// Here each thread accumulates its own reduced system, summed afterwards,
// and the cost functions are Ceres' own, evaluated directly.
//
// The mathematics is Ceres' Levenberg–Marquardt (its defaults): the step
// solves (JᵀJ + D/μ) δ = −Jᵀr, D the diagonal of JᵀJ clamped to
// [1e-6, 1e32], μ the trust radius (options.initial_trust_region_radius),
// grown by 1/max(1/3, 1 − (2ρ − 1)³) on a step of gain ratio ρ above
// options.min_relative_decrease, else divided by a factor that doubles on each
// rejection; robust losses through Triggs' correction, as Ceres applies it.
// Stopping as Ceres states it: function, gradient and parameter tolerances,
// iteration and time limits, and the options' iteration callbacks
// (SOLVER_TERMINATE_SUCCESSFULLY ends with USER_SUCCESS). The summary's
// fields are those ceres::Solve fills that a caller reads: costs,
// iterations, termination and message, times, and the reduced problem's
// residual and effective parameter counts.

#include <ceres/problem.h>
#include <ceres/solver.h>

#include <string>
#include <vector>

namespace aerotri {

// The reduced system's size up to which it is held dense (an n x n matrix
// per thread, factored by the blocked Cholesky of dense_cholesky.h); beyond
// it only the blocks that share a point or a residual are held, factored by
// CHOLMOD (sparse_cholesky.h), so that a thousand-photo survey stays here.
constexpr int kMaxSchurLmDenseSize = 4000;

// How the reduced system is held: dense up to kMaxSchurLmDenseSize columns
// and sparse beyond (auto), or as asked (tests compare the two).
enum class ReducedStorage { kAuto, kDense, kSparse };

// Solves `problem` in place (its parameter blocks' values), `points`
// eliminated, when the solver takes it: every residual holds at most one of
// `points` (3-vectors without manifold). Otherwise false with the reason,
// the problem untouched. summary->linear_solver_type_used says how the
// reduced system was held: DENSE_SCHUR or SPARSE_SCHUR.
bool SolveSchurLm(const ceres::Solver::Options& options, ceres::Problem* problem, const std::vector<double*>& points,
                  ceres::Solver::Summary* summary, std::string* why_not,
                  ReducedStorage storage = ReducedStorage::kAuto);

}  // namespace aerotri
