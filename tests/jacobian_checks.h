// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// Shared helpers of the Jacobian test battery: a comparison that reports the
// worst entry, so the same checker is used on real Jacobians and on the
// deliberately wrong one that it must catch.

#include <Eigen/Core>
#include <cmath>
#include <sstream>
#include <string>

namespace aerotri::testing {

// Largest |a - b| / max(1, |b|) over all entries; sets *where to "row,col".
inline double WorstRelativeError(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b,
                                 std::string* where = nullptr) {
  double worst = 0.0;
  for (int r = 0; r < a.rows(); ++r) {
    for (int c = 0; c < a.cols(); ++c) {
      const double e = std::abs(a(r, c) - b(r, c)) / std::max(1.0, std::abs(b(r, c)));
      if (!(e <= worst)) {
        worst = e;
        if (where) {
          std::ostringstream s;
          s << r << "," << c;
          *where = s.str();
        }
      }
    }
  }
  return worst;
}

}  // namespace aerotri::testing
