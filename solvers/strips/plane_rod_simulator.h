// Forward simulation of a plane inextensible rod (thesis §4.6.1): a polygon of N equal
// edges with edge angles α_j as unknowns, nodal stiffnesses K_k with Voronoi weights w_k,
// bending energy Σ_k w_k K_k ψ((α_k − α_{k−1})/w_k − κ₀) with the boundary angles as
// α_{−1}, α_N, gravity potential −Σ_k K_k w_k ⟨x_k, e⟩, and the end-point constraint
// Σ_j l_j (cos α_j, sin α_j) = γ(l) − γ(0) through Lagrange multipliers. Equilibria are found
// by Newton's method on the KKT system (Eigen SparseLU) with a backtracking line search on
// the residual norm, and continuation in the weight and the curvature limit (plasticity)
// if the full problem fails from the initial guess.
#pragma once

#include <Eigen/SparseCore>
#include <string>
#include <vector>

#include "strips/strip_model.h"

namespace parafab {

struct PlaneRodProblem {
  double length = 1;                  ///< [m]
  /// K(s) as a piecewise linear function through (stiffness_s[i], stiffness[i]); stiffness
  /// per unit of the moment law (M = K m(κ)), > 0; any common scale.
  std::vector<double> stiffness_s, stiffness;
  Vec2 start_point{0, 0}, end_point{1, 0};
  double start_angle = 0, end_angle = 0;  ///< tangent angles at the clamps [rad]
  StripBoundary boundary;                 ///< free_x/free_y/free_angle per end
  Vec2 load{0, 0};                        ///< e [1/m³]: weight per length = K e
  /// Optional, one per stiffness sample: weight per length = weight_ratio·K·e there (e.g.
  /// the two layers of a composite strip); empty: 1.
  std::vector<double> weight_ratio;
  MomentLaw law;
  double natural_curvature = 0;           ///< κ₀ [1/m]
  /// Optional κ₀ field added to natural_curvature, piecewise linear through
  /// (natural_curvature_s[i], natural_curvature_field[i]): e.g. the permanent set of an
  /// ideally plastic strip (App. A.5), re-loaded elastically.
  std::vector<double> natural_curvature_s, natural_curvature_field;
  /// Initial edge angles (size = edges), e.g. the target's; empty: linear between the end
  /// angles.
  std::vector<double> initial_angles;
};

struct PlaneRodOptions {
  int edges = 400;
  int max_iterations = 100;      ///< Newton iterations per load step
  double tolerance = 1e-10;      ///< relative on moments (K_max/l) and positions (l)
  int max_load_steps = 256;      ///< continuation: halve the step down to 1/this
  /// Keep the KKT matrix [H Cᵀ; C 0] at the returned state (H: energy Hessian in the edge
  /// angles, C: constraint Jacobian) in PlaneRodResult::kkt, for stability tests
  /// (constrained_inertia in jacobi_stability.h).
  bool hessian = false;
};

struct PlaneRodResult {
  bool converged = false;
  std::vector<double> node_s;        ///< arc length of the nodes (N + 1)
  std::vector<Vec2> nodes;           ///< equilibrium positions
  std::vector<double> edge_angles;   ///< α_j (N)
  std::vector<double> curvature;     ///< κ_k at the nodes
  Vec2 multiplier{0, 0};             ///< λ (end-point constraint; zero for removed rows)
  /// Force of the end support on the rod, −λ [units of K / m²]: with K normalized as in the
  /// design it equals StripDesign::end_force (the internal force n(l)).
  Vec2 end_force{0, 0};
  double energy = 0;                 ///< bending + gravity at the equilibrium
  double residual = 0;               ///< max |KKT residual| (scaled)
  int iterations = 0;                ///< Newton iterations, all load steps
  int load_steps = 0;                ///< continuation steps tried (1 without continuation)
  double seconds = 0;
  std::string message;
  /// With PlaneRodOptions::hessian: the KKT matrix at the returned state, N + constraints
  /// square, the N edge angles first; `constraints` rows of C (end coordinates held).
  Eigen::SparseMatrix<double> kkt;
  int constraints = 0;
};

/// Throws parafab::Error for invalid input (non-positive stiffness or length, mismatched
/// sizes, fewer than 4 edges).
PlaneRodResult simulate_plane_rod(const PlaneRodProblem& problem,
                                  const PlaneRodOptions& options = {});

}  // namespace parafab
