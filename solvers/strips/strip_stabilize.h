// Stability recovery of a strip curve (thesis §4.5.4, Algorithm 4.2): the B-spline control
// points (degree ≥ 4) move in the tangent space of the equilibrium-curve manifold (App. A.4:
// inflections on the fixed line, end points / tangents and arc length fixed) to push the first
// isoperimetric conjugate point σ (Eq. 4.7) beyond the strip's end, with R ≤ R_max by the
// p-norm bound and ProjectStep. K = (a + ⟨b, γ⟩)/κ is a function of the curve, so σ(q) is
// differentiated by chaining the partials ∂σ/∂K, ∂σ/∂α of the adjoint (App. A.3,
// conjugate_point_sensitivity) with dK/dq and dα/dq. For comparison, Algorithm 4.1 (§4.5.3):
// K itself as the variable with the simulator in the loop, which stalls at the bifurcation.
#pragma once

#include <string>
#include <vector>

#include "strips/jacobi_stability.h"
#include "strips/strip_constraints.h"
#include "strips/strip_design.h"

namespace parafab {

struct StripStabilizeOptions {
  /// Bound on R = sup K / inf K (its p-norm estimate R_p on the samples, §4.5.4 "Remarks");
  /// +∞: no bound (the failure mode of §4.5.4: κ′ → 0 at an inflection). The thesis example
  /// used 3; the unstable sine wave of the tests (R 2.6) needs more (6 is not enough with the
  /// margin).
  double R_max = 10.0;
  /// Stable with a margin: the curve is also stable under the force λ scaled by 1 + margin (the
  /// second variation ∫K h′² + (1 + margin) Q h² stays positive on the constraint tangents;
  /// it is linear in the factor, so this implies stability at factor 1). σ of the scaled state
  /// is the objective.
  double margin = 0.05;
  int edges = 200;              ///< Jacobi discretization inside the loop
  int verify_edges = 800;       ///< independent final test (strip_stability on the design)
  int max_iterations = 300;     ///< accepted steps over all rounds
  int rounds = 3;               ///< restarts with fresh nodes if the final test disagrees
  double p = 32;                ///< exponent of R_p
  int samples = 200;            ///< R_p samples
  double initial_step = 0.002;  ///< trial |Δq| as a fraction of the length
  double max_step = 0.01;       ///< cap on |Δq| (fraction of the length)
  int memory = 6;               ///< L-BFGS pairs (0: steepest ascent of σ)
  int quasi_halvings = 5;       ///< PoleDescentOptions::quasi_halvings
  double bound_tolerance = 1e-2;  ///< PoleDescentOptions::bound_tolerance
  int bound_returns = 2;          ///< PoleDescentOptions::bound_returns
  double max_seconds = 0;       ///< > 0: wall-time limit
  int min_degree = 4;           ///< lower degrees (or more than max_poles poles) are refitted
  int max_poles = 40;
  int fit_poles = 0;            ///< refit pole count; 0: min(pole count + 2, 20)
  int deviation_samples = 400;
  StripConstraintOptions constraints;
};

struct StripStabilizeIteration {
  int iteration = 0;
  double sigma = NAN;         ///< conjugate point of the curve [m]; NaN: stable
  double sigma_margin = NAN;  ///< with the force scaled by 1 + margin (the objective); NaN: stable
  double R = NAN;             ///< max K / min K of the line on the samples
  double R_p = NAN;
  double step = 0;            ///< |Δq| [length units]
  double max_pole_move = 0;   ///< [length units]
  double min_inflection_dkappa = NAN;  ///< min |κ′(s₀)|·l² over the inflections
  double seconds = 0;
};

struct StripStabilizeResult {
  explicit StripStabilizeResult(BSplineCurve2 c) : curve(c), original(std::move(c)) {}
  /// stable_after with the margin (Jacobi on the design with the force scaled by 1 + margin).
  bool done = false;
  /// "already" (stable with the margin at start) | "stable" | "stalled" | "stationary" |
  /// "max_iterations" | "time" | "constraints_failed"
  std::string status;
  std::string message;
  BSplineCurve2 curve;        ///< the stabilized curve
  BSplineCurve2 original;     ///< the input (after a refit, the refitted curve)
  bool stable_before = false, stable_after = false;  ///< Jacobi verdict on the design
  bool stable_margin_after = false;
  double sigma_before = NAN, sigma_after = NAN;       ///< [m]; NaN: stable
  double sigma_margin_before = NAN, sigma_margin_after = NAN;
  double length = 0;
  double R_before = NAN, R_after = NAN;  ///< design_strip's R (LP Eq. 4.4)
  double max_pole_move = 0;              ///< max |P − P₀| [length units]
  double deviation = 0;                  ///< sampled Hausdorff distance to the input [m]
  double deviation_relative = 0;         ///< / length
  double min_inflection_dkappa = NAN;    ///< of the result, min |κ′(s₀)|·l²
  int inflections = 0;
  bool refit = false;
  double refit_deviation = 0;
  std::vector<StripStabilizeIteration> history;
  StripDesign design;                    ///< the design of the result
  int rejected_steps = 0;
  int bound_returns = 0;  ///< Newton steps back onto the R_max bound (PoleDescentResult::bound_returns)
  double seconds = 0;
};

/// Algorithm 4.2. Throws parafab::Error for a rational or infeasible curve, or invalid options.
StripStabilizeResult stabilize_strip(const BSplineCurve2& curve, const StripStabilizeOptions& options = {});

/// The stability objective of Algorithm 4.2 on a fixed discretization: nodes at fixed
/// parameters u_k, K_k = (a + ⟨b, γ(u_k)⟩)/κ(u_k), α_j the chord angles, λ = (1 + margin) R b.
/// Returns σ (NaN when stable) and dσ/dq (2m) when unstable.
struct CurveConjugatePoint {
  bool valid = false;   ///< K > 0 at every node
  bool stable = false;
  double sigma = NAN;
  Eigen::VectorXd gradient;  ///< dσ/dq
  DiscreteRodState state;
  std::string message;
};
CurveConjugatePoint curve_conjugate_point(const BSplineCurve2& curve, double a, const Vec2& b,
                                          const std::vector<double>& node_u, double length,
                                          double margin, bool gradient = true);

/// Algorithm 4.1 (the failed attempt): K as the variable, K ← K + h·∇σ (∇σ = δσ/δK of A.3
/// on the simulated equilibrium, the step scaled to h·mean K at the largest entry), the
/// equilibrium re-simulated from the previous one, until stable. The simulated equilibrium
/// is compared with the target curve (deviation) at every step.
struct StiffnessAscentOptions {
  int edges = 200;
  double step = 0.02;           ///< h: max relative change of K per iteration
  int max_iterations = 80;
  double lost_shape = 0.02;     ///< deviation / length above which the shape counts as lost
};
struct StiffnessAscentIteration {
  int iteration = 0;
  double sigma = NAN;           ///< [m]; NaN: stable
  double deviation = NAN;       ///< max |x_k − γ(s_k)| / length of the simulated equilibrium
  double gradient_norm = NAN;   ///< max |δσ/δK| (grows without bound towards the bifurcation)
  bool converged = true;        ///< the simulation
};
struct StiffnessAscentResult {
  /// "stable" (stable and the shape kept) | "lost_shape" (the equilibrium left the target) |
  /// "simulation_failed" | "max_iterations"
  std::string status;
  bool stable = false;
  double sigma_before = NAN, sigma = NAN;  ///< [m]
  double deviation = NAN;                  ///< of the last equilibrium (relative)
  std::vector<double> stiffness;           ///< last K at the nodes
  std::vector<Vec2> nodes;                 ///< last equilibrium
  std::vector<StiffnessAscentIteration> history;
  double seconds = 0;
  std::string message;
};
StiffnessAscentResult stabilize_by_stiffness(const BSplineCurve2& curve, const StiffnessAscentOptions& options = {});

/// EnforceConstraints (App. A.4) with the line through the first and last inflection: makes
/// the inflections of a fitted curve collinear (no-op with fewer than two). Throws
/// parafab::Error if the Newton iteration fails.
void project_to_equilibrium(BSplineCurve2& curve, const StripConstraintOptions& options = {});

/// The simulator problem of a design (the designed K, clamped ends of the curve, target chord
/// angles as the initial state) with `edges` edges; `target` receives the curve's nodes.
PlaneRodProblem strip_rod_problem(const BSplineCurve2& curve, const StripDesign& design,
                                  const StripDesignOptions& options, int edges, std::vector<Vec2>* target);

}  // namespace parafab
