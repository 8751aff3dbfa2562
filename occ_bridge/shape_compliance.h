// Compliance objective of shape optimization (thesis §6.5.3): C = fᵀu of the linear XFEM solve
// (§6.4) on a grid that stays fixed during the optimization, and its derivative with respect
// to a design direction. Compliance is self-adjoint (dC = 2uᵀdf − uᵀdK u, u from the solve).
// Two routes: the exact rule derivative of Eq. 6.30-6.31 (compliance_gradient: boundary
// integrals over the moving patches, all of p at once; the default), and the SEMI-ANALYTIC one
// (compliance_derivative: dK, df as central differences of the element matrices of only the
// cells the perturbed model's re-cut changes, contracted with u), for entries the exact route
// does not cover (a support's or load's own motion next to another condition, a cone or plane running tangent into a support or load).
// adjoint_shape_gradient is the exact route for any objective with an adjoint (the failure metric,
// the target objective with its own surface density).
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "grid_model.h"
#include "piece_gaps.h"
#include "shape_parameters.h"
#include "xfem/linear_xfem.h"
#include "xfem/materials.h"

namespace parafab::occ {

struct PartShape;

/// The elasticity job of the compliance objective: faces by index (the write-back keeps
/// topology and face order, so indices stay valid on every modified part).
struct ComplianceSetup {
  xfem::ElasticMaterial material;
  std::vector<xfem::DirichletCondition> dirichlet;   ///< supports
  std::vector<xfem::TractionCondition> tractions;    ///< loads (traction per area)
  /// Per load: a total force (then that load's traction is force / area of its face on every
  /// model, as `parafab simulate` spreads a force) or zero (the traction above, kept fixed). With
  /// a kept traction, a load face that shrinks lowers the total load and the compliance.
  std::vector<xfem::Vec3> forces;
  xfem::LinearXfemOptions solver;
  GridModelOptions grid;  ///< grid.block_cells > 0 (the re-cut works block by block)
  /// A hyperelastic law (null: linear elasticity). Then each state is solved by Newton
  /// (xfem::solve_nonlinear, `load_steps`, the Hessian at the solution kept for adjoints) and
  /// `compliance` is not computed (0): only objectives with an adjoint through the tangent (the
  /// target shape, shape_target.h) may use it.
  std::shared_ptr<const xfem::Material> hyperelastic;
  int load_steps = 1;
  /// Thesis §6.4.4 (Eq. 6.24): pieces about to join tied by a penalty (linear elasticity only).
  MergePenaltyOptions merge;
};

/// One evaluated model: the part, its grid model and the solution (with the kept factorization).
struct ComplianceState {
  bool done = false;
  std::string message;
  std::shared_ptr<const PartShape> part;
  std::shared_ptr<const GridModel> model;
  std::vector<xfem::TractionCondition> tractions;  ///< the loads on this part (forces spread over its faces)
  xfem::LinearXfemResult solution;
  double compliance = 0;
  bool recut_full = false;    ///< the re-cut fell back to a whole cut (same grid planes)
  double occt_volume = 0;     ///< OCCT's volume of `part`, against which the cut's rules were checked
  /// compliance_at with `switches_from`: elements whose discrete switches were frozen there, and
  /// whether the switches came out as the elements' own fractions would set them (false: this
  /// model's objective differs from its own-switch value; the optimizer then re-evaluates it).
  int frozen_elements = 0;
  bool switches_own = true;
  /// Whether every cut element integrates on its own fitting box (xfem::GridElement::frame:
  /// compliance_at with `switches_from` freezes the frames too; false when one differs from its
  /// own by more than 1e-9 of its cell). Only the failure metric integrates there.
  bool frames_own = true;
  /// setup.merge: the pairs of pieces closer than d_crit and their ties (same order).
  std::vector<PieceGap> gaps;
  std::vector<xfem::PieceTie> ties;
  double gap_seconds = 0;
};

/// The start: cuts `part` on a new grid (the grid of the whole optimization) and solves.
ComplianceState compliance_start(std::shared_ptr<const PartShape> part, const ComplianceSetup& setup);

/// A modified part on the grid of `base` (re-cut from the base part: the objective depends on
/// the part only, whatever the previous iterate was). With `switches_from` (another model on
/// the same grid, e.g. a line search's start), the discrete switches (small-cell aggregation
/// and its hosts, incompatible modes) of every cut element in a cell that has as many elements
/// in both are decided on that model's fractions (xfem::GridElement::switch_fraction): along a
/// line search the objective then only jumps where a cell gains or loses a subvolume. Not frozen
/// (big trial steps): an element whose own fraction is below the incompatible-mode floor or
/// differs from its match's by more than half the aggregation threshold.
ComplianceState compliance_at(std::shared_ptr<const PartShape> part, const ComplianceState& base,
                              const ComplianceSetup& setup, const GridModel* switches_from = nullptr);

/// `model` (of a compliance_at with `switches_from`: the state's part, model and OCCT volume)
/// solved again with every element on its own switches. The re-cut does not depend on the
/// switches, so this is compliance_at of the same part from the same base without
/// `switches_from`, less the re-cut and OCCT's volume: the optimizer's switch refresh of an
/// accepted point. The copy shares the model's cut.
ComplianceState compliance_own_switches(std::shared_ptr<const PartShape> part, const GridModel& model,
                                        double occt_volume, const ComplianceSetup& setup);
inline ComplianceState compliance_own_switches(const ComplianceState& state, const ComplianceSetup& setup) {
  return compliance_own_switches(state.part, *state.model, state.occt_volume, setup);
}

/// A solved state whose switches are its own but whose failure frames were frozen
/// (switches_own && !frames_own): the same state on its own frames, with no solve. The frames
/// enter only the failure metric's integral, not K or f, so the solution (and its kept
/// factorization) is the one a re-solve would give. The copy shares the cut.
ComplianceState compliance_own_frames(const ComplianceState& state);

struct ComplianceDerivative {
  bool done = false;
  std::string message;
  double derivative = 0;   ///< dC/ds along the perturbation (s: the step parameter)
  int cells_changed = 0;   ///< cells whose elements were differenced
  /// Cells where the perturbed models have another number of elements than `at` (a subvolume
  /// appears, vanishes or a cell switches between cut and uncut): a discrete change of the
  /// model. One-sided difference where one side matches; skipped where neither does.
  int topology_switches = 0;
  /// One perturbed model could not be used (projection, write-back or a cut whose rules miss
  /// OCCT's volume): a one-sided difference (message says which side).
  bool one_sided = false;
};

/// dC/ds at `at` from the models `plus` (s = +h) and `minus` (s = −h) of a perturbation:
/// Σ_changed elements [2 uₑ·(fₑ⁺ − fₑ⁻) − uₑᵀ(Kₑ⁺ − Kₑ⁻)uₑ] / 2h, with aggregation and DOF
/// numbering frozen at `at`. Each perturbed model is re-cut from `at` so that only the cells
/// the perturbation touches are new. Either part may be null (then one-sided).
ComplianceDerivative compliance_derivative(const ComplianceState& at, std::shared_ptr<const PartShape> plus,
                                           std::shared_ptr<const PartShape> minus, double h,
                                           const ComplianceSetup& setup);

/// dC/dp for every entry of p by the rule derivatives of Eq. 6.30–6.31 (quadrature points frozen,
/// weights moving with the domain; see xfem::bulk_shape_density): the state's one solve and no
/// perturbed model. Self-adjoint, so dC = 2uᵀdf − uᵀdK u, and per cut element
///   dC/dp_i = ∫_{patches of moving faces} (2ρ g·u_h − ψ(u, u)) Vₙ,i dA,
/// Vₙ,i = ∂X/∂p_i·n from the face's implicit function (as moment_derivatives), plus, where a
/// moving face F shares an edge with a support or load Γ, the strip that Γ's patch gains along
/// that edge: ∮ (2 f_Γ − k_Γ)(uₑ) a ds with the edge's conormal speed a = Vₙ,F / (n_F·ν)
/// (xfem::boundary_term_density; ν the outward conormal in Γ), and for a total force F_i its
/// traction's change −2 W_i dA_i / A_i (W_i = ∫ u_h·t dA). Exact for the discrete compliance with
/// its topology (cut cells, subvolumes, aggregation, incompatible-mode switches) frozen at `at`,
/// as in the semi-analytic route. Where F is tangent to Γ (|n_F·ν| < 0.2) and F is a cylinder,
/// torus or sphere (a fillet running into a support, a ball end), the edge moves with F's spine
/// (optimize::spine_point; the null-space completion of Fig. 6.12, case 2). A load face's own
/// motion (a bolt hole's radius under its bolt load): with uₕ frozen, 2 d/ds ∫_Γ uₕ·t dA =
/// 2∫_Γ (∂ₙ(uₕ·t) + κ uₕ·t) Vₙ dA + 2∮ uₕ·t α ds, κ the mean curvature (sum) and α =
/// −Vₙ (n_Γ·n_F)/(ν·n_F) where Γ's edge slides along its neighbour F, plus its bulk term and, for
/// a total force, the traction's change through dA. A support's own motion (its Nitsche terms
/// F(X, n) with n turning by n' = −∇_Γ Vₙ): ∫_Γ [(∂ₙF + κF) Vₙ − ∂F/∂n·∇_Γ Vₙ] dA + ∮ F α ds,
/// the edges both Γ's edges on its neighbours and its pieces' edges on the cell walls (σ(u) jumps
/// there, so the two cells' strips do not cancel); exact for the Nitsche integrals themselves,
/// which the solver's patch rules carry with an error whose change on a curved support is up to
/// 1.5e-5 of dC at their default there (degree 8; 1e-4 … 1e-3 at 5:
/// ShapeCompliance.ASupportsOwnMotionHasAnExactGradient). Not included,
/// flagged `incomplete`: a support's or load's own motion where its face is free-form, is both
/// a support and a load, is a support with a prescribed `field`, shares an edge with another
/// support or load or a face without a parameter block, or runs tangent (|n_F·ν| < 0.2) into a
/// neighbour (a support also (|n_W·ν| < 0.05) along a cell wall), except a plane support or load
/// into which a cylinder, torus or sphere runs tangent (the edge is the foot of its spine S: a
/// slide of −φ(S) ν·∂n); a cone or plane tangent to a support or load; and the
/// poles of a B-spline face whose basis functions reach an edge it shares with a support or load
/// (on other poles Vₙ = R_ij(u, v) n_c at the rule's own (u, v)). With the local Nitsche penalty a
/// clamped cut cell's penalty κΛ changes with every face that cuts it: C changes by
/// κ dΛ (2uᵀg − uᵀPu), dΛ = vᵀdBv − Λ vᵀdÂv (xfem::LocalPenaltyParts; vᵀdÂv by the bulk density
/// of (v, v) on the moving patches, vᵀdBv by the flux density of v on the clamped patch's moving
/// edges); where Λ is not a simple eigenvalue (gap ≤ 1e-6) the cell's moving faces are flagged
/// (of a B-spline face, the poles whose basis functions reach its patches).
struct ComplianceGradient {
  bool done = false;
  std::string message;
  Eigen::VectorXd gradient;      ///< dC/dp_i, one per entry of p (0 for faces without a cut patch)
  std::vector<char> incomplete;  ///< per entry of p: see above (use the semi-analytic route there)
  int elements = 0;              ///< cut elements with a patch on a moving face, a support or a load
  int points = 0;                ///< boundary quadrature points (patches and edges)
  int edge_points = 0;           ///< of which on edges of supports and loads
  /// Eq. 6.24's ties whose weight's change is not differentiated: the gap has no derivative (an
  /// end on an edge of the part, a B-spline face) or the tie blends a floating node (the
  /// aggregation map then changes with d). The entries of their faces are flagged incomplete (the
  /// semi-analytic route has no tie term either: there those entries miss the tie's change).
  int ties_without_derivative = 0;
  double seconds = 0;
};
/// `moving` (optional, one flag per entry of p): the entries whose derivative is wanted, e.g. the
/// non-zero rows of dp⊥/dp̃ over the design. The boundary integrals over the patches of faces
/// with no such entry are skipped (the bridge's deck and floor, cut by every cell): the wanted
/// entries are the same to the last bit, the others lack those integrals (use the gradient only
/// along directions that move wanted entries).
ComplianceGradient compliance_gradient(const ComplianceState& at, const ComplianceSetup& setup,
                                       const ShapeParameters& parameters, const Eigen::VectorXd& p,
                                       const std::vector<char>* moving = nullptr);

/// What the exact route needs of an objective J(u, Ω) other than the compliance: its adjoint
/// λ (K λ = −∂J/∂u, e.g. failure_adjoint) and, when J has a domain integral ∫_Ω j(u) dV of its
/// own, that integrand: `density(e, points)` = j at the points of element e (J/V-like scalings
/// folded in; null: none).
struct ShapeAdjoint {
  Eigen::VectorXd lambda;
  std::function<std::vector<double>(int element, const std::vector<xfem::Vec3>& points)> density;
  /// When J has a surface integral ∫_F g(X) dA of its own over one face F = `surface_face` (the
  /// target objective: g = (d² − J)/A), `surface_density(e, points, g, ∇g)` fills g and its
  /// spatial gradient at points of element e on F's patches (u frozen). Null: none.
  int surface_face = -1;
  std::function<void(int element, const std::vector<xfem::Vec3>& points, std::vector<double>& value,
                     std::vector<xfem::Vec3>& gradient)>
      surface_density;
};
/// compliance_gradient's route for J (linear elasticity only): with u frozen,
///   dJ/dp_i = ∫_{moving patches} (j + ψ(λ, u) − ρg·λ) Vₙ,i dA + λᵀ(dK u − df)|_{conditions} + ties
///             [+ ∫_F (∂ₙg + κg) Vₙ,i dA + ∮_∂F g a_i ds for a surface density on F],
/// every term of compliance_gradient with (u, u) → (λ, u) in dK and 2u → −λ in df (its strips,
/// the load's own motion, a total force's area term, the local penalty's dΛ, Eq. 6.24's ties;
/// the bilinear Nitsche and mode-tied forms by polarization of their quadratic ones). The same
/// coverage and the same `incomplete` flags. Exact for J's discrete value where j is in the span
/// the rules integrate exactly (Eq. 6.31, "exact if g is in the function space"); an objective
/// whose integrand is not (the failure metric's exponential) passes its projection on that span
/// (failure_gradient), over frames held fixed. A surface density's edge term a_i is the edge's
/// speed across itself inside F: a neighbour's slide as for a support's strips (a tangent
/// cylinder, torus or sphere by its spine), F's own slide as for a load's own motion; where F
/// is a plane and the neighbour a swept face running tangent into it, the edge is the foot of
/// the spine S on F, a_i = −φ_F(S) ν·∂n_F/∂p_i. Flagged `incomplete`: F's own entries where F is
/// a B-spline, a neighbour across its edges has no parameter block, or F runs tangent into a
/// neighbour otherwise; no wall terms (g is continuous across cell walls: u_h is nodal).
ComplianceGradient adjoint_shape_gradient(const ComplianceState& at, const ComplianceSetup& setup,
                                          const ShapeParameters& parameters, const Eigen::VectorXd& p,
                                          const ShapeAdjoint& adjoint, const std::vector<char>* moving = nullptr);

/// Whether a design direction dp (e.g. a column of dp⊥/dp̃) moves no entry flagged incomplete:
/// |dp_i| ≤ 1e-6 ‖dp‖∞ there (the projection derivative's round-off is ~1e-10). Then
/// gradient·dp is its exact derivative.
bool exact_along(const ComplianceGradient& gradient, const Eigen::VectorXd& dp);

/// The term of one element in a derivative by changed cells: evaluated on an element of a
/// perturbed model (or of `at` for a one-sided difference) with the DOF nodes of `at`'s
/// element `base` (at.solution.node[base]); called from several threads at once.
using ElementTerm = std::function<double(const xfem::GridElement& element,
                                         const std::vector<xfem::TractionCondition>& tractions, int base)>;

/// The term of a pair of pieces whose incompatible modes are condensed jointly
/// (xfem::mode_tied on at.ties): evaluated on the pair's elements of a perturbed model (or of
/// `at`), `tie` the state's (its weight and blend held, its elements `at`'s).
using PairTerm = std::function<double(const xfem::GridElement& a, const xfem::GridElement& b, const xfem::PieceTie& tie)>;

/// The machinery of compliance_derivative for any sum of element terms: both perturbed models
/// re-cut from `at`, their changed cells' elements matched to `at`'s, and
/// Σ weight·term(element) with weights ±1/2h (central) or ±1/h (one-sided); plus the same
/// difference of pair_term over the mode-tied pairs in changed cells.
ComplianceDerivative element_difference(const ComplianceState& at, std::shared_ptr<const PartShape> plus,
                                        std::shared_ptr<const PartShape> minus, double h, const ComplianceSetup& setup,
                                        const ElementTerm& term, const PairTerm& pair_term = {});

/// The residual R = ∂(energy)/∂uₑ of one element at its nodal values uₑ, the term an adjoint
/// contracts with λ in a shape derivative (λᵀ dR/ds): Kₑuₑ − fₑ (linear), or the hyperelastic
/// internal force plus the boundary terms minus the loads (setup.hyperelastic, as
/// xfem::solve_nonlinear assembles them).
Eigen::VectorXd element_residual(const xfem::GridElement& element, const std::vector<xfem::TractionCondition>& tractions,
                                 const Eigen::VectorXd& ue, const ComplianceSetup& setup);

/// λ = −H⁻¹ ∂J/∂u with the state's kept factorization (K, or the tangent H(u) of a hyperelastic
/// state); `who` names the caller in the error when ∂J/∂u does not belong to the state.
Eigen::VectorXd adjoint_of(const ComplianceState& state, const Eigen::VectorXd& dJ_du, const char* who);

/// The entries of a nodal vector v (3 per DOF node) at an element's DOF nodes.
Eigen::VectorXd element_values(const Eigen::VectorXd& v, const std::vector<int>& nodes);

}  // namespace parafab::occ
