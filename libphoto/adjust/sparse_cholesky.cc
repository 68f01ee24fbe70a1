// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/adjust/sparse_cholesky.h"

#include <cholmod.h>

#include <limits>
#include <stdexcept>
#include <string>

namespace aerotri {
namespace internal {

struct SparseCholesky::Impl {
  int n = 0;
  std::vector<int> colptr, rows;
  cholmod_common common;
  cholmod_factor* factor = nullptr;

  // A header over the pattern and `x`: CHOLMOD reads it, never owns it.
  cholmod_sparse Header(double* x) {
    cholmod_sparse a{};
    a.nrow = a.ncol = static_cast<size_t>(n);
    a.nzmax = rows.size();
    a.p = colptr.data();
    a.i = rows.data();
    a.x = x;
    a.stype = -1;  // symmetric, the lower triangle read
    a.itype = CHOLMOD_INT;
    a.xtype = CHOLMOD_REAL;
    a.dtype = CHOLMOD_DOUBLE;
    a.sorted = 1;
    a.packed = 1;
    return a;
  }
};

SparseCholesky::SparseCholesky(int n, std::vector<int> colptr, std::vector<int> rows) : impl_(new Impl) {
  if (n < 0 || colptr.size() != static_cast<size_t>(n) + 1 || colptr.back() != static_cast<int>(rows.size())) {
    throw std::invalid_argument("SparseCholesky: the pattern's column pointers do not match its " +
                                std::to_string(rows.size()) + " rows");
  }
  impl_->n = n;
  impl_->colptr = std::move(colptr);
  impl_->rows = std::move(rows);
  cholmod_start(&impl_->common);
  impl_->common.print = 0;  // errors are returned, not printed
  impl_->common.error_handler = nullptr;
  // Always supernodal, hence L Lᵀ: a simplicial L D Lᵀ would factor an
  // indefinite matrix without a word, where LM must see the failure.
  impl_->common.supernodal = CHOLMOD_SUPERNODAL;
}

SparseCholesky::~SparseCholesky() {
  if (impl_->factor != nullptr) cholmod_free_factor(&impl_->factor, &impl_->common);
  cholmod_finish(&impl_->common);
}

int SparseCholesky::size() const { return impl_->n; }
long SparseCholesky::nonzeros() const { return static_cast<long>(impl_->rows.size()); }

bool SparseCholesky::Factorize(const double* values) {
  Impl& m = *impl_;
  if (m.n == 0) return true;
  cholmod_sparse a = m.Header(const_cast<double*>(values));
  if (m.factor == nullptr) {
    m.factor = cholmod_analyze(&a, &m.common);  // the ordering and the symbolic factor, once
    if (m.factor == nullptr) throw std::runtime_error("CHOLMOD could not analyse the reduced system's pattern");
  }
  const int ok = cholmod_factorize(&a, m.factor, &m.common);
  return ok != 0 && m.common.status == CHOLMOD_OK && m.factor->minor == static_cast<size_t>(m.n);
}

Eigen::VectorXd SparseCholesky::Solve(const Eigen::VectorXd& b) {
  Impl& m = *impl_;
  Eigen::VectorXd x = Eigen::VectorXd::Zero(m.n);
  if (m.n == 0) return x;
  cholmod_dense rhs{};
  rhs.nrow = static_cast<size_t>(m.n);
  rhs.ncol = 1;
  rhs.nzmax = static_cast<size_t>(m.n);
  rhs.d = static_cast<size_t>(m.n);
  rhs.x = const_cast<double*>(b.data());
  rhs.xtype = CHOLMOD_REAL;
  rhs.dtype = CHOLMOD_DOUBLE;
  cholmod_dense* solution = cholmod_solve(CHOLMOD_A, m.factor, &rhs, &m.common);
  if (solution == nullptr) {
    x.setConstant(std::numeric_limits<double>::quiet_NaN());
    return x;
  }
  x = Eigen::Map<const Eigen::VectorXd>(static_cast<const double*>(solution->x), m.n);
  cholmod_free_dense(&solution, &m.common);
  return x;
}

long SparseCholesky::FactorNonzeros() const {
  const cholmod_factor* f = impl_->factor;
  if (f == nullptr) return 0;
  return f->is_super ? static_cast<long>(f->xsize) : static_cast<long>(f->nzmax);
}

}  // namespace internal
}  // namespace aerotri
