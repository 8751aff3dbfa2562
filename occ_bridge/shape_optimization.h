// Shape optimization of a part on its own CAD parameters (thesis §6.2.3, §6.5): design
// variables are entries of p (face parameters), every evaluation projects them onto c_para = 0
// (Eq. 6.25-6.26, Ipopt), writes the valid model back into the B-rep (shape_modify.h), and
// evaluates a mass-property objective with exact Hadamard shape derivatives
// (shape_derivatives.h) chained through dp⊥/dp̃ (Eq. 6.29); L-BFGS with bounds drives it.
// Compliance (§6.5.3) runs the linear XFEM solve on a grid fixed for the whole run, with the
// exact rule-derivative gradient, semi-analytic where that does not apply (shape_compliance.h);
// "failure" (the stress metric of §6.2.3 Eq. 6.4) on the same solve with an adjoint gradient by
// the same two routes (shape_failure.h); "target" (a face's deformed shape matched to a target
// surface, §6.2.3 Eq. 6.6) with the same adjoint, its shape terms exact on a linear solve and
// differenced over the changed cells where that route does not apply or the solve is
// hyperelastic (shape_target.h).
#pragma once

#include <Eigen/Core>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "face_model.h"
#include "optimize/lbfgs.h"
#include "optimize/projection.h"
#include "shape_compliance.h"
#include "shape_derivatives.h"
#include "shape_failure.h"
#include "shape_parameters.h"
#include "shape_target.h"

namespace parafab::occ {

struct PartShape;

/// What to minimize, from the ten volume moments (density ρ, axis through `point` along `axis`):
///  "mass": ρV;  "volume": V;  "center_of_mass": |c⊥|², c⊥ the centre's offset from the axis;
///  "inertia_alignment": |I a − (aᵀ I a) a|² / (tr I)², I the inertia about the centre (the axis
///  a a principal axis); "balance": center_of_mass / L² + inertia_alignment (L: bbox diagonal).
///  "compliance": fᵀu of the linear XFEM solve (ShapeOptimizationOptions::compliance; not a
///  function of the moments: objective_from_moments gives 0 for it).
///  "failure": (1/V)∫ exp(α(σ_vm/σ_y − 1)) dV (or the bare integral when per_volume is false) of
///  the same solve (thesis §6.2.3 Eq. 6.4; fields yield_stress σ_y, exponent α, per_volume — JSON
///  "normalize"); objective_from_moments gives 0 for it; at most one failure term in a "sum".
///  "target": (1/A)∫_F d(X + u(X))² dA of the same solve, face F = `face` deformed, d its
///  distance from `target` (thesis §6.2.3 Eq. 6.6; shape_target.h); without a target, F's own
///  surface as read (plane, cylinder, sphere, torus); at most one target term in a "sum".
///  "sum": Σ weightᵢ · fᵢ / scaleᵢ over `terms` (each of another type than "sum"); with
///  `normalize` optimize_shape sets every scaleᵢ to |fᵢ| at the start (terms of different units
///  then weigh by their relative change; a term that is 0 at the start keeps scale 1).
struct ObjectiveSpec {
  std::string type = "mass";
  double density = 1;
  Vec3 point = Vec3::Zero();
  Vec3 axis = Vec3::UnitZ();
  double length_scale = 1;  ///< L of "balance" (set from the part when 0 or negative)
  double yield_stress = 0;  ///< σ_y of "failure" (required > 0)
  double exponent = 0;      ///< α of "failure" (required > 0)
  bool per_volume = true;   ///< "failure": divide the integral by the volume (JSON objective.normalize)
  int face = -1;            ///< "target": the matched face
  bool has_target = false;  ///< "target": `target` given (else the face's own surface as read)
  TargetSurface target;     ///< "target": the surface the deformed face should lie on
  double weight = 1;        ///< as a term of a "sum"
  double scale = 1;         ///< as a term of a "sum" (divides the term)
  std::vector<ObjectiveSpec> terms;  ///< of a "sum"
  bool normalize = false;            ///< of a "sum": scales from the start values
};

/// The factor of the objective `type` ("compliance", "failure", "target": the ones optimize_shape adds
/// beside the moments) in `spec`: 1 when spec is of that type, Σ weight/scale of such terms of a
/// "sum", 0 otherwise.
double term_weight(const ObjectiveSpec& spec, const std::string& type);
/// The spec that defines the failure metric: `spec` itself for "failure", the failure term of a
/// "sum" (one at most: a second is an input error naming it), null otherwise.
const ObjectiveSpec* failure_term(const ObjectiveSpec& spec);
/// As failure_term for "target".
const ObjectiveSpec* target_term(const ObjectiveSpec& spec);

/// The objective value and d value / d moments.
double objective_from_moments(const ObjectiveSpec& spec, const Moments& m, Eigen::Matrix<double, 10, 1>* gradient);

struct ShapeOptimizationOptions {
  ObjectiveSpec objective;
  /// Design variables (indices into p); empty: every entry of every face that is not fixed.
  std::vector<int> design;
  ShapeParameterOptions parameterization;
  /// Bounds on design entries: ± this times max(1, |initial|) around the start (0: none).
  double relative_bound = 0.5;
  /// Absolute bounds per design entry (same length as `design`, or empty: none), intersected
  /// with the relative ones; ±inf for no bound on that side (e.g. a wall thickness that must
  /// stay castable). A start outside them is clamped into them.
  std::vector<double> design_min, design_max;
  /// Volume bounds by an augmented Lagrangian (Powell–Hestenes–Rockafellar, see optimize_shape):
  double volume_max_ratio = 0;     ///< V ≤ ratio·V0 (0: no bound)
  double volume_min_ratio = 0;     ///< V ≥ ratio·V0 (0: no bound)
  /// Absolute volume bounds [model units³] (0: none), e.g. a mass bound divided by the density;
  /// with a ratio on the same side, the tighter of the two holds.
  double volume_max = 0, volume_min = 0;
  double penalty = 1e4;            ///< initial penalty weight ρ, relative to max(|f0|, tiny)
  int max_outer = 8;               ///< multiplier updates (outer iterations) at most
  /// Start the multiplier of a bound that holds with equality (or is violated) at the start at
  /// its least-squares estimate from ∇f and ∇V there, instead of 0 (no extra evaluation: the
  /// first inner run starts from the one that gave the estimate). The first steps then follow
  /// the bound; but where the optimum leaves it, the run stays near it and its line searches
  /// fight the penalty's kink. Measured (README): the bridge on 80 cells −27.5 % in 28
  /// evaluations against −23.6 % in 31 without; the L-bracket's 52 "auto" parameters 167
  /// evaluations and C 21.6 against 49 and 19.2 without. Hence off by default.
  bool estimate_multiplier = false;
  /// Polled before every evaluation and after every accepted iterate (a signal handler's flag,
  /// FreeCAD's Cancel): true ends the run at once with status "interrupted" and the best valid
  /// iterate so far as `part` (the part as read if none was accepted yet). Empty: never.
  std::function<bool()> interrupted;
  /// A run ends feasible when the relative violation (V/V0 − ratio) is at most this; if the
  /// outer iterations end above it, a volume-only Newton restoration moves onto the bound.
  double volume_tolerance = 1e-7;
  /// Start the design entries here instead of the part's own values (empty: the part's own;
  /// clamped into the bounds around the part's own values). With lbfgs.max_iterations = 0 this
  /// just applies the given parameters (projection + write-back).
  Eigen::VectorXd design_start;
  /// Projection weight of the entries that are not design variables (design entries: 1), so
  /// that tangent neighbours follow a design change instead of pulling it back.
  double follower_weight = 1e-4;
  /// The elasticity job of objective "compliance" (required for it, ignored otherwise). The grid
  /// is cut once from the first evaluated model and every later model is re-cut on it (fixed
  /// grid planes: the objective is continuous along line searches except where a cell changes
  /// its number of subvolumes; the small-cell aggregation and incompatible-mode thresholds are
  /// frozen at the current model in the gradient and, with freeze_switches, during line searches).
  std::shared_ptr<const ComplianceSetup> compliance;
  /// Discrete switches (small-cell aggregation and its hosts, incompatible modes) frozen during
  /// each line search: a trial model's cut cells switch as those of the search's start (the last
  /// accepted iterate), so the objective along the search is continuous except where a cell
  /// gains or loses a subvolume; an accepted point whose own switches differ is evaluated again
  /// with them (ShapeOptimizationResult::switch_refreshes) before the next search. Off: every
  /// model switches on its own volume fractions (the behaviour before 2026-11-29).
  bool freeze_switches = true;
  /// Route of the compliance, failure and target gradients. Exact (default): the rule
  /// derivatives of Eq. 6.30–6.31 (compliance_gradient, failure_gradient, target_gradient: one
  /// solve and adjoint, boundary integrals, every design entry at once), except for the design
  /// entries those flag `incomplete`, which take the semi-analytic route. SemiAnalytic: every
  /// design entry by two perturbed models (the route before 2026-11-27; for the failure metric,
  /// before 2026-12-02; for the target, until 2026-12-02). A hyperelastic target always takes
  /// the semi-analytic route.
  enum class ComplianceGradientRoute { Exact, SemiAnalytic };
  ComplianceGradientRoute compliance_gradient = ComplianceGradientRoute::Exact;
  /// Step of the semi-analytic compliance gradient: this × L (part diagonal) for lengths, this
  /// for directions (normal/axis components, half-angles); each side projected like an iterate.
  double compliance_step = 1e-4;
  optimize::LbfgsOptions lbfgs;
  optimize::ProjectionOptions projection;
  BoundaryQuadratureOptions quadrature;
  FaceModelOptions face_model;
};

struct ShapeIterate {
  int iteration = 0;
  double objective = 0;             ///< without the penalty
  double constraint_violation = 0;  ///< volume bound violation (relative), 0 if none
  int outer = 0;                    ///< augmented-Lagrangian outer iteration of this iterate
  int evaluations = 0;              ///< evaluations of the run so far
  double tangency_residual = 0;     ///< face model relations at p⊥
  Eigen::VectorXd design;           ///< design entries of p⊥
  double seconds = 0;
};

/// One augmented-Lagrangian outer iteration: the inner L-BFGS run with multiplier λ and
/// penalty ρ (both relative to max(|f0|, tiny), per unit relative violation), its end point.
struct AugmentedLagrangianStep {
  int outer = 0;
  double multiplier = 0, penalty = 0;  ///< used in this inner run
  double violation = 0;                ///< signed g = V/V0 − max_ratio (or min_ratio − V/V0) at its end
  double objective = 0;
  std::string inner_status;
  int inner_iterations = 0, evaluations = 0;
};

struct ShapeOptimizationResult {
  bool done = false;            ///< finished by a stopping rule (not cancelled, not failed)
  std::string status, message;
  double initial_objective = 0, final_objective = 0;
  double initial_volume = 0, final_volume = 0;
  std::vector<ShapeIterate> iterations;
  std::vector<std::string> design_names;
  Eigen::VectorXd design_initial, design_final;
  /// d objective / d design entry at the start (the sensitivities of the part as read; the
  /// volume bound's penalty not included), by the route `gradient` names.
  Eigen::VectorXd initial_gradient;
  Eigen::VectorXd p_initial, p_final;  ///< p⊥ at the start and at the end
  double tangency_residual_max = 0;    ///< face model relations on the final part
  std::shared_ptr<const PartShape> part;  ///< the final valid model
  int evaluations = 0, invalid_models = 0, failed_projections = 0;
  /// "exact" (Hadamard boundary integrals: mass-property objectives, and compliance and failure
  /// by the rule derivatives), "semi-analytic" (central differences of the changed cut cells'
  /// element matrices, contracted with u or the adjoint; exact volume-penalty part) or "exact + semi-analytic" (some
  /// design entries each way, see the counts below).
  std::string gradient = "exact";
  /// Compliance / failure design-entry derivatives computed by each route, summed over evaluations.
  int exact_derivatives = 0, semi_analytic_derivatives = 0;
  int topology_switches = 0;   ///< compliance: cells with another number of elements in a perturbed model
  /// Accepted iterates evaluated again with their own discrete switches (freeze_switches).
  int switch_refreshes = 0;
  /// Of those, the refreshes that only moved the failure metric's frames (switches already the
  /// model's own): no solve (compliance_own_frames).
  int frame_refreshes = 0;
  /// compliance with merge (Eq. 6.24): evaluations with at least one tie, the most ties in one,
  /// and the most of them whose pieces' incompatible modes were condensed jointly (xfem::mode_tied).
  int tied_evaluations = 0, max_ties = 0, max_mode_tied_pairs = 0;
  int gradient_cells = 0;      ///< compliance: cells differenced, summed over gradients
  /// "failure": max σ_vm over the material quadrature points at the start and at the end.
  double initial_max_von_mises = 0, final_max_von_mises = 0;
  /// "target": the matched face's RMS distance √J and max |d| at its rule points, start and end.
  double initial_target_rms = 0, final_target_rms = 0, initial_target_max = 0, final_target_max = 0;
  TargetSurface target;  ///< "target": the surface used (given, or the face's own as read)
  std::vector<AugmentedLagrangianStep> outer;  ///< empty without a volume bound
  bool volume_restored = false;        ///< the final volume-only restoration moved the design
  double final_violation = 0;          ///< relative, ≥ 0
  /// status "infeasible_constraints": no p satisfies every constraint, and `part` is the nearest
  /// valid model (tangencies and unit axes hold; the user constraints, least squares, violated
  /// by these values: name of the row, c_i). No iterations; design_final its design entries.
  struct Violation {
    std::string name;
    double value = 0;
  };
  std::vector<Violation> violated_constraints;
  std::vector<std::string> notes;      ///< parameterization notes and first invalid-model message
  double seconds = 0;
};

/// Called after every accepted iterate; returning false interrupts the run (status
/// "interrupted", the last valid model is kept), as ShapeOptimizationOptions::interrupted does.
using ShapeProgress = std::function<bool(const ShapeIterate&)>;

/// Throws parafab::Error for invalid options (unknown objective, design index out of range);
/// a failing projection or B-rep update is a status, never an exception.
ShapeOptimizationResult optimize_shape(const PartShape& part, const ShapeOptimizationOptions& options,
                                       const ShapeProgress& progress = {});

}  // namespace parafab::occ
