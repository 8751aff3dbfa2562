// Stability of designed Kirchhoff rods (thesis §4.5.1 eigenvalue condition applied to the
// discrete elastic rod of §5.7.4 / Bergou et al. 2008): the inertia of the exact energy
// Hessian on the free degrees of freedom (the clamps fix nodes 0, 1, N−1, N and the first and
// last material angle, so the constraint tangent space is the coordinate subspace of the
// free DOFs) at the designed state. A negative eigenvalue means a perturbation that lowers
// the energy: the design is an unstable equilibrium.
#pragma once

#include <string>

#include "rods/discrete_elastic_rod.h"

namespace parafab {

struct RodStabilityOptions {
  /// |μ| ≤ zero_tolerance · max|μ| counts as zero (no verdict from second order).
  double zero_tolerance = 1e-12;
};

struct RodEquilibriumStabilityOptions {
  RodStabilityOptions hessian;
  DiscreteRodOptions simulation;
  /// The discrete equilibrium counts as the design's when no node is farther than this ·
  /// length from the target; otherwise the rod moved away from the target (`moved_away`), and
  /// the design is not `stable` whatever the inertia at the reached equilibrium says.
  double max_distance = 1e-3;
};

struct RodStability {
  /// no negative and no zero eigenvalue (hessian_at_equilibrium: at the reached equilibrium,
  /// and that equilibrium is the design's: not moved_away)
  bool stable = false;
  int negative = 0, zero = 0, positive = 0;
  int free_dofs = 0;
  double min_eigenvalue = NAN;  ///< smallest eigenvalue of the free Hessian [J per DOF unit²]
  /// min eigenvalue / max diagonal entry of the free Hessian (dimensionless indicator)
  double min_relative = NAN;
  double seconds = 0;
  std::string method = "hessian";  ///< "hessian" (at the target) or "hessian_at_equilibrium"
  /// hessian_at_equilibrium: max node distance of the discrete equilibrium from the target / length
  double equilibrium_distance = NAN;
  bool equilibrium_converged = false;
  /// hessian_at_equilibrium: the equilibrium lies more than max_distance · length from the
  /// target. The inertia above is still that of the reached equilibrium (computed whenever the
  /// simulation converged): positive definite there means the rod settles stably somewhere
  /// else — a coarse discretization (its equilibrium is O(h²) off the target) or another
  /// state (a buckled helix) —, `equilibrium_stable` says which.
  bool moved_away = false;
  /// hessian_at_equilibrium: the reached equilibrium's Hessian has no negative or zero
  /// eigenvalue (false when the simulation did not converge)
  bool equilibrium_stable = false;
  /// "stable", "unstable" (a negative or zero eigenvalue where the rod settles, or no
  /// converged equilibrium) or "moved_away" (settles stably, but away from the target)
  std::string verdict;
  std::string message;
};

/// The Hessian at the model's state (its `nodes` and `material_normal`, e.g. the design's
/// target). Throws parafab::Error for an invalid model.
RodStability rod_stability(const DiscreteRodModel& model, const RodStabilityOptions& options = {});

/// The verdict at the discrete equilibrium rather than at the target: Newton's method of
/// simulate_discrete_rod (energy-decreasing, with Hessian shifts) started at the target finds
/// the discrete rod's equilibrium; stable when it converges within `max_distance` · length of
/// the target and the Hessian there has no negative or zero eigenvalue. Near a bifurcation the
/// target's own Hessian can be barely positive while the rod leaves (helix at t = 1.5 t*), which
/// this catches. Costs one forward simulation.
RodStability rod_stability_at_equilibrium(const DiscreteRodModel& model,
                                          const RodEquilibriumStabilityOptions& options = {});

/// The same with the forward simulation of `model` already done (e.g. by a validation run on
/// the same discretization): `equilibrium` = simulate_discrete_rod(model, options.simulation).
RodStability rod_stability_at_equilibrium(const DiscreteRodModel& model, const DiscreteRodResult& equilibrium,
                                          const RodEquilibriumStabilityOptions& options = {});

}  // namespace parafab
