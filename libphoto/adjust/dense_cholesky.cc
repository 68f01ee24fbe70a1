// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/adjust/dense_cholesky.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <vector>

#include "libphoto/base/parallel.h"

namespace aerotri {
namespace internal {

bool CholeskyInPlace(Eigen::MatrixXd* a_inout, unsigned threads) {
  Eigen::MatrixXd& a = *a_inout;
  const Eigen::Index n = a.rows();
  const Eigen::Index nb = 128;
  const unsigned t = std::max(1u, threads);
  if (n <= 6 * nb || t == 1) {  // small: one thread is as fast (cholesky_bench)
    Eigen::LLT<Eigen::Ref<Eigen::MatrixXd>, Eigen::Lower> llt(a);
    return llt.info() == Eigen::Success;
  }
  for (Eigen::Index k0 = 0; k0 < n; k0 += nb) {
    const Eigen::Index kb = std::min(nb, n - k0);
    Eigen::Ref<Eigen::MatrixXd> diagonal = a.block(k0, k0, kb, kb);
    Eigen::LLT<Eigen::Ref<Eigen::MatrixXd>, Eigen::Lower> llt(diagonal);
    if (llt.info() != Eigen::Success) return false;
    const Eigen::Index r0 = k0 + kb, rest = n - r0;
    if (rest == 0) break;
    // The panel below: P = A_ik L_kk⁻ᵀ, in row shares.
    const Eigen::Index share = (rest + t - 1) / t;
    ParallelFor(t, t, [&](std::size_t th) {
      const Eigen::Index begin = r0 + static_cast<Eigen::Index>(th) * share;
      const Eigen::Index rows = std::min(share, n - begin);
      if (rows <= 0) return;
      a.block(k0, k0, kb, kb).triangularView<Eigen::Lower>().transpose().solveInPlace<Eigen::OnTheRight>(
          a.block(begin, k0, rows, kb));
    });
    // The trailing lower triangle: A_ij −= P_i P_jᵀ, by column blocks.
    const Eigen::Index blocks = (rest + nb - 1) / nb;
    ParallelFor(static_cast<std::size_t>(blocks), t, [&](std::size_t j) {
      const Eigen::Index c0 = r0 + static_cast<Eigen::Index>(j) * nb;
      const Eigen::Index cb = std::min(nb, n - c0);
      a.block(c0, c0, n - c0, cb).noalias() -= a.block(c0, k0, n - c0, kb) * a.block(c0, k0, cb, kb).transpose();
    });
  }
  return true;
}

Eigen::VectorXd CholeskySolve(const Eigen::MatrixXd& l, const Eigen::VectorXd& b) {
  Eigen::VectorXd x = b;
  l.triangularView<Eigen::Lower>().solveInPlace(x);
  l.triangularView<Eigen::Lower>().transpose().solveInPlace(x);
  return x;
}

}  // namespace internal
}  // namespace aerotri
