// The kept sparse factorization of the XFEM systems (thesis §6.4, Eq. 6.22 and 6.17–6.18).
#include "xfem/sparse_cholesky.h"

#include <Eigen/CholmodSupport>
#include <Eigen/SparseLU>
#include <unistd.h>

#include <chrono>
#include <cstdarg>
#include <cstdio>
#include <cmath>
#include <fstream>
#include <mutex>

#include "common/error.h"

namespace parafab::xfem {

namespace {
// Eigen keeps CHOLMOD's factor protected; the analysis's sizes are read from it.
struct SupernodalLlt : Eigen::CholmodSupernodalLLT<Eigen::SparseMatrix<double>> {
  const cholmod_factor* factor() const { return m_cholmodFactor; }
};

// CHOLMOD prints its warnings ("matrix not positive definite", then handled by the LU
// fallback) through SuiteSparse's printf, i.e. on stdout, where the CLI writes its JSON: they
// go to stderr instead.
int print_to_stderr(const char* format, ...) {
  va_list args;
  va_start(args, format);
  const int n = std::vfprintf(stderr, format, args);
  va_end(args);
  return n;
}
}  // namespace

double SparseCholesky::default_memory_limit_mb() {
  return 0.7 * static_cast<double>(sysconf(_SC_PHYS_PAGES)) * static_cast<double>(sysconf(_SC_PAGE_SIZE)) / 1e6;
}

double SparseCholesky::resident_mb() {
  std::ifstream statm("/proc/self/statm");  // size resident shared ... (pages)
  double size = 0, resident = 0;
  if (!(statm >> size >> resident)) return 0;
  return resident * static_cast<double>(sysconf(_SC_PAGE_SIZE)) / 1e6;
}

struct SparseCholesky::Impl {
  SupernodalLlt llt;
  std::unique_ptr<Eigen::SparseLU<Eigen::SparseMatrix<double>>> lu;
  std::shared_ptr<const Eigen::SparseMatrix<double>> K;  // for iterative refinement (compressed)
};

SparseCholesky::SparseCholesky() : impl_(std::make_unique<Impl>()) {
  static std::once_flag once;
  std::call_once(once, [] {
#if defined(SUITESPARSE_MAIN_VERSION) && SUITESPARSE_MAIN_VERSION >= 7
    SuiteSparse_config_printf_func_set(print_to_stderr);  // the struct is private from SuiteSparse 7
#else
    SuiteSparse_config.printf_func = print_to_stderr;
#endif
  });
}
SparseCholesky::~SparseCholesky() = default;
SparseCholesky::SparseCholesky(SparseCholesky&&) noexcept = default;
SparseCholesky& SparseCholesky::operator=(SparseCholesky&&) noexcept = default;

bool SparseCholesky::same_pattern(const Eigen::SparseMatrix<double>& K) const {
  if (status_ == Status::Empty || K.rows() != rows_ || K.cols() != rows_ || !K.isCompressed()) return false;
  if (static_cast<size_t>(K.nonZeros()) != inner_.size()) return false;
  return std::equal(outer_.begin(), outer_.end(), K.outerIndexPtr()) &&
         std::equal(inner_.begin(), inner_.end(), K.innerIndexPtr());
}

void SparseCholesky::analyze(const Eigen::SparseMatrix<double>& pattern) {
  PARAFAB_VERIFY(pattern.rows() == pattern.cols(),
                 "sparse Cholesky: the matrix must be square, got " << pattern.rows() << " × " << pattern.cols());
  const auto t0 = std::chrono::steady_clock::now();
  Eigen::SparseMatrix<double> copy;
  if (!pattern.isCompressed()) copy = pattern, copy.makeCompressed();
  const Eigen::SparseMatrix<double>& P = pattern.isCompressed() ? pattern : copy;
  cholmod_common& c = impl_->llt.cholmod();
  if (P.rows() >= metis_from) {
    c.nmethods = 1, c.method[0].ordering = CHOLMOD_METIS, c.postorder = 1;
  } else {
    c.nmethods = 0;  // CHOLMOD's default: AMD (METIS only when AMD's fill is very poor)
  }
  impl_->llt.analyzePattern(P);
  impl_->lu.reset();
  // The factor's real storage (supernodal: xsize values, amalgamation zeros included) and the
  // flops of a simplicial LLᵀ, both known from the symbolic analysis alone.
  const cholmod_factor* L = impl_->llt.factor();
  factor_entries_ = L ? static_cast<double>(L->is_super ? L->xsize : L->nzmax) : 0.0;
  factor_flops_ = c.fl;
  rows_ = static_cast<int>(P.rows());
  outer_.assign(P.outerIndexPtr(), P.outerIndexPtr() + P.outerSize() + 1);
  inner_.assign(P.innerIndexPtr(), P.innerIndexPtr() + P.nonZeros());
  status_ = Status::Analyzed;
  message_.clear();
  ++analyses;
  analyze_seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

bool SparseCholesky::factorize(const Eigen::SparseMatrix<double>& K_in) {
  auto K = std::make_shared<Eigen::SparseMatrix<double>>(K_in);
  K->makeCompressed();
  return factorize(std::shared_ptr<const Eigen::SparseMatrix<double>>(std::move(K)));
}

bool SparseCholesky::factorize(std::shared_ptr<const Eigen::SparseMatrix<double>> K_in) {
  PARAFAB_VERIFY(K_in, "sparse Cholesky: factorize without a matrix");
  if (!K_in->isCompressed()) {
    auto compressed = std::make_shared<Eigen::SparseMatrix<double>>(*K_in);
    compressed->makeCompressed();
    K_in = std::move(compressed);
  }
  const Eigen::SparseMatrix<double>& K = *K_in;
  if (!same_pattern(K)) analyze(K);
  // Refuse before the numeric factorization allocates a factor the machine cannot hold: the
  // analysis knows the factor's size exactly; the rest of the run is what it holds now.
  if (memory_limit_mb > 0) {
    const double held = resident_mb();
    PARAFAB_VERIFY(factor_mb() + held <= memory_limit_mb,
                   "the sparse Cholesky factor of these " << rows_ << " unknowns needs " << std::lround(factor_mb())
                   << " MB (" << factor_entries_ << " values by CHOLMOD's analysis) and the run already holds "
                   << std::lround(held) << " MB: more than the " << std::lround(memory_limit_mb)
                   << " MB allowed (memory_limit_mb; default 70% of the memory): use fewer cells");
  }
  const auto t0 = std::chrono::steady_clock::now();
  impl_->lu.reset();
  impl_->llt.factorize(K);
  ++factorizations;
  if (impl_->llt.info() == Eigen::Success) {
    status_ = Status::Factorized;
    message_.clear();
  } else {  // not positive definite: too small a Nitsche β, an indefinite Newton step, no support
    auto lu = std::make_unique<Eigen::SparseLU<Eigen::SparseMatrix<double>>>();
    lu->compute(K);
    if (lu->info() == Eigen::Success) {
      impl_->lu = std::move(lu);
      status_ = Status::FactorizedByLU;
      message_ = "matrix not positive definite; factorized by sparse LU";
    } else {
      status_ = Status::Failed;
      message_ = "matrix singular (" + std::to_string(rows_) + " unknowns): " + lu->lastErrorMessage();
    }
  }
  impl_->K = std::move(K_in);
  factorize_seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return IsDone();
}

Eigen::VectorXd SparseCholesky::solve(const Eigen::VectorXd& b, int refinements) const {
  PARAFAB_VERIFY(IsDone(), "sparse Cholesky: solve without a factorization (" << (message_.empty() ? "not factorized" : message_) << ")");
  PARAFAB_VERIFY(b.size() == rows_, "sparse Cholesky: right-hand side of size " << b.size() << ", expected " << rows_);
  auto apply = [&](const Eigen::VectorXd& r) -> Eigen::VectorXd {
    return impl_->lu ? Eigen::VectorXd(impl_->lu->solve(r)) : Eigen::VectorXd(impl_->llt.solve(r));
  };
  Eigen::VectorXd x = apply(b);
  for (int k = 0; k < refinements; ++k) x += apply(b - *impl_->K * x);
  return x;
}

}  // namespace parafab::xfem
