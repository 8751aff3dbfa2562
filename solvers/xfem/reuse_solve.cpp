// A changed XFEM system (thesis §6.4, Eq. 6.22) solved with an earlier factorization (issue 11 §3).
#include "xfem/reuse_solve.h"

#include <chrono>
#include <cmath>
#include <cstdio>

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include "common/error.h"

namespace parafab::xfem {

namespace {

// y = K x for a symmetric K stored by columns: y_i = (column i) · x, rows in parallel (TBB).
// Each y_i is one serial sum, so the result does not depend on the thread count.
void symmetric_product(const Eigen::SparseMatrix<double>& K, const Eigen::VectorXd& x, Eigen::VectorXd& y) {
  y.resize(K.rows());
  tbb::parallel_for(tbb::blocked_range<Eigen::Index>(0, K.cols(), 512), [&](const tbb::blocked_range<Eigen::Index>& range) {
    for (Eigen::Index i = range.begin(); i != range.end(); ++i) {
      double sum = 0;
      for (Eigen::SparseMatrix<double>::InnerIterator it(K, i); it; ++it) sum += it.value() * x(it.index());
      y(i) = sum;
    }
  });
}

}  // namespace

PcgResult preconditioned_cg(const Eigen::SparseMatrix<double>& K, const Eigen::VectorXd& b,
                            const std::function<void(const Eigen::VectorXd&, Eigen::VectorXd&)>& apply,
                            const Eigen::VectorXd& x0, const PcgOptions& o) {
  PARAFAB_VERIFY(K.rows() == K.cols() && K.rows() == b.size(),
                 "preconditioned_cg: matrix " << K.rows() << " × " << K.cols() << ", right-hand side " << b.size());
  PARAFAB_VERIFY(x0.size() == 0 || x0.size() == b.size(), "preconditioned_cg: start of size " << x0.size() << ", expected " << b.size());
  PcgResult res;
  res.x = x0.size() ? x0 : Eigen::VectorXd::Zero(b.size());
  const double bnorm = b.norm();
  if (bnorm == 0) {
    res.x.setZero();
    res.converged = true;
    return res;
  }
  const double stop = o.tolerance * bnorm;
  Eigen::VectorXd Ap;
  symmetric_product(K, res.x, Ap);
  Eigen::VectorXd r = b - Ap, z(b.size()), p;
  double rnorm = r.norm();
  if (rnorm <= stop) {
    res.converged = true;
    res.residual = rnorm / bnorm;
    return res;
  }
  apply(r, z);
  p = z;
  double rz = r.dot(z);
  for (res.iterations = 1; res.iterations <= o.max_iterations; ++res.iterations) {
    symmetric_product(K, p, Ap);
    const double pAp = p.dot(Ap);
    if (!(pAp > 0) || !(rz > 0)) {
      char msg[160];
      std::snprintf(msg, sizeof msg, "the matrix or the preconditioner is not positive definite (pᵀKp = %.3g, rᵀz = %.3g)",
                    pAp, rz);
      res.message = msg;
      break;
    }
    const double alpha = rz / pAp;
    res.x.noalias() += alpha * p;
    r.noalias() -= alpha * Ap;
    rnorm = r.norm();
    if (!std::isfinite(rnorm)) {
      res.message = "the residual is not finite";
      break;
    }
    if (rnorm <= stop) break;
    apply(r, z);
    const double rz_next = r.dot(z);
    p = z + (rz_next / rz) * p;
    rz = rz_next;
  }
  res.iterations = std::min(res.iterations, o.max_iterations);
  // The true residual (the recurrence drifts by round-off).
  symmetric_product(K, res.x, Ap);
  res.residual = (b - Ap).norm() / bnorm;
  res.converged = res.message.empty() && res.residual <= o.tolerance;
  if (res.message.empty() && !res.converged) {
    char msg[160];
    std::snprintf(msg, sizeof msg, "relative residual %.3g after %d iterations (tolerance %.3g)", res.residual,
                  res.iterations, o.tolerance);
    res.message = msg;
  }
  return res;
}

ReusedFactorization::ReusedFactorization(std::shared_ptr<const SparseCholesky> old, const Eigen::SparseMatrix<double>& K_old,
                                         std::shared_ptr<const Eigen::SparseMatrix<double>> K_new, std::vector<int> old_of,
                                         const ReusedFactorizationOptions& o)
    : old_(std::move(old)), K_(std::move(K_new)), old_of_(std::move(old_of)) {
  const auto t0 = std::chrono::steady_clock::now();
  PARAFAB_VERIFY(old_ && old_->status() == SparseCholesky::Status::Factorized,
                 "reused factorization: the old system holds no Cholesky factorization");
  PARAFAB_VERIFY(K_old.rows() == old_->rows() && K_old.cols() == old_->rows(),
                 "reused factorization: old matrix " << K_old.rows() << " × " << K_old.cols() << ", factorization of " << old_->rows());
  PARAFAB_VERIFY(K_ && K_->rows() == K_->cols() && static_cast<size_t>(K_->rows()) == old_of_.size(),
                 "reused factorization: matrix " << (K_ ? K_->rows() : 0) << " × " << (K_ ? K_->cols() : 0)
                                                 << ", DOF map of " << old_of_.size());
  old_factorizations_ = old_->factorizations;
  if (!K_->isCompressed()) {
    auto compressed = std::make_shared<Eigen::SparseMatrix<double>>(*K_);
    compressed->makeCompressed();
    K_ = std::move(compressed);
  }
  const Eigen::SparseMatrix<double>& K = *K_;
  const int n = static_cast<int>(K.rows()), n_old = static_cast<int>(K_old.rows());
  for (int i = 0; i < n; ++i)
    PARAFAB_VERIFY(old_of_[i] < n_old, "reused factorization: DOF " << i << " mapped to " << old_of_[i] << " of " << n_old);
  // Changed rows: unmapped DOFs, and mapped ones whose row differs from the old row (another
  // pattern or other values). K and K_old are symmetric: column j is row j. Rows in parallel,
  // each thread with its own scatter of the old row.
  std::vector<char> changed(n, 0);
  struct OldRow {
    std::vector<double> value;
    std::vector<int> stamp;
  };
  tbb::enumerable_thread_specific<OldRow> scratch([n_old] { return OldRow{std::vector<double>(n_old, 0.0), std::vector<int>(n_old, -1)}; });
  tbb::parallel_for(tbb::blocked_range<int>(0, n, 256), [&](const tbb::blocked_range<int>& range) {
    OldRow& w = scratch.local();
    for (int i = range.begin(); i != range.end(); ++i) {
      const int oi = old_of_[i];
      if (oi < 0) {
        changed[i] = 1;
        continue;
      }
      int old_count = 0;
      double scale = 0;
      for (Eigen::SparseMatrix<double>::InnerIterator it(K_old, oi); it; ++it) {
        w.stamp[it.index()] = i, w.value[it.index()] = it.value(), ++old_count;
        scale = std::max(scale, std::abs(it.value()));
      }
      int count = 0;
      for (Eigen::SparseMatrix<double>::InnerIterator it(K, i); it; ++it) {
        ++count;
        const int oj = old_of_[it.index()];
        if (oj < 0 || w.stamp[oj] != i || std::abs(w.value[oj] - it.value()) > o.row_tolerance * scale) {
          changed[i] = 1;
          break;
        }
      }
      if (count != old_count) changed[i] = 1;
    }
  });
  for (int i = 0; i < n; ++i) mapped_ += old_of_[i] >= 0, changed_ += changed[i];
  // The old factorization serves only the unchanged DOFs: on a changed row the old stiffness can
  // be far from the new one (a sliver that grew, material that went), and its inverse there
  // would spoil the preconditioner; those rows are the local solve's.
  for (int i = 0; i < n; ++i)
    if (changed[i]) old_of_[i] = -1;
  // The local set: changed DOFs and `overlap` layers of neighbours.
  std::vector<char> in = changed;
  for (int layer = 0; layer < o.overlap; ++layer) {
    std::vector<char> next = in;
    for (int j = 0; j < n; ++j)
      if (in[j])
        for (Eigen::SparseMatrix<double>::InnerIterator it(K, j); it; ++it) next[it.index()] = 1;
    in = std::move(next);
  }
  std::vector<int> local_of(n, -1);
  for (int i = 0; i < n; ++i)
    if (in[i]) local_of[i] = static_cast<int>(local_.size()), local_.push_back(i);
  if (!local_.empty()) {
    // K on the local set, column by column: local numbers increase with the global ones, so
    // every column's rows come out sorted (no triplets, no sort).
    const int m = static_cast<int>(local_.size());
    auto KLL = std::make_shared<Eigen::SparseMatrix<double>>(m, m);
    Eigen::Index nnz = 0;
    for (int j : local_)
      for (Eigen::SparseMatrix<double>::InnerIterator it(K, j); it; ++it) nnz += local_of[it.index()] >= 0;
    KLL->resizeNonZeros(nnz);
    int* outer = KLL->outerIndexPtr();
    int* inner = KLL->innerIndexPtr();
    double* value = KLL->valuePtr();
    Eigen::Index k = 0;
    for (int c = 0; c < m; ++c) {
      outer[c] = static_cast<int>(k);
      for (Eigen::SparseMatrix<double>::InnerIterator it(K, local_[c]); it; ++it)
        if (local_of[it.index()] >= 0) inner[k] = local_of[it.index()], value[k] = it.value(), ++k;
    }
    outer[m] = static_cast<int>(k);
    local_factor_.factorize(std::shared_ptr<const Eigen::SparseMatrix<double>>(std::move(KLL)));
    PARAFAB_VERIFY(local_factor_.status() == SparseCholesky::Status::Factorized,
                   "reused factorization: the changed block (" << local_.size() << " DOFs) is not positive definite");
  }
  setup_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

void ReusedFactorization::apply_old(const Eigen::VectorXd& r, Eigen::VectorXd& z) const {
  PARAFAB_VERIFY(old_->factorizations == old_factorizations_ && old_->status() == SparseCholesky::Status::Factorized,
                 "reused factorization: the old factorization was replaced since this preconditioner was built");
  const int n = static_cast<int>(r.size());
  Eigen::VectorXd ro = Eigen::VectorXd::Zero(old_->rows());
  for (int i = 0; i < n; ++i)
    if (old_of_[i] >= 0) ro(old_of_[i]) = r(i);
  const Eigen::VectorXd zo = old_->solve(ro, 0);
  for (int i = 0; i < n; ++i)
    if (old_of_[i] >= 0) z(i) += zo(old_of_[i]);
}

void ReusedFactorization::apply_local(const Eigen::VectorXd& r, Eigen::VectorXd& z) const {
  if (local_.empty()) return;
  Eigen::VectorXd rl(local_.size());
  for (size_t k = 0; k < local_.size(); ++k) rl(k) = r(local_[k]);
  const Eigen::VectorXd zl = local_factor_.solve(rl, 0);
  for (size_t k = 0; k < local_.size(); ++k) z(local_[k]) += zl(k);
}

void ReusedFactorization::apply(const Eigen::VectorXd& r, Eigen::VectorXd& z) const {
  // Symmetric multiplicative Schwarz: local, old, local, each on the residual of the last.
  // Neither residual needs a full product with K: after the first local solve z lives on the
  // local DOFs (K z from their columns only), and the last local solve reads the residual on
  // the local DOFs only (their rows, i.e. columns by symmetry).
  z.setZero(r.size());
  if (local_.empty()) {
    apply_old(r, z);
    return;
  }
  apply_local(r, z);
  Eigen::VectorXd s = r;
  for (const int j : local_)
    for (Eigen::SparseMatrix<double>::InnerIterator it(*K_, j); it; ++it) s(it.index()) -= it.value() * z(j);
  apply_old(s, z);
  // s on the local rows only (apply_local reads nothing else): r − K z there.
  tbb::parallel_for(tbb::blocked_range<size_t>(0, local_.size(), 256), [&](const tbb::blocked_range<size_t>& range) {
    for (size_t k = range.begin(); k != range.end(); ++k) {
      const int j = local_[k];
      double Kz = 0;
      for (Eigen::SparseMatrix<double>::InnerIterator it(*K_, j); it; ++it) Kz += it.value() * z(it.index());
      s(j) = r(j) - Kz;
    }
  });
  apply_local(s, z);
}

Eigen::VectorXd ReusedFactorization::local_correction(const Eigen::VectorXd& b, const Eigen::VectorXd& x0) const {
  Eigen::VectorXd x = x0.size() ? x0 : Eigen::VectorXd::Zero(b.size());
  apply_local(Eigen::VectorXd(b - *K_ * x), x);
  return x;
}

PcgResult ReusedFactorization::solve(const Eigen::VectorXd& b, const Eigen::VectorXd& x0, const PcgOptions& o) const {
  // The start corrected on the local DOFs first: a new DOF starts at 0 next to neighbours that
  // carry the old displacement, which would leave a large residual there.
  return preconditioned_cg(*K_, b, [this](const Eigen::VectorXd& r, Eigen::VectorXd& z) { apply(r, z); },
                           local_correction(b, x0), o);
}

}  // namespace parafab::xfem
