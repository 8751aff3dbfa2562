// Release of a plane rod from a given (perturbed) state by an energy-decreasing solver
// (thesis §4.5: a stable equilibrium is a local minimum of the energy, an unstable one a
// saddle; §4.6.1 discretization, the same energy as plane_rod_simulator.h). The end-point
// constraint is a quadratic penalty, μ/2 |Σ h t_j − Δ|², so the total energy
// E(α) = bending + gravity + penalty is minimized without constraints by Newton's method with
// a Hessian modification (H + τI, τ raised until the Cholesky factorization succeeds) and an
// Armijo line search on E: every accepted step lowers E, so the solver cannot stay at a saddle
// it was pushed off, unlike the residual Newton of simulate_plane_rod.
#pragma once

#include <string>
#include <vector>

#include "strips/plane_rod_simulator.h"

namespace parafab {

struct PlaneRodReleaseOptions {
  int edges = 200;
  int max_iterations = 2000;
  /// μ = penalty · max K / length³: the end point is held to about |λ| / μ.
  double penalty = 1e6;
  /// Converged when max |∂E/∂α_j| ≤ tolerance · max K / length (the penalty's round-off
  /// floor is near μ h ε l ≈ 1e-10 of that scale).
  double tolerance = 1e-8;
};

struct PlaneRodReleaseResult {
  bool converged = false;
  std::vector<double> edge_angles;
  std::vector<Vec2> nodes;             ///< referenced to the start point
  double initial_energy = NAN, energy = NAN;  ///< including the penalty
  double end_point_error = NAN;        ///< |Σ h t_j − Δ| [m] of the held coordinates
  int iterations = 0;
  int hessian_shifts = 0;              ///< Newton steps with τ > 0 (indefinite Hessian met)
  bool monotone = true;                ///< every accepted step lowered E (checked)
  double seconds = 0;
  std::string message;
};

/// Starts from problem.initial_angles (required, size = edges). The linear moment law and
/// natural curvature as in simulate_plane_rod; free ends drop their penalty terms / clamp
/// terms. Throws parafab::Error for invalid input.
PlaneRodReleaseResult release_plane_rod(const PlaneRodProblem& problem,
                                        const PlaneRodReleaseOptions& options = {});

}  // namespace parafab
