// Fabricability optimization of a strip curve (thesis §4.6.2): lower the optimal stiffness
// ratio R = sup K / inf K of LP Eq. 4.4 to a target by moving the B-spline control points
// (degree ≥ 4), a local/global scheme: the local step is gradient descent with line search on
// the p-norm ratio R_p (§4.5.4 "Remarks") in the tangent space of the equilibrium-curve
// manifold, followed by EnforceConstraints (App. A.4); the global step re-solves LP Eq. 4.4
// for the line (a, b) when the curve has fewer than two inflections. Gravity is accounted for
// afterwards by the design with LP Eq. 4.6. dR/dP is the LP's envelope derivative from the
// Clp multipliers (lp_ratio_gradient).
//
// The descent loop (descend_poles) takes any objective over the poles: Algorithm 4.2
// (stability recovery) plugs its F = −σ (or a barrier on the conjugate point) and δF/δK·dK/dq
// in as a PoleObjective, with R ≤ R_max enforced by ProjectStep.
#pragma once

#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "strips/strip_constraints.h"
#include "strips/strip_design.h"

namespace parafab {

/// dR*/dP of the optimal ratio of LP Eq. 4.4 on samples at fixed parameters (plus the
/// inflections, which move with the poles), from the LP multipliers (envelope theorem).
struct LpRatioGradient {
  bool ok = false;
  double R = NAN;         ///< max K / min K of the LP's line over the samples and zeros
  double objective = NAN; ///< the LP variable R* (the value that is differentiated)
  double a = 0;
  Vec2 b{0, 0};
  Eigen::VectorXd gradient;  ///< dR*/dq (2m)
  std::string message;
};
LpRatioGradient lp_ratio_gradient(const BSplineCurve2& curve, const std::vector<double>& sample_u,
                                  const std::vector<double>& inflection_u);

/// An objective over the poles: returns F and, if `gradient` is non-null, ∂F/∂q (2m). The
/// constraints give the current line (a, b) and the tracked inflections.
using PoleObjective =
    std::function<double(const BSplineCurve2& curve, const StripConstraints& constraints, Eigen::VectorXd* gradient)>;

struct PoleDescentIteration {
  int iteration = 0;
  double F = NAN;            ///< objective
  double R = NAN;            ///< max K / min K of the current line on the samples
  double R_p = NAN;          ///< p-norm ratio
  double step = 0;           ///< accepted |Δq|, after EnforceConstraints and returns onto R_max [length units]
  double max_pole_move = 0;  ///< max over poles of |P − P_original| [length units]
  double min_inflection_dkappa = NAN;  ///< min |κ'(s₀)|·l² over inflections (NaN: none)
  double seconds = 0;        ///< since the start
};

struct PoleDescentOptions {
  int max_iterations = 400;
  double initial_step = 0.01;   ///< steepest-descent trial |Δq| as a fraction of the length
  double max_step = 0.05;       ///< cap on |Δq| (fraction of the length)
  int memory = 8;               ///< L-BFGS pairs in the tangent space (0: steepest descent)
  /// Halvings of an L-BFGS direction before it is dropped for steepest descent
  int quasi_halvings = 5;
  double min_step = 1e-9;       ///< stop when the trial step falls below this · l
  double R_max = INFINITY;      ///< R_p ≤ R_max by ProjectStep; infinite: no bound
  /// A step is rejected if R_p > max(R_max·(1 + this), R_p before·(1 + 10⁻³)) afterwards
  /// (the linearized projection overshoots on the curved bound; §4.5.4: small, temporary).
  double bound_tolerance = 1e-3;
  /// Newton steps back onto R_p = R_max when a trial step overshoots the bound (0: halve the
  /// step instead, as before)
  int bound_returns = 2;
  double p = 32;                ///< exponent of R_p (thesis: p > 20)
  int samples = 200;            ///< fixed-parameter samples (equally spaced in arc length at start)
  double max_seconds = 0;       ///< > 0: stop after this wall time
  /// Called after every accepted step; may change the line (global step) and returns true to
  /// stop (target reached).
  std::function<bool(BSplineCurve2&, StripConstraints&, PoleDescentIteration&)> on_accept;
  StripConstraintOptions constraints;
};

struct PoleDescentResult {
  explicit PoleDescentResult(BSplineCurve2 c) : curve(std::move(c)) {}
  bool converged = false;    ///< stationary (step collapsed) or stopped by on_accept
  /// "target" (on_accept stopped) | "stationary" (no decrease possible; with R_max: a KKT
  /// point on the bound) | "stalled" (every step leaves the manifold: constraints fail or the
  /// inflection count changes; converged = false) | "max_iterations" | "time" | "constraints_failed"
  std::string status;
  std::string message;
  BSplineCurve2 curve;
  double a = 0;
  Vec2 b{0, 0};
  std::vector<double> inflections;  ///< parameters
  std::vector<PoleDescentIteration> history;
  int rejected_steps = 0;
  /// Newton steps taken to return overshooting trials onto the R_max bound (bound_returns),
  /// including those of trials rejected afterwards
  int bound_returns = 0;
  std::string last_rejection;  ///< why the last rejected trial step was rejected
  double seconds = 0;
};

/// Descent of F over the poles on the equilibrium manifold: Δq along the L-BFGS direction of
/// the projected gradient P∇F (P the projection onto T_qM; steepest descent of length
/// initial_step·l without memory), ProjectStep for R_p ≤ R_max, EnforceConstraints, and
/// backtracking (the step halves) unless F decreases (Armijo), the inflection count stays and,
/// with a bound, K > 0 on every sample.
/// (a, b): the line through the curve's inflections (≥ 2) or LP Eq. 4.4's optimum (< 2).
PoleDescentResult descend_poles(const BSplineCurve2& curve, const PoleObjective& F,
                                const PoleDescentOptions& options = {});

struct StripImproveOptions {
  double target_R = 3.5;        ///< stop when the LP ratio on the samples is ≤ this
  int max_iterations = 400;
  double p = 32;
  int samples = 200;
  int global_every = 3;         ///< the LP global step every this many accepted steps (< 2 inflections)
  double initial_step = 0.01;
  double max_seconds = 0;       ///< > 0: wall-time limit
  int min_degree = 4;           ///< lower degrees are fitted by a quartic first (fit_poles poles)
  int fit_poles = 0;            ///< 0: the curve's pole count + 2
  int deviation_samples = 400;  ///< for the curve deviation
  StripConstraintOptions constraints;
  /// The designs of the input and the result (gravity here: Eq. 4.6 afterwards). Default:
  /// tolerance 1e-3 on the estimated gap of R with at most 4097 samples (the solver's 1e-6 can
  /// take seconds on curves whose K peaks sharply); the target test uses the continuous-curve
  /// estimate R_continuous (sampled extrema of K refined: an estimate, not a certified bound;
  /// StripDesignOptions::tolerance).
  StripDesignOptions design = [] {
    StripDesignOptions d;
    d.tolerance = 1e-3;
    d.max_samples = 4097;
    return d;
  }();
};

struct StripImproveResult {
  explicit StripImproveResult(BSplineCurve2 c) : curve(std::move(c)) {}
  bool done = false;            ///< target reached
  std::string status;           ///< as PoleDescentResult::status, or "already" (R ≤ target at start)
  std::string message;
  BSplineCurve2 curve;          ///< the improved curve
  double R_initial = NAN;       ///< design_strip's R of the input
  double R = NAN;               ///< design_strip's R of the result (no gravity)
  /// its continuous-curve estimate R_continuous (the LP line's ratio with the 16 largest and
  /// smallest sampled extrema of K refined; NOT a certified upper bound: a peak of K between
  /// samples that is no sampled extremum is missed); done ⇔ R_estimate ≤ target (and, under
  /// gravity, R_gravity ≤ target). JSON: `R_estimate`, and `R_upper` as a deprecated alias.
  double R_estimate = NAN;
  double R_gravity = NAN;       ///< with the requested gravity (LP Eq. 4.6), if any
  double max_pole_move = 0;     ///< max |P − P₀| [length units]
  double deviation = 0;         ///< max over samples of the distance to the input curve (sampled Hausdorff)
  double deviation_relative = 0;  ///< deviation / length
  int inflections = 0;
  bool refit = false;           ///< the input's degree was below min_degree
  double refit_deviation = 0;
  std::vector<PoleDescentIteration> history;
  StripDesign design;           ///< final design (with the options' gravity etc.)
  double seconds = 0;
};

/// The target under gravity (§4.6.2: gravity is designed afterwards with LP Eq. 4.6): empty
/// when the requested design (feasible, with R_gravity) meets target_R, else the message that
/// says why not (status "target_without_gravity"). One rule for the C++ and the JSON results.
std::string gravity_target_shortfall(double R_estimate, double target_R, bool gravity_feasible, double R_gravity,
                                     const std::string& infeasible_reason);

/// Throws parafab::Error for a rational or infeasible input curve (naming the reason).
StripImproveResult improve_strip_fabricability(const BSplineCurve2& curve,
                                               const StripImproveOptions& options = {});

/// Sampled two-sided distance between curves (max of the nearest-point distances of
/// `samples` points of each, refined by local Newton projection).
double curve_deviation(const BSplineCurve2& a, const BSplineCurve2& b, int samples = 400);
/// Largest distance from the points to the curve (nearest of `samples` curve points, refined
/// by Newton projection): how far a curve fitted to or moved from sampled points lies from them.
double points_deviation(const std::vector<Vec2>& points, const BSplineCurve2& curve, int samples = 400);

}  // namespace parafab
