// Static equilibrium of hyperelastic parts on the cut grid (thesis §6.4.1, Eq. 6.17–6.18):
// minimize Σ_e ∫ Ψ(F) dV + boundary terms − external work by Newton's method with a
// backtracking line search on the energy, load stepping, and CHOLMOD for the Newton systems.
#pragma once

#include <string>
#include <vector>

#include "xfem/linear_xfem.h"
#include "xfem/materials.h"

namespace parafab::xfem {

struct NonlinearXfemOptions {
  /// Nitsche β, gravity, surface degree, the element type (hex8 or hex27; rules must match, see
  /// occ::rules_for_element); incompatible modes unused.
  LinearXfemOptions boundary;
  int load_steps = 1;          ///< loads and prescribed displacements ramped in equal steps
  int max_iterations = 50;     ///< Newton iterations per load step
  double tolerance = 1e-9;     ///< ‖gradient‖ ≤ tolerance · max(‖external load‖, ‖initial gradient‖)
  /// Factorize the Hessian at the converged u once more and keep it (NonlinearXfemResult::
  /// factorization): adjoint solves of shape derivatives (occ::target_adjoint).
  bool keep_factorization = false;
};

struct NonlinearXfemResult {
  bool converged = false;
  std::string message;
  int dofs = 0, iterations = 0;
  int aggregated_nodes = 0;  ///< DOF nodes tied to neighbours by cell aggregation (as LinearXfemResult)
  std::vector<double> residuals;         ///< ‖gradient‖ after every Newton step (all load steps)
  Eigen::VectorXd u;
  std::vector<std::vector<int>> node;  ///< as LinearXfemResult::node
  double energy = 0;
  double seconds = 0;
  /// With options.keep_factorization: the reduced Hessian TᵀH(u)T at the solution, factorized,
  /// and T (empty when nothing is aggregated), so that as_linear().solve_again(b) solves
  /// H(u) x = b (the tangent problem of an adjoint).
  std::shared_ptr<const SparseCholesky> factorization;
  Eigen::SparseMatrix<double> aggregation;
  /// The same interpolation as the linear result (and the kept factorization, if any).
  LinearXfemResult as_linear() const;
};

/// Boundary terms use linearized Nitsche (the consistency term with the small-strain stress
/// of E, ν from `small_strain`): exact for linear problems, an O(strain²) inconsistency at
/// Dirichlet faces under large strain, while the penalty keeps the condition enforced.
NonlinearXfemResult solve_nonlinear(const std::vector<GridElement>& elements,
                                    const std::vector<std::array<int, 2>>& adjacent,
                                    const Material& material, const ElasticMaterial& small_strain,
                                    const std::vector<DirichletCondition>& dirichlet,
                                    const std::vector<TractionCondition>& tractions,
                                    const NonlinearXfemOptions& options = {});

/// The bulk internal force of one element, ∂/∂uₑ Σ_q w_q Ψ(F(X_q)) (uₑ: 3 per node, 8 or 27
/// nodes in the order of node_offset): the element's share of the gradient solve_nonlinear
/// drives to zero, without boundary terms. Throws parafab::Error where Ψ is not finite (J ≤ 0).
Eigen::VectorXd element_internal_force(const GridElement& element, const Material& material, const Eigen::VectorXd& ue);

}  // namespace parafab::xfem
