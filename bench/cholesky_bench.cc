// SPDX-License-Identifier: BSD-3-Clause
// The reduced system's Cholesky: Eigen's LLT (one thread) against aerotri's
// blocked factorisation (dense_cholesky.h) on the given threads, alternately,
// at the sizes the survey engine meets (3,086 columns: 513 photos; 4,000:
// the dense limit). Prints each size's best of 3 and the ratio.
// Usage: cholesky_bench [threads]   (default 2)
#include <Eigen/Cholesky>
#include <chrono>
#include <cstdio>
#include <cstdlib>

#include "libphoto/adjust/dense_cholesky.h"

int main(int argc, char** argv) {
  const unsigned threads = argc > 1 ? static_cast<unsigned>(std::atoi(argv[1])) : 2u;
  using Clock = std::chrono::steady_clock;
  for (const int n : {500, 1500, 3086, 4000}) {
    std::srand(n);
    const Eigen::MatrixXd g = Eigen::MatrixXd::Random(n, n);
    Eigen::MatrixXd s = g * g.transpose();
    s.diagonal().array() += n;
    double eigen_s = 1e30, ours_s = 1e30, diff = 0.0;
    for (int round = 0; round < 3; ++round) {
      Eigen::MatrixXd a = s, b = s;
      auto t = Clock::now();
      Eigen::LLT<Eigen::Ref<Eigen::MatrixXd>, Eigen::Lower> llt(a);
      eigen_s = std::min(eigen_s, std::chrono::duration<double>(Clock::now() - t).count());
      t = Clock::now();
      if (!aerotri::internal::CholeskyInPlace(&b, threads)) return 1;
      ours_s = std::min(ours_s, std::chrono::duration<double>(Clock::now() - t).count());
      const Eigen::MatrixXd la = a.triangularView<Eigen::Lower>(), lb = b.triangularView<Eigen::Lower>();
      diff = (la - lb).cwiseAbs().maxCoeff() / la.cwiseAbs().maxCoeff();
    }
    std::printf("n=%d  eigen_llt_s=%.3f  aerotri_%u_threads_s=%.3f  ratio=%.2f  max_rel_diff=%.1e\n", n, eigen_s, threads,
                ours_s, ours_s / eigen_s, diff);
  }
  return 0;
}
