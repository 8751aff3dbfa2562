// The parameter projection of thesis §6.5.1-6.5.2: p⊥ = argmin ½‖p − p̃‖²_W s.t. c_para(p) = 0
// and bounds (Eq. 6.25-6.26), solved by Ipopt with exact first and second derivatives and warm
// starts, and its derivative dp⊥/dp̃ by the implicit function theorem (Eq. 6.29).
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "optimize/shape_constraints.h"

namespace parafab::optimize {

struct ProjectionOptions {
  double tolerance = 1e-12;             ///< Ipopt tol and constr_viol_tol (absolute, on c and the KKT error)
  int max_iterations = 200;             ///< Ipopt max_iter
  double feasible_violation = 1e-9;     ///< max |c_i| below which the result counts as a valid model
  bool print = false;                   ///< Ipopt's own output (print_level 5) on stdout
  /// Ipopt's "search direction too small" counts as solved only where p is stationary: the
  /// projected gradient residual ≤ stationarity × ‖w∘(p − p̃)‖∞ (or ≤ feasible_violation);
  /// otherwise the projection is solved again from p̃ (cold), and if that stops the same way it
  /// is not done.
  double stationarity = 1e-6;
  /// w_i of the distance ½ Σ w_i (p_i − p̃_i)² (empty: all 1). Small weights on entries that are
  /// not design variables let them follow the design (fillets following a moved plane).
  Eigen::VectorXd weights;
};

struct ProjectionResult {
  bool done = false;                     ///< a valid model: max |c_i| <= feasible_violation
  std::string status;                    ///< "solved", "infeasible" (nearest model returned), "failed"; "least_violation" (project_least_violation)
  std::string message;                   ///< Ipopt's status in words
  Eigen::VectorXd p;                     ///< p⊥ (or Ipopt's last iterate when not done)
  Eigen::VectorXd multipliers;           ///< λ of c (Ipopt sign: L = ½‖p − p̃‖² + λᵀc)
  double constraint_violation = 0;       ///< max |c_i(p)|
  double distance = 0;                   ///< ‖p − p̃‖
  int iterations = 0;
  int restarts = 0;                      ///< cold restarts after a stop away from the nearest point
  double seconds = 0;
};

/// Projects `target` (p̃) onto {c(p) = 0, lower <= p <= upper} starting from `start` (warm
/// start: the previous p⊥, and `start_multipliers` if non-empty). Entries with lower == upper
/// are fixed. Throws parafab::Error for mismatched sizes; non-convergence is a status.
ProjectionResult project(const ConstraintSystem& system, const Eigen::VectorXd& target,
                         const Eigen::VectorXd& start, const Eigen::VectorXd& lower,
                         const Eigen::VectorXd& upper, const Eigen::VectorXd& start_multipliers = {},
                         const ProjectionOptions& options = {});

/// When no p satisfies every constraint (project() ends "infeasible"): the nearest valid model.
/// Rows with soft[i] (user constraints: ties, symmetries, draft) give way; the others (unit axes,
/// tangencies, what makes the B-rep valid) and the bounds hold. Two Ipopt solves: the least
/// violation min ½Σ_soft c_i² + ε·½‖p − p̃‖²_W (ε = `regularization`, only to make the point
/// unique; it biases the violations by about ε times the distance moved), then the point nearest p̃ among those with that violation (the projection with the
/// soft rows held at their values). done: the hard rows hold to feasible_violation (status
/// "least_violation"; system.values(p) on the soft rows are what remains violated); else
/// "failed". Throws parafab::Error for mismatched sizes.
ProjectionResult project_least_violation(const ConstraintSystem& system, const std::vector<bool>& soft,
                                         const Eigen::VectorXd& target, const Eigen::VectorXd& start,
                                         const Eigen::VectorXd& lower, const Eigen::VectorXd& upper,
                                         const ProjectionOptions& options = {}, double regularization = 1e-12);

struct ProjectionDerivative {
  Eigen::MatrixXd jacobian;  ///< dp⊥/dp̃ (n × n; symmetric when W = I)
  int free = 0;              ///< entries not fixed or at a bound
  int rank = 0;              ///< rank of the constraint Jacobian on the free entries
};

/// dp⊥/dp̃ = Z (Zᵀ H Z)⁻¹ Zᵀ W with H = W + Σ λ_i ∇²c_i (W = diag(weights), empty: I) and Z a null-space basis of ∂c/∂p on the
/// entries that are free (strictly inside their bounds by `bound_gap`); rank-revealing, so
/// dependent constraints (redundant tangencies) are fine.
ProjectionDerivative projection_derivative(const ConstraintSystem& system, const ProjectionResult& projection,
                                           const Eigen::VectorXd& lower, const Eigen::VectorXd& upper,
                                           const Eigen::VectorXd& weights = {}, double bound_gap = 1e-9);

}  // namespace parafab::optimize
