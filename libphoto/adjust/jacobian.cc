// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/adjust/jacobian.h"

#include <ceres/cost_function.h>
#include <ceres/manifold.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <numeric>
#include <unordered_map>

#include "libphoto/base/parallel.h"

namespace aerotri {
namespace internal {

LossCorrector::LossCorrector(const ceres::LossFunction* loss, const double* r, int rows) {
  double sq = 0.0;
  for (int i = 0; i < rows; ++i) sq += r[i] * r[i];
  if (loss == nullptr) {
    cost = 0.5 * sq;
    return;
  }
  double rho[3];
  loss->Evaluate(sq, rho);
  cost = 0.5 * rho[0];
  sqrt_rho1 = std::sqrt(rho[1]);
  if (sq == 0.0 || rho[2] <= 0.0) {
    residual_scaling = sqrt_rho1;
    return;
  }
  const double alpha = 1.0 - std::sqrt(1.0 + 2.0 * sq * rho[2] / rho[1]);
  residual_scaling = sqrt_rho1 / (1.0 - alpha);
  alpha_sq_norm = alpha / sq;
}

namespace {

using RowMajor = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

struct Column {
  int col = -1;  // first column; -1 where the block is held
  int ambient = 0;
  int tangent = 0;
  RowMajor plus;  // the manifold's Plus Jacobian at the block's value (empty: none)
};

}  // namespace

bool EvaluateJacobian(const ceres::Problem& problem, const std::vector<ceres::ResidualBlockId>& residual_blocks,
                      const std::vector<double*>& parameter_blocks, int threads, std::vector<double>* residuals,
                      ceres::CRSMatrix* jacobian) {
  std::unordered_map<const double*, int> index;
  std::vector<Column> columns(parameter_blocks.size());
  int num_cols = 0;
  for (size_t b = 0; b < parameter_blocks.size(); ++b) {
    double* x = parameter_blocks[b];
    Column& c = columns[b];
    c.col = num_cols;
    c.ambient = problem.ParameterBlockSize(x);
    c.tangent = problem.ParameterBlockTangentSize(x);
    if (const ceres::Manifold* m = problem.GetManifold(x)) {
      c.plus.resize(c.ambient, c.tangent);
      m->PlusJacobian(x, c.plus.data());
    }
    num_cols += c.tangent;
    index.emplace(x, static_cast<int>(b));
  }
  // Each residual block's parameters (flat), the listed ones' indices, its
  // first row and first value.
  const size_t nb = residual_blocks.size();
  std::vector<double*> params;
  std::vector<int> listed;  // index into columns, or -1
  std::vector<long> param_begin(nb + 1, 0), value_begin(nb + 1, 0);
  std::vector<int> row_begin(nb + 1, 0);
  std::vector<double*> block_params;
  for (size_t k = 0; k < nb; ++k) {
    problem.GetParameterBlocksForResidualBlock(residual_blocks[k], &block_params);
    int width = 0;
    for (double* x : block_params) {
      const auto it = index.find(x);
      params.push_back(x);
      listed.push_back(it == index.end() ? -1 : it->second);
      if (it != index.end()) width += columns[it->second].tangent;
    }
    const int rows = problem.GetCostFunctionForResidualBlock(residual_blocks[k])->num_residuals();
    param_begin[k + 1] = static_cast<long>(params.size());
    row_begin[k + 1] = row_begin[k] + rows;
    value_begin[k + 1] = value_begin[k] + static_cast<long>(rows) * width;
  }
  ceres::CRSMatrix& crs = *jacobian;
  crs.num_rows = row_begin[nb];
  crs.num_cols = num_cols;
  crs.rows.assign(crs.num_rows + 1, 0);
  crs.cols.resize(value_begin[nb]);
  crs.values.resize(value_begin[nb]);
  residuals->assign(crs.num_rows, 0.0);

  const unsigned t = std::max(1u, std::min(ThreadCount(threads), static_cast<unsigned>(std::max<size_t>(nb, 1))));
  std::vector<char> ok(t, 1);
  ParallelFor(t, t, [&](std::size_t th) {
    std::vector<RowMajor> ambient;
    std::vector<double*> jac_ptrs;
    std::vector<int> order;
    RowMajor tangent;
    for (size_t k = nb * th / t; k < nb * (th + 1) / t; ++k) {
      const ceres::CostFunction* cost = problem.GetCostFunctionForResidualBlock(residual_blocks[k]);
      const ceres::LossFunction* loss = problem.GetLossFunctionForResidualBlock(residual_blocks[k]);
      const int rows = row_begin[k + 1] - row_begin[k];
      const long p0 = param_begin[k];
      const int np = static_cast<int>(param_begin[k + 1] - p0);
      ambient.resize(np);
      jac_ptrs.assign(np, nullptr);
      order.clear();
      for (int a = 0; a < np; ++a) {
        const int b = listed[p0 + a];
        if (b < 0) continue;
        ambient[a].resize(rows, columns[b].ambient);
        jac_ptrs[a] = ambient[a].data();
        order.push_back(a);
      }
      double* r = residuals->data() + row_begin[k];
      if (!cost->Evaluate(params.data() + p0, r, jac_ptrs.data())) {
        ok[th] = 0;
        return;
      }
      for (int i = 0; i < rows; ++i) {
        if (!std::isfinite(r[i])) {
          ok[th] = 0;
          return;
        }
      }
      const LossCorrector c(loss, r, rows);
      Eigen::Map<Eigen::VectorXd> rv(r, rows);
      // Columns ascending within the row.
      std::sort(order.begin(), order.end(),
                [&](int a, int b) { return columns[listed[p0 + a]].col < columns[listed[p0 + b]].col; });
      const long width = (value_begin[k + 1] - value_begin[k]) / std::max(rows, 1);
      long at = 0;
      for (int a : order) {
        const Column& col = columns[listed[p0 + a]];
        if (col.plus.size() > 0) {
          tangent.noalias() = ambient[a] * col.plus;
        } else {
          tangent = ambient[a];
        }
        if (!c.Identity()) {
          if (c.alpha_sq_norm != 0.0) tangent -= c.alpha_sq_norm * rv * (rv.transpose() * tangent);
          tangent *= c.sqrt_rho1;
        }
        if (!tangent.allFinite()) {
          ok[th] = 0;
          return;
        }
        for (int i = 0; i < rows; ++i) {
          const long v = value_begin[k] + i * width + at;
          for (int j = 0; j < col.tangent; ++j) {
            crs.cols[v + j] = col.col + j;
            crs.values[v + j] = tangent(i, j);
          }
        }
        at += col.tangent;
      }
      for (int i = 0; i < rows; ++i) crs.rows[row_begin[k] + i + 1] = static_cast<int>(value_begin[k] + (i + 1) * width);
      if (!c.Identity()) rv *= c.residual_scaling;
    }
  });
  return std::all_of(ok.begin(), ok.end(), [](char v) { return v != 0; });
}

}  // namespace internal
}  // namespace aerotri
