// The terms of the exact shape gradient of compliance_gradient and adjoint_shape_gradient
// (thesis §6.5.3, Eq. 6.30–6.31; shape_compliance.h states the formulas): the bulk term
// (Reynolds over the moving patches, analytic faces and B-spline poles), J's own surface
// integral, a load's work for a total force's area term, a load's and a support's own motion
// with their edges, the strips along the edges of supports and loads where a neighbour moves,
// the local Nitsche penalty's dΛ, and Eq. 6.24's ties. shape_gradient (shape_compliance.cpp)
// builds the context, runs element_terms over the cut elements in parallel and sums them in
// element order. Only for occ_bridge/*.cpp.
#pragma once

#include <map>
#include <optional>
#include <set>
#include <utility>
#include <vector>

#include "shape_compliance.h"
#include "xfem/area_rules.h"
#include "xfem/quadrature_rule.h"

namespace parafab::occ::detail {

/// What every term reads: the state and job, the parameters at p, the adjoint (null: J = C) and
/// which faces' motion is differentiated where (the coverage of shape_compliance.h).
struct GradientContext {
  const ComplianceState& at;
  const ComplianceSetup& setup;
  const ShapeParameters& sp;
  const Eigen::VectorXd& p;
  const ShapeAdjoint* adj;  ///< null: the compliance (λ = −u, z = 2u)
  const char* who;          ///< the caller, in errors
  int np = 0;               ///< sp.size()
  /// Faces whose motion is wanted: some entry of their block (or pole block) is `moving`.
  std::vector<char> face_moves{};
  std::set<int> conditioned{};  ///< faces with a support or a load
  std::set<int> supports{};     ///< faces with a support
  std::map<int, std::vector<int>> neighbours{};  ///< support/load face → moving faces sharing an edge with it
  std::map<int, std::vector<int>> own_sides{};   ///< support or load whose own motion is differentiated → faces across its edges
  std::vector<double> sign{};                    ///< per face: the sign of its implicit function (implicit_sign), 0 unset
  /// J's own surface integral over F (the target objective): F (−1: none), the faces across F's
  /// edges whose motion slides them (with parameter blocks), and whether F's own motion is
  /// differentiated.
  int surface_face = -1;
  std::vector<int> surface_sides{};
  bool surface_own = false;
  std::vector<double> load_area{};  ///< per load: the face's area A of a total force (F/|t|), else 0
  bool local_penalty = false;     ///< xfem::LinearXfemOptions::NitschePenalty::Local
  bool gravity = false;
  xfem::SurfaceRuleOptions so{}, so_support{};  ///< the bulk's and a support's own motion's surface rules
  const xfem::QuadratureRule1* gauss = nullptr;  ///< along loop segments
  /// Pieces whose incompatible modes a tie condenses jointly (per tie), and element → (tie, 0
  /// for element_a, 1 for element_b).
  std::vector<char> modes_tied{};
  std::map<int, std::pair<int, int>> tied_side{};
};

/// Checks the arguments and builds the context; flags in `incomplete` the entries whose faces'
/// motion is not covered (a support's or load's own motion that fails the conditions, B-spline
/// poles moving an edge of a support, load or F).
GradientContext gradient_context(const ComplianceState& at, const ComplianceSetup& setup, const ShapeParameters& sp,
                                 const Eigen::VectorXd& p, const std::vector<char>* moving, const ShapeAdjoint* adj,
                                 const char* who, std::vector<char>& incomplete);

/// Marks every entry of `face`'s block (and pole block) incomplete.
void flag_face(const ShapeParameters& sp, int face, std::vector<char>& incomplete);

/// Cut elements with a patch on a face that has parameters, on a support or load, or on F.
std::vector<int> moving_elements(const GradientContext& c);

/// One element's contributions, summed by sum_terms in element order.
struct ElementTerms {
  std::vector<std::pair<int, double>> gradient;   // (entry of p, dC/dp contribution)
  std::vector<std::pair<int, double>> area;       // (load index · size(p) + entry, dA contribution)
  std::vector<std::pair<int, double>> work;       // (load index, ∫ z_h·t dA)
  std::vector<int> tangent;                       // faces met at a tangent edge of a support/load (or a moving load's own)
  std::vector<int> penalised;                     // moving faces in a cut cell with a local penalty
  std::set<int> penalised_poles;                  // entries of p: poles moving such a cell's patch
  int points = 0, edge_points = 0;
  bool used = false;
};

/// An element's fields and local penalty, shared by the terms of its patches.
struct ElementFields {
  int e = -1;
  const xfem::GridElement* el = nullptr;
  Eigen::VectorXd ue, le, ze;  ///< uₑ, λₑ, and the field the load's change is contracted with: 2uₑ or −λₑ
  std::optional<xfem::BulkShapeDensity> density;  ///< of this element's (u, u), or (λ, u), built on first use
  double h = 0;                                   ///< the cell's smallest side
  bool penalised = false;                         ///< a local penalty on a clamped patch of this cell
  xfem::LocalPenaltyParts parts;
  bool simple = false;  ///< Λ a simple eigenvalue: dΛ is differentiated
  double lambda = 0;    ///< Λ
  std::map<int, double> d_lambda;  ///< dΛ per entry of p
};
ElementFields element_fields(const GradientContext& c, int e);

/// A support's or load's conditions on its face (the last of each kind, as element_system takes them).
struct PatchConditions {
  const xfem::DirichletCondition* dc = nullptr;
  const xfem::TractionCondition* tc = nullptr;
  int load = -1;             ///< index of tc
  bool spread_load = false;  ///< tc is a total force's
};
PatchConditions patch_conditions(const GradientContext& c, int face);

// The terms on one patch of an element.
/// Bulk: Reynolds over a patch of a moving analytic face (Vₙ = ∂X/∂p_k·n), and −Λ vᵀdÂv.
void bulk_term(const GradientContext& c, ElementFields& f, const xfem::CutPatch& patch,
               const optimize::ParameterBlock& block, ElementTerms& out);
/// Bulk on a B-spline face: Vₙ = R_ij(u, v) n_c for coordinate c of pole (i, j).
void pole_bulk_term(const GradientContext& ctx, ElementFields& f, const xfem::CutPatch& patch, const PoleBlock& poles,
                    ElementTerms& out);
/// J's own surface integral ∫_F g dA over a patch of F: F's own motion and its edges, and the
/// strips where a neighbour's motion slides F's edges.
void surface_density_term(const GradientContext& c, ElementFields& f, const xfem::CutPatch& patch, ElementTerms& out);
/// ∫ z_h·t dA over a total force's load patch, for the area term.
void load_work_term(const GradientContext& c, const ElementFields& f, const xfem::CutPatch& patch,
                    const PatchConditions& pc, ElementTerms& out);
/// A load's own motion (the surface-integral form of Eq. 6.30) and its edges.
void moving_load_term(const GradientContext& c, const ElementFields& f, const xfem::CutPatch& patch,
                      const PatchConditions& pc, ElementTerms& out);
/// A support's own motion (its Nitsche terms, Eq. 6.22, on a moving Γ), its edges and its vᵀdBv.
void moving_support_term(const GradientContext& c, ElementFields& f, const xfem::CutPatch& patch,
                         const PatchConditions& pc, ElementTerms& out);
/// The strips of a support's or load's patch along its edges on moving neighbours.
void neighbour_strips_term(const GradientContext& c, ElementFields& f, const xfem::CutPatch& patch,
                           const PatchConditions& pc, ElementTerms& out);
/// The local penalty's change κ dΛ times its weight (after the element's patches).
void penalty_term(const GradientContext& c, const ElementFields& f, ElementTerms& out);

/// Every term of element e (an entry of moving_elements), patch by patch.
ElementTerms element_terms(const GradientContext& c, int e);

/// The elements' terms added into r in element order (deterministic), with the total forces'
/// area terms −W dA/A.
void sum_terms(const GradientContext& c, const std::vector<ElementTerms>& terms, ComplianceGradient& r);

/// Eq. 6.24's ties: the change of their penalty with the gaps' distances.
void tie_terms(const GradientContext& c, ComplianceGradient& r);

}  // namespace parafab::occ::detail
