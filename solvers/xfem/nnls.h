// Non-negative least squares (Lawson & Hanson 1974, Ch. 23) for the optional non-negative
// weights of moment-fitted rules (thesis Eq. 6.11 solved as min ‖A w − b‖ s.t. w ≥ 0).
#pragma once

#include <Eigen/Core>

namespace parafab::xfem {

struct NnlsOptions {
  int max_iterations = 0;  ///< inner least-squares solves; 0: 3 × (number of columns)
  /// Optimality: stop when every inactive column's dual Aᵀ(b − A x) is ≤ this.
  /// 0: 10 · ε · ‖A‖₁ · max(rows, cols) · ‖b‖∞.
  double tolerance = 0;
};

struct NnlsResult {
  Eigen::VectorXd x;         ///< x ≥ 0
  double residual_norm = 0;  ///< ‖A x − b‖₂
  int iterations = 0;
  bool converged = false;  ///< KKT conditions met before max_iterations
};

/// min ‖A x − b‖₂ subject to x ≥ 0. Throws parafab::Error on mismatched dimensions.
NnlsResult solve_nnls(const Eigen::MatrixXd& A, const Eigen::VectorXd& b,
                      const NnlsOptions& options = {});

}  // namespace parafab::xfem
