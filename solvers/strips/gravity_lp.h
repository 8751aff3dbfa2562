// Stiffness profile of a strip under gravity: the linear program of thesis Eq. 4.6 (§4.4.2)
// with the two-phase smoothing of §4.4.3 (minimize the total variation of K′ subject to
// R ≤ R₁(1+ε)). Also carries the boundary variants of §4.3.3 and, through the effective
// curvature of each sample, nonlinear moment laws and natural curvature (Appendix A.5).
//
// Moment equilibrium (Eq. 4.5, derived here with the weight K·e per length, e = ĝ/βl³):
//   K(s) μ(s) = a + ⟨b, γ(s)⟩ + ⟨Re, γ(s)⟩ F(s) − G(s),  F = ∫ₛˡ K,  G = ∫ₛˡ ⟨Re, γ⟩ K,
// with R the rotation by +90° and μ the effective curvature (κ for the linear law). F and G
// are discretized by the trapezoidal rule (second order; the thesis' Voronoi sums are first
// order). K at every sample is then an affine function of (a, b), found by one backward
// sweep from s = l, so Eq. 4.6 (3n + 4 variables) reduces exactly to a 4-variable LP solved
// with solve_few_variable_lp. At a zero of μ the equation becomes the equality
// rhs(s₀) = 0 and K(s₀) its l'Hôpital limit (⟨b, γ′⟩ + ⟨Re, γ′⟩F)/μ′, as in Eq. 4.4.
// Phase two, min Σ|ΔK′| over the same 3 unknowns, is a few-variable program with n − 2
// absolute-value rows (FewVariableLp::D), solved by the dense solver's primal simplex with
// long steps from phase one's optimum (its dual simplex, then Clp's dual form as fallbacks;
// Clp with `form`); both phases stay linear in the number of samples.
#pragma once

#include <string>
#include <vector>

#include "common/few_variable_lp.h"
#include "strips/strip_model.h"

namespace parafab {

/// One sample of the curve as the LP sees it.
struct StripLpSample {
  double s = 0;           ///< arc length [m]
  Vec2 point{0, 0};       ///< γ(s)
  Vec2 tangent{1, 0};     ///< γ′(s)
  double mu = 0;          ///< effective curvature μ = m(κ − κ₀) [1/m]; 0 at a zero
  double dmu_ds = 0;      ///< μ′(s) [1/m²]; used at zeros only
  bool zero = false;      ///< a zero of μ (inflection or end): equality + l'Hôpital row
  double kappa = 0;       ///< κ itself (carried along for the caller; unused by the LP)
  /// Weight per length here relative to K·e (1: a plain sheet, weight ∝ K; a composite
  /// strip's layers give other ratios, §4.7.1).
  double weight = 1.0;
};

struct GravityLpOptions {
  /// Weight per length divided by K, e = ĝ/βl³ [1/m³] (StripGravity::load()); zero vector:
  /// no gravity, and the program is exactly Eq. 4.4.
  Vec2 load{0, 0};
  StripBoundary boundary;  ///< free_x / free_y add equality rows on the end forces
  /// Phase two of §4.4.3: minimize Σ|ΔK′| (total variation of K′) subject to the rows of
  /// phase one and R ≤ R₁(1 + smoothing_margin).
  bool smooth = true;
  double smoothing_margin = 0.01;  ///< ε
  /// Zero samples carry the equality and l'Hôpital rows (default). false drops them and the
  /// zero samples: the literal Eq. 4.6, whose optimum may spike near inflections.
  bool inflection_rows = true;
  /// With three or more equality rows (zeros, boundary rows) they must have rank ≤ 2:
  /// σ₃/σ₁ of the normalized rows above this is reported as infeasible.
  double zero_consistency_tolerance = 1e-4;
  LpForm form = LpForm::Dense;
  /// Warm start of phase one (opt-in, see StripDesignOptions::warm_start): rows active at the
  /// optimum of a similar LP, as (s, 0 for K ≥ 1 / 1 for K ≤ R) of their samples.
  std::vector<std::pair<double, int>> warm_rows;
  /// Phase one already solved on exactly these samples and options (GravityLpResult::
  /// phase_one_lp of an earlier call): reused instead of solved again, e.g. when phase two
  /// follows the refinement on the final grid. Same result as solving it again.
  const FewVariableLpResult* phase_one = nullptr;
};

struct GravityLpResult {
  LpStatus status = LpStatus::Failed;
  double a = 0;              ///< final line (input units), K normalized to min 1
  Vec2 b{0, 0};
  std::vector<double> K;     ///< at every sample (min = 1)
  double R = 0;              ///< max K / min K of the returned profile
  // Phase one (Eq. 4.6 proper).
  double a_first = 0;
  Vec2 b_first{0, 0};
  double R_first = 0;
  std::vector<double> K_first;
  // Phase two.
  bool smoothed = false;      ///< phase two ran and its solution is returned
  double tv_first = 0;        ///< Σ|ΔK′| of phase one [1/m]
  double tv = 0;              ///< Σ|ΔK′| of the returned profile [1/m]
  /// Internal force n(s) (force of the part beyond s on the part before it) at the ends,
  /// for K normalized to min 1 [1/m²]: reactions are n(l) at the end, −n(0) at the start.
  Vec2 start_force{0, 0}, end_force{0, 0};
  double zero_consistency = 0;  ///< σ₃/σ₁ of the equality rows (0 with fewer than 3)
  int equality_rows = 0;
  int iterations_first = 0, iterations_second = 0;
  std::vector<std::pair<double, int>> active_rows;  ///< basic rows of phase one, as warm_rows
  FewVariableLpResult phase_one_lp;                 ///< phase one's LP result (for phase_one)
  FewVariableLpResult phase_two_lp;                 ///< phase two's (in x / max|x₁|; empty without it)
  double seconds_first = 0, seconds_second = 0, seconds = 0;
  double max_violation = 0;   ///< of phase one's normalized program
  std::string message;
  bool ok() const { return status == LpStatus::Optimal; }
};

/// `samples` sorted by s from 0 to `length` (the ends included). Throws parafab::Error for
/// fewer than 3 samples, unsorted samples or a non-positive length.
GravityLpResult solve_gravity_lp(const std::vector<StripLpSample>& samples, double length,
                                 const GravityLpOptions& options = {});

/// Σ|(K_{i+1} − K_i)/h_i − (K_i − K_{i−1})/h_{i−1}|, the discrete total variation of K′.
double total_variation_of_derivative(const std::vector<double>& s, const std::vector<double>& K);

}  // namespace parafab
