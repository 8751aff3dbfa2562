// Stability of plane elastic curves (thesis §4.5.2, Eq. 4.7, the isoperimetric stability
// matrix Z; §3.3.3 Legendre/Jacobi conditions; discretized as in §4.6.1; the adjoint of
// Appendix A.3 for δσ/δK). Two tests on the same discrete rod (N equal edges, edge angles α_j,
// nodal stiffnesses K_k with Voronoi weights w_k, Lagrange multiplier λ of the end-point
// constraint Σ h (cos α_j, sin α_j) = γ(l) − γ(0)):
//  - the Jacobi test: ζ, η_i of −(Pζ′)′ + Qζ = 0 / T_i (P = K m′(κ), Q = −⟨μ, γ′⟩ with μ = λ
//    minus the weight carried beyond s; T = (−sin α, cos α) for each constrained end
//    coordinate) integrated as the three-term recurrence of the discrete second variation,
//    M_i = Σ h T_i ζ, N_ij = Σ h T_i η_j, Z(s) = det Z(s); the first sign change of Z on
//    (0, l] is the conjugate point σ. O(N).
//  - the eigenvalue test: inertia of the energy Hessian on the tangent space of the end-point
//    constraints (null-space projection; dense, O(N³)), from the simulator's KKT matrix.
// With a free end angle the last determinant is that of the natural end condition (Kζ′ = 0),
// with a free start angle ζ starts as ζ(0) = 1, ζ′(0) = 0; free x / y ends drop a constraint.
#pragma once

#include <Eigen/SparseCore>
#include <string>
#include <vector>

#include "strips/plane_rod_simulator.h"
#include "strips/strip_design.h"

namespace parafab {

/// A discrete plane rod state (thesis §4.6.1): what both stability tests read.
struct DiscreteRodState {
  double length = 1;                ///< [m]; edges of length h = length / N
  std::vector<double> stiffness;    ///< K_k at the nodes k = 0..N (N + 1 values, > 0)
  std::vector<double> angles;       ///< α_j of the edges j = 0..N−1 [rad]
  double start_angle = 0, end_angle = 0;  ///< clamp angles α_{−1}, α_N
  /// λ of L = W + ⟨λ, Σ h t_j − Δ⟩ (the simulator's PlaneRodResult::multiplier); a component
  /// whose end coordinate is free is ignored.
  Vec2 multiplier{0, 0};
  StripBoundary boundary;
  Vec2 load{0, 0};                  ///< e [1/m³]: weight per length K e (times weight_ratio)
  /// Optional, N + 1 values: weight per length = weight_ratio_k K_k e at the nodes (composite
  /// strips, whose broad layer's weight does not follow K, §4.7.1); empty: 1.
  std::vector<double> weight_ratio;
  MomentLaw law;
  double natural_curvature = 0;
  int edges() const { return static_cast<int>(angles.size()); }
};

struct JacobiOptions {
  /// |Z| / (product of the column norms of Z) below this counts as zero (degenerate, e.g. a
  /// straight start where the two constraint tangents are parallel): no sign there.
  double degenerate_tolerance = 1e-9;
  int max_samples = 200;  ///< Z(s) samples kept in the result (every k-th node), 0: none
};

struct JacobiResult {
  bool stable = false;
  bool legendre = true;       ///< P = K m′(κ) > 0 at every node
  double sigma = NAN;         ///< first conjugate point in (0, l] [m]; NaN when stable
  /// m with s_{m−1} < σ ≤ s_m, where s_m = (m + ½) h (m < N) and s_N = l (Z_m clamps the
  /// angle of edge m, centred at (m + ½) h); −1 when stable
  int conjugate_index = -1;
  int constraints = 2;        ///< p: constrained end coordinates
  double Z_end = NAN;         ///< normalized Z at l (sign: > 0 stable side)
  double min_Z = NAN;         ///< min of the normalized Z over (0, l]
  std::vector<double> s, Z;   ///< normalized Z(s) = det Z / Π‖columns‖ ∈ [−1, 1], at s_m
  std::vector<double> Z_raw;  ///< det Z for m = 0..N (for σ and its derivative)
  double seconds = 0;
  std::string method = "jacobi";
  std::string message;
};

/// Jacobi test of Eq. 4.7 on a discrete rod. Throws parafab::Error for invalid states
/// (sizes, non-positive stiffness or length).
JacobiResult jacobi_stability(const DiscreteRodState& state, const JacobiOptions& options = {});

/// Derivatives of σ (Appendix A.3, discrete adjoint of the recurrence above), for the
/// stability recovery (Algorithm 4.2).
struct ConjugatePointSensitivity {
  bool defined = false;                 ///< a conjugate point exists (unstable state)
  double sigma = NAN;
  /// Partial derivatives at fixed everything else (for an optimizer over the curve: chain
  /// them with dK/dq, dα/dq, dλ/dq of a curve parametrization).
  std::vector<double> dsigma_dK_partial;  ///< ∂σ/∂K_k, N + 1
  std::vector<double> dsigma_dangles;     ///< ∂σ/∂α_j, N
  Vec2 dsigma_dmultiplier{0, 0};          ///< ∂σ/∂λ
  /// Total derivative through the discrete equilibrium (α, λ follow K with the ends held):
  /// δσ/δK of A.3; only when `equilibrium` was requested (the state must be one).
  std::vector<double> dsigma_dK;
  double equilibrium_residual = NAN;  ///< max |KKT residual| of the state (scaled like the simulator)
  double seconds = 0;
  std::string message;
};

/// Throws parafab::Error for a nonlinear moment law (m″ is not modelled). With
/// `equilibrium` the state is taken as a discrete equilibrium and δσ/δK is the total
/// derivative (one sparse KKT solve: the ᾱ, λ̄ problem of A.3).
ConjugatePointSensitivity conjugate_point_sensitivity(const DiscreteRodState& state,
                                                      bool equilibrium = true,
                                                      const JacobiOptions& options = {});

/// Constrained eigenvalue test: inertia of H on {C δα = 0} for the KKT matrix [H Cᵀ; C 0]
/// (n angle unknowns first) by a null-space projection (Householder QR of Cᵀ) and a dense
/// symmetric eigensolver.
struct ConstrainedInertia {
  int negative = 0, zero = 0, positive = 0;
  double min_eigenvalue = NAN;   ///< of the projected Hessian
  double max_eigenvalue = NAN;
  int constraint_rank = 0;
  bool stable = false;           ///< negative == 0 && zero == 0
  double seconds = 0;
  std::string method = "hessian";
};
/// `zero_tolerance`: |μ| ≤ tol · max|μ| counts as zero.
ConstrainedInertia constrained_inertia(const Eigen::SparseMatrix<double>& kkt, int unknowns,
                                       double zero_tolerance = 1e-10);

/// The discrete state of a simulated equilibrium (for the Jacobi test and δσ/δK on exactly
/// the simulator's equilibrium).
DiscreteRodState rod_state(const PlaneRodProblem& problem, const PlaneRodResult& result);

/// The discrete state of a designed strip: its curve sampled at `edges` equal edges, K of the
/// design interpolated at the nodes, λ from the design's line (Eq. 4.4: λ = R b, R the
/// rotation by +90°) or its end force (gravity LP: λ = −n(l)), the load, law and ends of the
/// design options. Throws parafab::Error for an infeasible design.
DiscreteRodState rod_state(const BSplineCurve2& curve, const StripDesign& design,
                           const StripDesignOptions& options, int edges);

/// The stability of a designed strip: the Jacobi test on the design, and (optionally) the
/// constrained eigenvalue test on the simulated equilibrium of the designed K.
struct StripStabilityOptions {
  int edges = 800;               ///< of the Jacobi discretization
  bool eigenvalue_check = false; ///< also simulate and run the Hessian inertia test
  PlaneRodOptions simulation{400};
  JacobiOptions jacobi;
};

struct StripStability {
  bool stable = false;           ///< the Jacobi verdict
  double sigma = NAN;            ///< NaN when stable
  std::string method = "jacobi";
  JacobiResult jacobi;
  // Eigenvalue cross-check (eigenvalue_check):
  bool checked = false;
  bool simulation_converged = false;
  ConstrainedInertia inertia;
  JacobiResult jacobi_on_simulation;  ///< the Jacobi test on the simulated equilibrium
  bool agree = false;            ///< Jacobi verdict == eigenvalue verdict
  double simulation_seconds = 0;
  double jacobi_seconds = 0;     ///< including the state construction
  double eigen_seconds = 0;      ///< inertia only (the simulation is separate)
  std::string message;
};

/// Throws parafab::Error if the design is not feasible.
StripStability strip_stability(const BSplineCurve2& curve, const StripDesign& design,
                               const StripDesignOptions& design_options,
                               const StripStabilityOptions& options = {});

}  // namespace parafab
