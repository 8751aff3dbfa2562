// Solving a changed XFEM system (thesis §6.4, Eq. 6.22, after a re-cut of some cells) with the
// factorization of an earlier one instead of factorizing again (issue 11 §3; the thesis
// factorizes every system). Conjugate gradients, preconditioned by a symmetric multiplicative Schwarz pair:
// the old factorization on the DOFs common to both systems, and an exact factorization of the
// new matrix on the DOFs whose rows changed (plus a layer of neighbours).
#pragma once

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "xfem/sparse_cholesky.h"

namespace parafab::xfem {

struct PcgOptions {
  /// Stop at ‖b − K x‖ ≤ tolerance · ‖b‖ (the true residual, recomputed at the end).
  double tolerance = 1e-10;
  int max_iterations = 100;
};

struct PcgResult {
  bool converged = false;
  std::string message;  ///< why not
  int iterations = 0;
  double residual = 0;  ///< ‖b − K x‖ / ‖b‖ at the end
  Eigen::VectorXd x;
};

/// Conjugate gradients on K x = b (K symmetric positive definite), preconditioned by
/// apply(r, z): z = M⁻¹ r (M symmetric positive definite), from x0 (size 0: zero).
PcgResult preconditioned_cg(const Eigen::SparseMatrix<double>& K, const Eigen::VectorXd& b,
                            const std::function<void(const Eigen::VectorXd&, Eigen::VectorXd&)>& apply,
                            const Eigen::VectorXd& x0, const PcgOptions& options = {});

struct ReusedFactorizationOptions {
  /// Layers of neighbours (through K's pattern) added to the changed DOFs of the local solve.
  int overlap = 1;
  /// A row counts as changed when an entry differs from the old row by more than this times the
  /// row's largest entry (kept element matrices are copies, so kept rows agree to round-off).
  double row_tolerance = 1e-12;
};

/// A preconditioner of a system K whose DOF i is DOF old_of[i] of the factorized K_old (−1:
/// new), from two solves: B_O r = Pᵀ K_old⁻¹ P r, where P scatters the unchanged DOFs (mapped,
/// and their row of K equals their row of K_old) into the old numbering (the others get 0),
/// and B_L r = R_Lᵀ K_LL⁻¹ R_L r on the changed DOFs (new, or another row) and `overlap` layers
/// of their neighbours, K_LL being K on L (factorized here). Combined as symmetric
/// multiplicative Schwarz, z = B_L r, z += B_O (r − K z), z += B_L (r − K z) (symmetric; CG
/// checks that it is positive, else the caller factorizes).
class ReusedFactorization {
 public:
  /// Throws parafab::Error when `old` holds no Cholesky factorization or the sizes disagree.
  /// K is shared, not copied (a hex27 system of 10⁴ unknowns holds ~50 MB), and must not change
  /// afterwards. The row comparison takes 12 bytes per old unknown and thread.
  ReusedFactorization(std::shared_ptr<const SparseCholesky> old, const Eigen::SparseMatrix<double>& K_old,
                      std::shared_ptr<const Eigen::SparseMatrix<double>> K, std::vector<int> old_of,
                      const ReusedFactorizationOptions& options = {});
  /// The same with a copy of K.
  ReusedFactorization(std::shared_ptr<const SparseCholesky> old, const Eigen::SparseMatrix<double>& K_old,
                      const Eigen::SparseMatrix<double>& K, std::vector<int> old_of,
                      const ReusedFactorizationOptions& options = {})
      : ReusedFactorization(std::move(old), K_old, std::make_shared<const Eigen::SparseMatrix<double>>(K),
                            std::move(old_of), options) {}
  void apply(const Eigen::VectorXd& r, Eigen::VectorXd& z) const;
  /// x with K x = b by PCG from x0 (size 0: zero).
  PcgResult solve(const Eigen::VectorXd& b, const Eigen::VectorXd& x0, const PcgOptions& options) const;
  const Eigen::SparseMatrix<double>& matrix() const { return *K_; }
  /// x0 + B_L (b − K x0): the start CG uses.
  Eigen::VectorXd local_correction(const Eigen::VectorXd& b, const Eigen::VectorXd& x0) const;
  int mapped_dofs() const { return mapped_; }
  int changed_dofs() const { return changed_; }  ///< new DOFs and changed rows
  int local_dofs() const { return static_cast<int>(local_.size()); }  ///< with the overlap
  double setup_seconds = 0;  ///< row comparison and the local factorization

 private:
  void apply_old(const Eigen::VectorXd& r, Eigen::VectorXd& z) const;    // z += B_O r
  void apply_local(const Eigen::VectorXd& r, Eigen::VectorXd& z) const;  // z += B_L r
  std::shared_ptr<const SparseCholesky> old_;
  int old_factorizations_ = 0;
  std::shared_ptr<const Eigen::SparseMatrix<double>> K_;  // compressed
  std::vector<int> old_of_, local_;
  SparseCholesky local_factor_;
  int mapped_ = 0, changed_ = 0;
};

}  // namespace parafab::xfem
