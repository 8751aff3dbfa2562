// Bending-active strip design (thesis §4.3): a plane curve in; the feasibility diagnosis of
// Theorem 1, the optimal stiffness profile of LP Eq. 4.4 with the sample count chosen from a
// tolerance on R, the width profile of a sheet (K = E·w·h³/12) and the flat outline out.
// With gravity (§4.4), free end directions or angles (§4.3.3), a natural curvature or a
// nonlinear moment law (Appendix A.5) the profile comes from the gravity LP (gravity_lp.h,
// Eq. 4.6 with the smoothing phase of §4.4.3) on nested grids instead.
#pragma once

#include <map>
#include <string>
#include <vector>

#include "common/few_variable_lp.h"
#include "strips/equilibrium_check.h"
#include "strips/gravity_lp.h"
#include "strips/strip_model.h"

namespace parafab {

struct StripDesignOptions {
  double youngs_modulus = 3e9;  ///< E of the sheet [Pa]
  double thickness = 0.5e-3;    ///< h of the sheet [m]
  /// Yield strain ε_y of the material (σ_y / E); +∞: unknown. The bending strain h·|κ − κ₀|/2
  /// is reported for every design; a design whose strain exceeds ε_y is refused (parafab::Error
  /// naming `material_name`, the strain and s) unless the moment law models plasticity (a
  /// finite law.curvature_limit). `strain_thickness` > 0 replaces h (e.g. h₁ + h₂ of a
  /// composite strip's glued laminate, §4.7.1).
  double yield_strain = INFINITY;
  std::string material_name;
  double strain_thickness = 0;
  /// §4.7.1 composite strip (a broad layer of thickness h₁ and constant width w₁, a narrow
  /// one of thickness h₂ and width w₂(s), cK = h₁³w₁ + ((h₁+h₂)³ − h₁³)w₂, see
  /// composite_strip.h). Under gravity its weight per length is ρg(h₁w₁ + (ρ₂/ρ)h₂w₂), not
  /// ∝ K: the design iterates the weight of both layers to a fixed point (ρg from βl³, E and
  /// `thickness`: ρg = E h²/(12 βl³)).
  struct Composite {
    bool enabled = false;
    double outer_thickness = 0, inner_thickness = 0;  ///< h₁, h₂ [m]
    double outer_width = 0;                           ///< w₁ [m]
    double inner_density_ratio = 1;                   ///< ρ₂/ρ
  } composite;
  double min_width = 0.01;      ///< width where K is smallest [m]
  /// Sampling: start with `initial_samples` samples equally spaced in arc length and double
  /// until the estimated relative gap between the sampled optimum R (a lower bound of the
  /// continuous optimum) and the continuous ratio of its line is at most `tolerance`. The
  /// continuous ratio is an ESTIMATE, not a certified bound: only the 16 largest sampled
  /// maxima and 16 smallest minima of K are refined on the continuous curve, and an extremum
  /// between two samples that does not show up as a sampled extremum is missed.
  double tolerance = 1e-6;
  int initial_samples = 64;
  int max_samples = (1 << 18) + 1;
  LpForm lp_form = LpForm::Dense;
  ZeroCurvatureOptions zeros;
  EquilibriumCheckOptions check;

  // ---- Extensions; the defaults keep the plain Eq. 4.4 design above. Any non-default value
  // routes the design through the gravity LP (Eq. 4.6, which is Eq. 4.4 without gravity).
  StripGravity gravity;            ///< §4.4: weight K/βl³ per length
  StripBoundary boundary;          ///< §4.3.3: free x / y / angle at an end
  MomentLaw law;                   ///< Appendix A.5: nonlinear moment law, plasticity
  double natural_curvature = 0.0;  ///< §4.3.3: κ₀ [1/m]; zeros are those of κ − κ₀
  bool smooth = true;              ///< §4.4.3 phase two (only when gravity is on)
  double smoothing_margin = 0.01;  ///< ε of phase two
  bool inflection_rows = true;     ///< see GravityLpOptions::inflection_rows
  /// Sampling of the gravity LP: from initial_samples + 1, the count doubles (nested grids)
  /// until R changes by at most this (relative) between grids, or max_samples. The
  /// trapezoidal integrals make R converge as O(n⁻²).
  double load_tolerance = 1e-4;
  int fixed_samples = 0;           ///< > 0: exactly this many samples, no refinement
  /// Gravity LP refinement: start each grid's phase-one LP from the rows active on the
  /// coarser grid (Clp warm start; nested grids keep those samples). Clp then needs 0–2
  /// iterations instead of 10–15. It ends in the same optimal basis on every curve tested
  /// (all samples, the 31-strip scene, the test curves: R and K bit-identical to the cold
  /// start), but a degenerate LP could end at another optimal vertex; false: cold starts.
  bool warm_start = true;
  /// The same for the Eq. 4.4 refinement (no gravity), on by default since it halves the LP
  /// phase of a 400-point curve: bit-identical on the samples and test curves
  /// (StripScene.WarmStartedLpsEqualColdStarts), 3e-16 apart in R on the strip-improve test curve.
  bool warm_start_eq44 = true;
  /// A free end angle needs κ = κ₀ at that end: |κ − κ₀|·length up to this counts as zero.
  double free_angle_tolerance = 1e-6;
};

struct StripSample {
  double s = 0;
  Vec2 point{0, 0};
  double kappa = 0;
  double K = 1;  ///< normalized stiffness, min over the strip = 1
};

struct StripDesign {
  // What was computed.
  bool feasible = false;
  std::string reason_code;  ///< "" or a stable code, see to_code(Infeasibility)
  std::string reason;       ///< human-readable, names where
  double reason_s = -1;     ///< arc length of the offending point, −1 if none
  double length = 0;
  std::vector<ZeroCurvaturePoint> zeros;  ///< inflections (and zeros at the ends)
  double a = 0;             ///< the line a + ⟨b, x⟩ = 0 through the inflections
  Vec2 b{0, 0};
  double collinearity_error = 0;  ///< max distance of an inflection from the line [m]
  double R = 1;             ///< max K / min K
  std::vector<StripSample> samples;  ///< sorted by s; zeros included (K by its limit)
  std::vector<double> width;         ///< [m], min = min_width
  std::vector<double> bending_stiffness;  ///< E·w·h³/12 [N·m²]
  std::vector<Vec2> outline;  ///< flat strip: centreline on +x from 0 to length, CCW polygon
  // Diagnostics.
  bool converged = false;   ///< the estimated gap met the tolerance before max_samples
  /// Estimate of max K / min K of the line on the continuous curve (≥ R; an estimate, see
  /// StripDesignOptions::tolerance). JSON: diagnostics.R_continuous.
  double R_continuous = NAN;
  int lp_samples = 0;       ///< samples in the final LP
  struct Refinement {
    int samples;
    double R;             ///< LP optimum on the samples (lower bound)
    double R_continuous;  ///< the same line on the continuous curve (estimate)
  };
  std::vector<Refinement> refinement;  ///< one entry per LP solved
  int lp_iterations = 0;    ///< of the final LP
  double lp_seconds = 0;    ///< of the final LP
  double total_seconds = 0;
  /// Where total_seconds went (wall time per phase, summed over the refinement): the
  /// arc-length table, zero finding with the strain check, the equilibrium check, sampling
  /// (arc-length inversion and curve evaluation), every LP solved (both phases), the
  /// continuous-ratio estimate (Eq. 4.4 only) and the widths/outline. For benchmarks only.
  struct Phases {
    double curve = 0, zeros = 0, check = 0, sampling = 0, lp = 0, ratio = 0, outputs = 0;
  } phases;
  std::string lp_message;
  // Gravity / general LP diagnostics (defaults for the plain Eq. 4.4 design).
  bool general_lp = false;   ///< designed with the gravity LP (Eq. 4.6)
  double R_first = NAN;      ///< phase-one optimum (before smoothing)
  bool smoothed = false;     ///< phase two returned the profile
  double tv_first = NAN, tv = NAN;  ///< Σ|ΔK′| before / after smoothing [1/m]
  Vec2 start_force{0, 0}, end_force{0, 0};  ///< internal force at the ends for min K = 1
  double zero_consistency = 0;  ///< σ₃/σ₁ of the equality rows
  double max_plastic_curvature = 0;  ///< max |κ − κ₀| beyond law.curvature_limit (0: elastic)
  double lp_seconds_second = 0;      ///< phase two of the final LP
  // Bending strain (App. A.5): max over the curve of h·|κ − κ₀|/2, where, and its ratio to
  // the yield strain (NaN when the yield strain is unknown).
  double max_strain = 0;
  double max_strain_s = 0;
  double yield_ratio = NAN;
  /// Under gravity: weight per length at every sample [N/m] (ρ g h w for a sheet; both
  /// layers for a composite strip), and the fixed-point iterations of the composite weight.
  std::vector<double> weight_per_length;
  int weight_iterations = 0;
  double weight_change = 0;  ///< last relative change of the composite weight (fixed point)
  /// Composite strips under gravity: per sample the ratio λ = (weight per length)/(K e) the
  /// LP used (not 1: the broad layer's weight does not follow K); empty otherwise (λ = 1).
  std::vector<double> weight_ratio;
};

/// Widths of the two layers of a composite strip for the normalized profile K (min 1):
/// c = ((h₁+h₂)³)·w₁ / max K, w₂ = clamp((cK − h₁³w₁)/((h₁+h₂)³ − h₁³), 0, w₁) (the narrow
/// strip as wide as the broad one where K is largest).
std::vector<double> composite_inner_width(const std::vector<double>& K,
                                          const StripDesignOptions::Composite& c);

/// Throws parafab::Error for invalid options (non-positive E, thickness, width, tolerance) or
/// a singular curve; an infeasible curve is a result with feasible = false and a reason.
StripDesign design_strip(const BSplineCurve2& curve, const StripDesignOptions& options = {});

/// A scene of independent strips (e.g. a pavilion, §4.8.1): design_strip for every curve,
/// distributed over `threads` TBB workers (0: TBB's default, 1: this thread only, in order).
/// Each result equals design_strip(curves[i], options) exactly; the first error thrown by
/// any strip is rethrown (naming the strip's index).
std::vector<StripDesign> design_strips(const std::vector<BSplineCurve2>& curves,
                                       const StripDesignOptions& options = {}, int threads = 0);

/// Curve evaluations kept between the nested grids of one design: the interior knots
/// (evaluated once, at their exact parameters) and the last grid's equally spaced points
/// (l·k/(n−1) is bit-identical to l·2k/(2n−2), so a refined grid evaluates only its new
/// points). Belongs to one curve.
struct ArcLengthSampleCache {
  const PlaneCurve* curve = nullptr;
  std::vector<CurvePoint> knots;   ///< interior breakpoints, in order
  std::vector<CurvePoint> spaced;  ///< the last grid's equally spaced points
};

/// Samples equally spaced in arc length plus the interior knots, leaving out points within
/// 1e-6·length of a zero. `cache` (optional) keeps the curve evaluations between calls on
/// nested grids of the same curve.
std::vector<CurvePoint> sample_by_arc_length(const PlaneCurve& curve, int count,
                                             const std::vector<ZeroCurvaturePoint>& zeros,
                                             ArcLengthSampleCache* cache = nullptr);

}  // namespace parafab
