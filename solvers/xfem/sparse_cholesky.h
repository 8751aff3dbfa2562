// The sparse solve of the XFEM systems (thesis §6.4, the linear systems of Eq. 6.22 and the
// Newton steps of Eq. 6.17–6.18): CHOLMOD's supernodal Cholesky kept as an object, so that
// the symbolic analysis (fill-reducing ordering, supernodes) is done once per sparsity
// pattern and the numeric factorization once per matrix. Later right-hand sides (an adjoint
// solve, another load case) reuse the factorization; later matrices with the same pattern
// (Newton iterations, a re-solve on an unchanged grid) reuse the analysis.
#pragma once

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <memory>
#include <string>
#include <vector>

namespace parafab::xfem {

class SparseCholesky {
 public:
  enum class Status {
    Empty,               ///< nothing analyzed yet
    Analyzed,            ///< symbolic analysis done, no numeric factorization
    Factorized,          ///< Cholesky factorization of a positive definite matrix
    FactorizedByLU,      ///< not positive definite: sparse LU fallback (solve still works)
    Failed               ///< singular (message says why); solve() throws
  };

  SparseCholesky();
  ~SparseCholesky();
  SparseCholesky(SparseCholesky&&) noexcept;
  SparseCholesky& operator=(SparseCholesky&&) noexcept;

  /// Systems of at least this many unknowns are ordered by METIS nested dissection, smaller
  /// ones by AMD (CHOLMOD's default). Measured on the L-bracket (bench_xfem_vs_calculix, the
  /// fresh runs): hex27 on 16 cells, 26,247 unknowns, factorization flops 1.17e10 → 5.3e9 and
  /// analysis + factorization 1.2 → 0.82 s; hex27 on 12 cells (10,485) 0.27 → 0.22 s; hex8 on
  /// 24 and 32 cells (10,374 / 22,242) about equal (METIS's longer analysis eats the gain).
  int metis_from = 10000;

  /// factorize() throws parafab::Error, before any numeric work, when the factor's memory (exact,
  /// from the symbolic analysis) plus what the process holds now (resident_mb()) exceeds this
  /// many MB (0: no limit). Default: 70% of physical memory.
  double memory_limit_mb = default_memory_limit_mb();
  static double default_memory_limit_mb();
  /// The process's resident memory now (Linux /proc/self/statm; 0 where unreadable).
  static double resident_mb();

  /// Symbolic analysis of K's pattern (square, both triangles stored as Eigen's
  /// SparseMatrix; only the pattern is read). Throws parafab::Error for a non-square matrix.
  void analyze(const Eigen::SparseMatrix<double>& pattern);
  /// Numeric factorization of K. Analyzes first when nothing is analyzed or K's pattern differs
  /// from the analyzed one (a same-pattern matrix reuses the analysis). Falls back to sparse LU
  /// when K is not positive definite. Returns IsDone(). Keeps a copy of K for refinement.
  bool factorize(const Eigen::SparseMatrix<double>& K);
  /// The same, keeping K itself for refinement (shared, not copied, unless it is uncompressed):
  /// K must not change afterwards.
  bool factorize(std::shared_ptr<const Eigen::SparseMatrix<double>> K);
  /// x with K x = b, plus `refinements` steps of iterative refinement (x += K⁻¹(b − K x)).
  /// Throws parafab::Error when nothing is factorized or b has the wrong size.
  Eigen::VectorXd solve(const Eigen::VectorXd& b, int refinements = 2) const;

  /// A factorization is held (Cholesky or the LU fallback): solve() works.
  bool IsDone() const { return status_ == Status::Factorized || status_ == Status::FactorizedByLU; }
  Status status() const { return status_; }
  const std::string& message() const { return message_; }
  int rows() const { return rows_; }
  /// True if K has exactly the analyzed pattern (same size, outer and inner indices).
  bool same_pattern(const Eigen::SparseMatrix<double>& K) const;

  /// From the last analysis: values stored in the factor L (supernodal, amalgamation zeros
  /// included), their memory in MB (8 bytes each), and the flops of the factorization.
  double factor_entries() const { return factor_entries_; }
  double factor_mb() const { return 8.0 * factor_entries_ / 1e6; }
  double factor_flops() const { return factor_flops_; }

  // Diagnostics: how often each step ran, and its accumulated wall time.
  int analyses = 0, factorizations = 0;
  double analyze_seconds = 0, factorize_seconds = 0;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  Status status_ = Status::Empty;
  std::string message_;
  int rows_ = 0;
  double factor_entries_ = 0, factor_flops_ = 0;
  std::vector<int> outer_, inner_;  // the analyzed pattern (compressed)
};

}  // namespace parafab::xfem
