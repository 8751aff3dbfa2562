// Linear elasticity on a fixed hexahedral grid with cut elements (thesis §6.4): trilinear
// (hex8) or triquadratic (hex27 Lagrange) hexahedra; every cut subvolume is its own element
// with copies of its cell's nodal DOFs (the change of basis of Eq. 6.20), shared between
// subvolumes connected through grid faces;
// Dirichlet conditions on B-rep faces by symmetric Nitsche (Eq. 6.22), tractions (Eq. 6.23)
// and gravity; sparse Cholesky (CHOLMOD) solve, or PETSc CG + AMG at scale.
#pragma once

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <array>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "xfem/cut_geometry.h"
#include "xfem/petsc_system.h"
#include "xfem/quadrature_rule.h"
#include "xfem/reuse_solve.h"
#include "xfem/sparse_cholesky.h"

namespace parafab::xfem {

/// One element: an uncut interior cell (no patches) or one subvolume of a cut cell.
struct GridElement {
  std::array<int, 3> cell{0, 0, 0};  ///< grid cell index
  Box3 box;                          ///< the cell's box (trilinear shape functions live here)
  QuadratureRule3 rule;              ///< volume rule over the element's part of the solid
  const Subvolume* subvolume = nullptr;  ///< boundary patches (null for interior cells)
  /// When ≥ 0: the volume fraction the discrete switches use (aggregation: small element and
  /// host choice; incompatible modes on or off) instead of the rule's own. Set from another
  /// model to freeze those switches, e.g. during an optimizer's line search
  /// (occ::compliance_at). −1: the rule's own (volume_fraction).
  double switch_fraction = -1;
  /// When set: the box on whose tensor Gauss points integrands outside the span the rule fits
  /// (occ::failure_value's exponential) are integrated, with weights fitted to this element's
  /// moments there. Set from another model with the switches (occ::compliance_at), so that such
  /// an objective along a line search integrates on fixed points, as thesis Eq. 6.31 assumes.
  /// Unset: the rule's own box (rule_frame).
  std::optional<Box3> frame;
};

/// Σ rule weights / box volume.
double volume_fraction(const GridElement& element);
/// element.frame when set, else rule_box(element).
Box3 rule_frame(const GridElement& element);
/// The box of the element's tensor Gauss rule (a cut cell's fitting box, an uncut cell's box),
/// recovered from its first and last points; the cell's box for an element without rule points
/// (a failed rule). Throws parafab::Error unless the rule has n³ points (n ≥ 2) or none.
Box3 rule_box(const GridElement& element);
/// The fraction the discrete switches see: switch_fraction when set, else volume_fraction.
inline double switching_fraction(const GridElement& element) {
  return element.switch_fraction >= 0 ? element.switch_fraction : volume_fraction(element);
}

struct ElasticMaterial {
  double youngs_modulus = 1;  ///< E
  double poisson_ratio = 0.3; ///< ν
  double density = 0;         ///< ρ (for gravity)
};

/// u = value(X) on B-rep face `face` (Nitsche).
struct DirichletCondition {
  int face = -1;
  Eigen::Matrix3d gradient = Eigen::Matrix3d::Zero();  ///< u(X) = offset + gradient·X
  Vec3 offset{0, 0, 0};
  /// Which displacement components are prescribed (1) or free (0): e.g. (0, 0, 1) lets the
  /// face slide in its plane z = const (a symmetry or roller condition).
  Vec3 components{1, 1, 1};
  /// When set, u = field(X) instead of offset + gradient·X (e.g. an exact solution that is not
  /// linear on the face, for convergence studies).
  std::function<Vec3(const Vec3&)> field;
};

/// Traction (force per area) on B-rep face `face`.
struct TractionCondition {
  int face = -1;
  Vec3 traction{0, 0, 0};
};

/// The basis on the grid cells. Hex8: trilinear, 8 corner nodes (with Wilson–Taylor
/// incompatible modes, see LinearXfemOptions). Hex27: triquadratic Lagrange, 27 nodes (corners,
/// edge midpoints, face centres, centre); its uncut cells need 3×3×3 Gauss rules and its cut
/// cells moment-fitted rules of degree ≥ 5 (occ::rules_for_element sets both).
enum class ElementType { Hex8, Hex27 };

/// "hex8" / "hex27"; throws parafab::Error naming `field` and the value otherwise.
ElementType element_type_from_name(const std::string& name, const std::string& field = "element");
const char* element_type_name(ElementType type);
/// 8 or 27.
int nodes_per_element(ElementType type);

struct LinearXfemOptions {
  ElementType element = ElementType::Hex8;  ///< the basis (rules must match: occ::rules_for_element)
  /// Nitsche stabilization β: the fixed penalty is β·E/h. 0 picks the default 100.
  double nitsche_beta = 0;
  /// The Nitsche penalty p of a cut element with a Dirichlet patch (thesis Eq. 6.22 leaves it
  /// between "unstable" and "locking", Fig. 6.11). Fixed: p = β·E/h on every element. Local:
  /// p = κ·Λₑ with Λₑ the smallest constant of ‖M σ(v)n‖²_Γₑ ≤ Λₑ âₑ(v, v) (a generalized
  /// eigenvalue; âₑ = aₑ + floor × the uncut cell's energy), so that the element's terms satisfy
  /// vᵀKₑv = aₑ + p‖Mv‖² − 2(Mv, Mσ(v)n) ≥ aₑ − âₑ/κ: coercive for κ > 1 up to the floor (cf.
  /// Griebel & Schweitzer 2003; Embar, Dolbow & Harari 2010); a sliver under the floor can leave
  /// the matrix indefinite (the solve then says so and uses LU). One dense generalized eigensolve
  /// per clamped cut element. Its shape derivative: local_penalty_parts (used by
  /// occ::compliance_gradient). Not the default (the README's figures and
  /// the optimizer's are measured with Fixed).
  enum class NitschePenalty { Fixed, Local };
  NitschePenalty nitsche_penalty = NitschePenalty::Fixed;
  double nitsche_local_factor = 4;  ///< κ
  /// The floor of âₑ: a sliver (volume fraction ≪ floor, its nodes aggregated) gets about the
  /// penalty of a piece of that fraction instead of one growing as 1/fraction. The price: such a
  /// cell's terms are only ≥ aₑ − âₑ/κ, and the turned L-bracket on the optimizer's 10-cell hex8
  /// grid is then indefinite (positive definite with floor 1e-4 or 0, which in turn moved the
  /// turned rubber block's bulge from 1.0 % to 1.2–1.6 % off CalculiX).
  double nitsche_local_floor = 5e-3;
  Vec3 gravity{0, 0, 0};  ///< acceleration; body force ρ·g
  /// Patch rules for Nitsche and traction integrals; hex27 uses at least 8 (the consistency
  /// term v·σ(u)n of a quadratic field is of degree 7).
  int surface_degree = 5;
  /// Patch rules on a curved Dirichlet (Nitsche) patch are of at least this degree. On a curved support
  /// the Nitsche integrand (σ(u)n·v with n turning) is no polynomial, and a degree-5 rule's error
  /// there changes with the shape: the exact shape gradient (which integrates those terms exactly)
  /// and the differences of the solver parted by 1e-4 … 1e-3 of dC on a clamped bolt hole and
  /// countersink (README "Shape optimization", tests ShapeCompliance.ASupportsOwnMotion…).
  /// Traction patches keep surface_degree (their integrand v·t is of low degree).
  int dirichlet_surface_degree = 8;
  /// Wilson–Taylor incompatible modes (statically condensed) against bending locking of the
  /// trilinear hexahedra; off: plain hex8. Not used by hex27 (no such locking).
  bool incompatible_modes = true;
  double incompatible_min_fraction = 1e-3;  ///< not on elements with a smaller volume fraction
  /// Small cut cells (the thesis is silent; cf. aggregated FEM, Badia et al. 2018): a DOF node
  /// used only by elements whose volume fraction is below this follows the trilinear (hex8) or
  /// triquadratic (hex27) field of the largest face-connected normal element (extrapolated to
  /// the node's position), so conditioning stays bounded
  /// as fractions go to 0. 0 turns it off.
  double aggregation_fraction = 0.05;
  /// Memory the factorization may bring the process to, in MB (SparseCholesky::memory_limit_mb:
  /// checked against the factor's exact size before it is computed). 0: 70% of the memory.
  double memory_limit_mb = 0;
  /// The solver of the reduced system TᵀKT: CHOLMOD's supernodal Cholesky (exact to round-off,
  /// memory growing as n^{4/3}), PETSc's Krylov solver with AMG (`krylov`, memory linear in n),
  /// or Auto: PETSc from `petsc_from` reduced unknowns on and whenever the process runs under
  /// mpirun with more than one rank, CHOLMOD otherwise (and always in a build without PETSc).
  struct Solver {
    enum class Type { Auto, Cholmod, Petsc };
    Type type = Type::Auto;
    KrylovOptions krylov;
    /// From tests/bench/bench_xfem_scale.py (turned L-bracket, hex8): at 123,120 unknowns PETSc
    /// and CHOLMOD solve in about the same time and PETSc needs 0.56× the memory; at 369,192 it is
    /// faster and needs 0.40×. Below, CHOLMOD's exact solve costs nothing extra.
    int petsc_from = 200000;
  } solver;
  /// What a LinearXfemSolver carries from one solve to the next (a re-solve after a re-cut):
  struct Reuse {
    /// Elements equal to one of the previous solve (same cell, box and rule bit for bit, and for
    /// boundary terms the same patches, surfaces and conditions; same material and options)
    /// take its element matrix and load instead of being integrated again.
    bool elements = true;
    /// A changed system is solved by CG preconditioned with the previous factorization (see
    /// ReusedFactorization) from the previous solution; a fresh factorization when fewer than
    /// min_mapped of its DOFs are DOFs of the factorized system, or CG does not converge in
    /// pcg.max_iterations (reported in LinearXfemResult::solve_info).
    bool factorization = true;
    PcgOptions pcg{1e-10, 100};
    double min_mapped = 0.5;
    ReusedFactorizationOptions preconditioner;
  } reuse;
};

/// The degree of the solver's patch rule on a boundary patch with a Dirichlet condition or
/// only a traction: surface_degree, at least 8 for hex27, at least dirichlet_surface_degree on
/// a curved Dirichlet patch (one whose surface map is not affine). On a plane the Nitsche
/// integrand is a polynomial (of degree 6 per direction on a tilted plane: the penalty's |u|²
/// of a trilinear u) and the degree-5 error's change is small (the turned bracket's clamped top,
/// turning: 1.2e-6 of dC); planar clamps are the common case, and at degree 8 the turned
/// bracket's hyperelastic Newton solve (XfemParallel.NewtonIdenticalForOneAndTwoThreads) stalled
/// at 1.1e-5, just above its tolerance (5, 6, 7 and 10 converge: round-off). Whoever integrates
/// the solver's boundary terms again uses this.
int patch_rule_degree(const LinearXfemOptions& options, const CutPatch& patch, bool dirichlet);

/// How LinearXfemSolver solved the system.
struct SolveInfo {
  /// "cholesky" (factorized), "pcg" (CG preconditioned by an earlier factorization),
  /// "cholesky after pcg" (CG did not converge: factorized; `fallback` says why), "cholesky after
  /// petsc" (Auto: the Krylov solve failed; `fallback` says why), or "petsc"
  /// (LinearXfemOptions::solver: `krylov` says which Krylov solver and preconditioner).
  std::string method = "cholesky";
  std::string fallback;      ///< why CG was not used or failed ("" when it was not tried)
  int iterations = 0;        ///< CG iterations
  double residual = 0;       ///< ‖f − K u‖ / ‖f‖ of the reduced system
  int mapped_dofs = 0, changed_dofs = 0, local_dofs = 0;  ///< see ReusedFactorization
  double pcg_seconds = 0, factorize_seconds = 0;
  double pcg_setup_seconds = 0;  ///< of pcg_seconds: the changed rows and the local factorization
  /// Method "petsc": its Krylov solver and preconditioner ("cg+gamg"), ranks, the matrix copy and
  /// the preconditioner's setup (the rest of petsc_seconds is the iterations), PETSc's memory.
  std::string krylov;
  int ranks = 1;
  double petsc_seconds = 0, petsc_copy_seconds = 0, petsc_setup_seconds = 0, petsc_memory_mb = 0;
};

struct LinearXfemResult {
  bool solved = false;
  /// K was not positive definite and was solved by LU: the displacement is not an elastic
  /// equilibrium to trust (too small a Nitsche penalty, too few supports); `message` says which.
  bool indefinite = false;
  std::string message;
  int dofs = 0, elements = 0, cut_elements = 0;
  Eigen::VectorXd u;                     ///< 3 per DOF node
  /// Per element: the DOF node of each of its 8 (hex8) or 27 (hex27) nodes, in the order of
  /// node_offset.
  std::vector<std::vector<int>> node;
  double assemble_seconds = 0, solve_seconds = 0;
  double energy = 0;                     ///< ½ uᵀKu − fᵀu at the solution
  int aggregated_nodes = 0;              ///< DOF nodes tied to a neighbour (small cut cells)
  int tied_node_pairs = 0;               ///< pairs of unknown DOF nodes under a PieceTie penalty
  int blended_nodes = 0;                 ///< floating DOF nodes a PieceTie blends towards an unknown
  int mode_tied_pairs = 0;               ///< PieceTies whose pieces' modes were condensed jointly (mode_tied)
  std::vector<char> floating;            ///< per DOF node: aggregated (follows a host); empty when none is
  /// Elements whose stiffness was copied from the one uncut interior cell integrated (all
  /// interior cells of a grid have the same box size and rule, hence the same matrix).
  int reused_element_matrices = 0;
  /// Elements whose system was taken from the previous solve of the same LinearXfemSolver.
  int cached_element_matrices = 0;
  SolveInfo solve_info;
  /// Phases of assemble_seconds: DOF numbering, element matrices (integration or copies),
  /// scatter into the sparse matrix, aggregation (TᵀKT).
  double number_seconds = 0, integrate_seconds = 0, scatter_seconds = 0, aggregate_seconds = 0;
  /// The factorization of the reduced stiffness TᵀKT (null if the solve failed). Shared with
  /// the LinearXfemSolver that made it: its next solve factorizes again in place.
  std::shared_ptr<const SparseCholesky> factorization;
  /// The aggregation map T (u = T u_reduced); empty (0 × 0) when nothing is aggregated (T = I).
  Eigen::SparseMatrix<double> aggregation;
  /// Method "pcg": the reduced system and its preconditioner (factorization is then null);
  /// solve_again runs CG on it.
  std::shared_ptr<const ReusedFactorization> preconditioned;
  PcgOptions pcg;
  /// Method "petsc": the reduced system in PETSc with its preconditioner (factorization is then
  /// null); solve_again runs the same Krylov solver on it.
  std::shared_ptr<const PetscSystem> iterative;

  /// The displacement (every DOF node) under another load vector f (size dofs, e.g. an adjoint
  /// right-hand side) with the kept factorization: T (TᵀKT)⁻¹ Tᵀ f (by CG with the same
  /// preconditioner and tolerance when the solve was "pcg"). Throws parafab::Error when there is
  /// no factorization, CG does not converge, or f has the wrong size.
  Eigen::VectorXd solve_again(const Eigen::VectorXd& f) const;

  /// Displacement at X inside element e (interpolation of its DOF nodes).
  Vec3 displacement(const std::vector<GridElement>& elements, int e, const Vec3& X) const;
};

/// Trilinear shape functions of the cell `box` at X (physical coordinates, not restricted to
/// the box): values N and gradients G (8×3), corners numbered as in `corner`.
void trilinear_shape(const Box3& box, const Vec3& X, Eigen::Matrix<double, 8, 1>& N,
                     Eigen::Matrix<double, 8, 3>& G);

/// Triquadratic Lagrange shape functions of the cell `box` at X: values N and gradients G
/// (27×3), node k = i + 3j + 9l at box.min + (i, j, l)·size/2.
void triquadratic_shape(const Box3& box, const Vec3& X, Eigen::Matrix<double, 27, 1>& N,
                        Eigen::Matrix<double, 27, 3>& G);

/// Corner k of a cell box in the node order used everywhere: bit 0 → x, bit 1 → y, bit 2 → z.
Vec3 corner(const Box3& box, int k);

/// Node k of an element with `nodes` (8 or 27) nodes, in half cells from the cell's min corner
/// (0, 1 or 2 per axis): hex8 node k at 2·(bit 0, bit 1, bit 2) of k; hex27 node k = i + 3j + 9l
/// at (i, j, l).
std::array<int, 3> node_offset(int nodes, int k);
/// The position of that node in `box`.
Vec3 node_position(const Box3& box, int nodes, int k);

/// DOF-node numbering: nodes of elements connected through a grid face (`adjacent` pairs of
/// element indices) share a DOF node where they sit at the same grid position (corners for
/// hex8; corners, edge midpoints and face centres for hex27).
std::vector<std::vector<int>> number_dof_nodes(const std::vector<GridElement>& elements,
                                               const std::vector<std::array<int, 2>>& adjacent,
                                               int& count, ElementType element = ElementType::Hex8);

/// Sparse assembly in bounded memory: triplets are summed into the matrix every `chunk`
/// entries (a hex27 element contributes 81² of them).
class SparseAccumulator {
 public:
  SparseAccumulator(int rows, int cols, size_t chunk = size_t(1) << 22);
  void add(int row, int col, double value) {
    triplets_.emplace_back(row, col, value);
    if (triplets_.size() >= chunk_) flush();
  }
  Eigen::SparseMatrix<double> finish();

 private:
  void flush();
  Eigen::SparseMatrix<double> matrix_;
  std::vector<Eigen::Triplet<double>> triplets_;
  size_t chunk_;
};

/// One element's dense stiffness (3n × 3n, DOFs 3k + component for its n = 8 or 27 nodes) and
/// load: bulk (if include_bulk; hex8 with incompatible modes condensed), gravity, and the
/// Nitsche and traction terms on its boundary patches. Independent of every other element.
struct ElementSystem {
  Eigen::MatrixXd K;
  Eigen::VectorXd f;
};
ElementSystem element_system(const GridElement& element, const ElasticMaterial& material,
                             const std::vector<DirichletCondition>& dirichlet,
                             const std::vector<TractionCondition>& tractions,
                             const LinearXfemOptions& options, bool include_bulk = true);

/// The Nitsche penalty element_system uses on `element`'s Dirichlet patches (per unit area):
/// β·E/h (Fixed), or κ·Λₑ (Local; 0 when the element has no Dirichlet patch), see
/// LinearXfemOptions::nitsche_penalty.
double nitsche_penalty(const GridElement& element, const ElasticMaterial& material,
                       const std::vector<DirichletCondition>& dirichlet, const LinearXfemOptions& options);

/// Shape-derivative density of an element's bulk bilinear form vₑᵀKₑuₑ (thesis §6.5.3,
/// Eq. 6.30–6.31 with the rule's points frozen): when the element's domain moves with normal
/// boundary velocity Vₙ, d(vₑᵀKₑuₑ) = ∫_{∂Vₑ} ψ Vₙ dA, and ψ at the rule's points is
/// ∂(vₑᵀKₑuₑ)/∂w_j. Exact when the rule integrates the element's integrand exactly (its
/// moment-fitted span holds it, as occ::rules_for_element arranges): then the rule derivative
/// Σ_j (∂w_j/∂p) k(X_j) of Eq. 6.31 equals Reynolds' ∫_{∂V} k Vₙ dA. ψ = ε(v)ᵀDε(u) for hex27 and
/// plain hex8; with incompatible modes the condensed modes enter ε (by the envelope theorem
/// their own change does not) and the modes' zero-mean shift adds a term. Nitsche and traction
/// terms are not included (their patches do not move with the volume). Returns ψ at `points`.
std::vector<double> bulk_shape_density(const GridElement& element, const Eigen::VectorXd& ve, const Eigen::VectorXd& ue,
                                       const ElasticMaterial& material, const LinearXfemOptions& options,
                                       const std::vector<Vec3>& points);

/// bulk_shape_density of one element at any number of point sets: what depends on the element
/// alone (the condensed incompatible modes of vₑ and uₑ and their mean-shift term, each a pass
/// over the element's volume rule) is computed once, on the first call. The same numbers as
/// bulk_shape_density; a cut cell's several moving patches then cost one volume pass, not one each.
class BulkShapeDensity {
 public:
  BulkShapeDensity(const GridElement& element, const Eigen::VectorXd& ve, const Eigen::VectorXd& ue,
                   const ElasticMaterial& material, const LinearXfemOptions& options);
  ~BulkShapeDensity();
  BulkShapeDensity(BulkShapeDensity&&) noexcept;
  std::vector<double> operator()(const std::vector<Vec3>& points);

 private:
  struct Element;
  std::unique_ptr<Element> element_;
};

/// The Nitsche and traction terms of element_system per unit area at a boundary point X with
/// outward normal n, contracted with the element's nodal values uₑ: uₑᵀKₑuₑ = ∫ stiffness dA and
/// uₑᵀfₑ = ∫ load dA over the condition's patches (bulk and gravity not included). When a
/// support's or load's patch grows by a strip of width a ds along its edge, uᵀKu and uᵀf change
/// by these densities times a ds. `dirichlet` and `traction` may be null.
/// With the local penalty the element's penalty must be given (`local_penalty`, from
/// local_penalty_parts). `flux` = |M σ(u)n|², the density of uᵀBu (B of the local penalty).
/// `load_gradient` = ∇_X of `load` at X with n held (uₕ·t, plus the Dirichlet part): a load
/// face's or support's own motion moves its patch through the element's field. With a Dirichlet
/// condition also ∇_X of `stiffness` and `flux` (n held; from the shape functions' second
/// derivatives) and ∂/∂n of `stiffness`, `load` and `flux` (X held): a support's own motion turns
/// its normal (n' = −∇_Γ Vₙ, optimize::implicit_normal_speed). A prescribed `field` is taken as
/// having no gradient (the caller must not differentiate its motion).
struct BoundaryTermDensity {
  double stiffness = 0;
  double load = 0;
  double flux = 0;
  Vec3 load_gradient = Vec3::Zero();
  Vec3 stiffness_gradient = Vec3::Zero();
  Vec3 flux_gradient = Vec3::Zero();
  Vec3 stiffness_normal = Vec3::Zero();
  Vec3 load_normal = Vec3::Zero();
  Vec3 flux_normal = Vec3::Zero();
};
BoundaryTermDensity boundary_term_density(const GridElement& element, const Eigen::VectorXd& ue,
                                          const ElasticMaterial& material, const LinearXfemOptions& options,
                                          const DirichletCondition* dirichlet, const TractionCondition* traction,
                                          const Vec3& X, const Vec3& normal, double local_penalty = -1);

/// The local Nitsche penalty of an element (LinearXfemOptions::NitschePenalty::Local) and what its
/// shape derivative needs: with B v = Λ Â v (vᵀÂv = 1, v off the rigid modes), a change of the
/// element's domain changes Λ by dΛ = vᵀ dB v − Λ vᵀ dÂ v (a simple eigenvalue: `gap` > 0), where
/// vᵀdÂv is the bulk density of (v, v) at the moving boundary (bulk_shape_density; the floor's
/// uncut cell does not move) and vᵀdBv the `flux` density of v along a moving edge of the
/// clamped patch; then uᵀKu and uᵀf change by κ dΛ (uᵀ mass u) and κ dΛ (uᵀ load).
struct LocalPenaltyParts {
  bool clamped = false;         ///< the element has a Dirichlet patch (else the rest is empty)
  double penalty = 0;           ///< κ Λ
  double flux_eigenvalue = 0;   ///< Λ
  Eigen::VectorXd mode;         ///< v
  double gap = 1;               ///< (Λ − λ₂)/Λ
  Eigen::MatrixXd mass;         ///< Σ w NᵀMN over the Dirichlet patches
  Eigen::VectorXd load;         ///< Σ w NᵀM g
};
LocalPenaltyParts local_penalty_parts(const GridElement& element, const ElasticMaterial& material,
                                      const std::vector<DirichletCondition>& dirichlet, const LinearXfemOptions& options);

/// Assembled stiffness and load (no Dirichlet conditions folded in unless given). The element
/// type is options.element; `node` must have its node count per element. Element matrices are
/// computed in parallel (TBB) and scattered in element order: the result is bit-identical for
/// every thread count. Uncut interior cells of one size get one matrix.
struct LinearSystem {
  Eigen::SparseMatrix<double> K;
  Eigen::VectorXd f;
  int reused_element_matrices = 0;  ///< uncut elements given the one interior cell matrix
};
LinearSystem assemble_linear(const std::vector<GridElement>& elements,
                             const std::vector<std::vector<int>>& node, int node_count,
                             const ElasticMaterial& material,
                             const std::vector<DirichletCondition>& dirichlet,
                             const std::vector<TractionCondition>& tractions,
                             const LinearXfemOptions& options, bool include_bulk = true);

/// Element systems from elsewhere (a cache): known(e) returns element e's system or null (then
/// it is integrated); made(e, system) is called for every element integrated or copied from
/// the interior matrix, from several threads at once (for different e).
struct ElementSource {
  std::function<const ElementSystem*(size_t)> known;
  std::function<void(size_t, const ElementSystem&)> made;
};
/// assemble_linear with `source`; also times the element matrices and the scatter.
LinearSystem assemble_linear(const std::vector<GridElement>& elements,
                             const std::vector<std::vector<int>>& node, int node_count,
                             const ElasticMaterial& material,
                             const std::vector<DirichletCondition>& dirichlet,
                             const std::vector<TractionCondition>& tractions,
                             const LinearXfemOptions& options, bool include_bulk, const ElementSource& source,
                             double* integrate_seconds = nullptr, double* scatter_seconds = nullptr);

/// The map u = T u_reduced of cell aggregation (see LinearXfemOptions::aggregation_fraction):
/// identity rows for ordinary DOF nodes, extrapolation rows for floating ones (the element
/// type follows from the node count per element). `reduced`: per DOF node its reduced node
/// (column block of T), −1 for floating ones.
Eigen::SparseMatrix<double> aggregation_map(const std::vector<GridElement>& elements,
                                            const std::vector<std::array<int, 2>>& adjacent,
                                            const std::vector<std::vector<int>>& node, int count,
                                            double fraction, int* aggregated = nullptr,
                                            std::vector<int>* reduced = nullptr);

/// Whether the discrete switches (aggregation's small elements and hosts, incompatible modes)
/// come out the same from every element's switch_fraction as from its own volume fraction
/// (true when no switch_fraction is set).
bool switches_match_own_fractions(const std::vector<GridElement>& elements,
                                  const std::vector<std::array<int, 2>>& adjacent, const LinearXfemOptions& options);

/// Thesis §6.4.4, Eq. 6.24: two elements about to join (two pieces of one cell, or pieces of
/// face-neighbour cells that share no part of their face) hold different DOF nodes at the grid
/// positions they share; at the join these become one. The penalty weight·‖x_a − x_b‖² on each
/// such pair of DOF nodes, added to the energy, makes that transition continuous as the weight
/// grows to its cap at the join (occ::piece_ties sets it from the pieces' gap d: E·h·b(d)).
/// A floating (aggregated) node is not penalized (that would couple two hosts' extrapolations):
/// paired with an unknown node, its row of the aggregation map T is blended towards that node,
/// (1 − θ)·T_floating + θ·T_unknown (θ = `blend`, 1 at the join, where the joined piece's node is
/// that unknown); two floating nodes keep their hosts. Hex8's incompatible modes of two pieces of
/// one cell are condensed jointly (see mode_tied): the joined piece has one mode set where the
/// pieces have two.
struct PieceTie {
  int element_a = -1, element_b = -1;
  double weight = 0;
  double blend = 0;  ///< θ ∈ [0, 1]
};
/// The pairs of DOF nodes (node[a][k], node[b][l]) a tie holds together: the grid positions
/// elements a and b share (hex8 corners, hex27 nodes) where their DOF nodes differ.
std::vector<std::array<int, 2>> tied_nodes(const std::vector<GridElement>& elements,
                                           const std::vector<std::vector<int>>& node, const PieceTie& tie);

/// Per tie: whether the incompatible modes of its two pieces are condensed jointly: hex8 with
/// incompatible modes, weight > 0, two pieces of one cell (one box: the same mode functions),
/// both with modes of their own (as element_system gives them: above incompatible_min_fraction,
/// K_aa not near singular), neither in another such tie
/// (three close pieces of one cell keep their own modes: no continuity there). The energy then
/// gets ½·weight·‖α_a − α_b‖² on the two mode sets, and each piece's mean shift of the mode
/// gradients moves towards the pair's, (1 − θ)·M_piece + θ·M_pair (θ = blend): at the join
/// (θ = 1, the weight at its cap) the joined piece's one set and mean.
std::vector<char> mode_tied(const std::vector<GridElement>& elements, const std::vector<PieceTie>& ties,
                            const ElasticMaterial& material, const LinearXfemOptions& options);

/// What a mode-tied pair (mode_tied) adds to the stiffness on its two pieces' 8 + 8 nodes
/// (48 × 48, a's then b's): the jointly condensed modes minus each piece's own condensation.
Eigen::MatrixXd tied_mode_correction(const GridElement& a, const GridElement& b, const PieceTie& tie,
                                     const ElasticMaterial& material, const LinearXfemOptions& options);

/// Shape-derivative parts of a mode-tied pair (mode_tied) at nodal values ua, ub (24 each) of
/// pieces element_a, element_b, the pair's modes condensed (envelope theorem: their change does
/// not enter): `density` is bulk_shape_density's ψ at `points` on piece `side` (0: element_a,
/// 1: element_b), with the means' changes as the pieces' rule weights move;
/// d_weight = ∂(uᵀKu)/∂weight = ‖α_a − α_b‖²; d_blend = ∂(uᵀKu)/∂θ.
struct TiedModeShapeTerms {
  std::vector<double> density;
  double d_weight = 0, d_blend = 0;
};
TiedModeShapeTerms tied_mode_shape_terms(const std::vector<GridElement>& elements, const PieceTie& tie,
                                         const Eigen::VectorXd& ua, const Eigen::VectorXd& ub,
                                         const ElasticMaterial& material, const LinearXfemOptions& options, int side,
                                         const std::vector<Vec3>& points);

LinearXfemResult solve_linear(const std::vector<GridElement>& elements,
                              const std::vector<std::array<int, 2>>& adjacent,
                              const ElasticMaterial& material,
                              const std::vector<DirichletCondition>& dirichlet,
                              const std::vector<TractionCondition>& tractions,
                              const LinearXfemOptions& options = {}, const std::vector<PieceTie>& ties = {});

/// solve_linear with state kept between solves (options.reuse), for a re-solve after a
/// re-cut or a load change:
/// - element matrices: elements equal to ones of the previous solve are not integrated again
///   (the uncut cells of a grid share one matrix in any case);
/// - the factorization: a changed system is solved by CG preconditioned with the last
///   factorization (ReusedFactorization), DOFs matched through the equal elements; a system
///   with the factorized pattern but other values is factorized again reusing the symbolic
///   analysis (in place: earlier results sharing it see the new factors); another pattern gets
///   a new factorization object (earlier results keep theirs).
class LinearXfemSolver {
 public:
  LinearXfemSolver();
  ~LinearXfemSolver();
  LinearXfemResult solve(const std::vector<GridElement>& elements, const std::vector<std::array<int, 2>>& adjacent,
                         const ElasticMaterial& material, const std::vector<DirichletCondition>& dirichlet,
                         const std::vector<TractionCondition>& tractions, const LinearXfemOptions& options = {},
                         const std::vector<PieceTie>& ties = {});
  /// The factorization of the last factorized system; analyses and factorizations count over
  /// the solver's life.
  const SparseCholesky& cholesky() const { return *cholesky_; }
  /// Element e's system as the last solve assembled it (copied or integrated); null when e is
  /// out of range or its system was not kept (uncut cells share one, returned for each).
  const ElementSystem* element_system(int e) const;
  /// Forget everything but the counters (the next solve integrates and factorizes afresh).
  void clear();

 private:
  struct Previous;
  std::shared_ptr<SparseCholesky> cholesky_;
  std::unique_ptr<Previous> previous_;
};

}  // namespace parafab::xfem

namespace parafab::xfem {

/// Cauchy stress (Voigt xx, yy, zz, xy, yz, xz) of the solution at X in element e
/// (small strain: σ = D ε).
Eigen::Matrix<double, 6, 1> stress_at(const LinearXfemResult& result, const std::vector<GridElement>& elements,
                                      const ElasticMaterial& material, int e, const Vec3& X);
double von_mises(const Eigen::Matrix<double, 6, 1>& s);

}  // namespace parafab::xfem

namespace parafab::xfem {

/// ∇u (∂u_i/∂X_j) of the solution at X in element e.
Eigen::Matrix3d displacement_gradient(const LinearXfemResult& result, const std::vector<GridElement>& elements,
                                      int e, const Vec3& X);

/// u and ∇u at several points of element e: the element's nodal values gathered once, one
/// fixed-size shape-function evaluation per point (the results pass over every rule point).
void displacement_and_gradient(const LinearXfemResult& result, const std::vector<GridElement>& elements, int e,
                               const std::vector<Vec3>& X, std::vector<Vec3>& u, std::vector<Eigen::Matrix3d>& H);

/// Upper bounds over element e's box of |u|, ‖∇u‖_F and (with `material`) the von Mises stress
/// of the linear-elastic stress, by the convex-hull property of the Bernstein form of the
/// element's field (trilinear: the nodal values; triquadratic: per axis b1 = 2 f½ − (f0 + f1)/2):
/// u is a convex combination of the control points b, ∇u one of control matrices (the scaled
/// differences Δ_d b, degree-raised along d), and each bound is the largest value of a convex
/// function at them. The results pass skips cut elements whose bounds cannot beat the maxima of
/// the uncut ones. Valid for points in the box only.
struct FieldBounds {
  double displacement = 0;  ///< ≥ max |u| over the box
  double gradient = 0;      ///< ≥ max ‖∇u‖_F over the box
  double von_mises = 0;     ///< ≥ max σ_vm(D ε(∇u)) over the box (0 without a material)
};
FieldBounds field_bounds(const LinearXfemResult& result, const std::vector<GridElement>& elements, int e,
                         const ElasticMaterial* material = nullptr);

/// u alone at several points of element e (the same shape functions, no gradients).
void displacement_at(const LinearXfemResult& result, const std::vector<GridElement>& elements, int e,
                     const std::vector<Vec3>& X, std::vector<Vec3>& u);

/// Small-strain Cauchy stress σ = D ε(∇u) (Voigt xx, yy, zz, xy, yz, xz).
Eigen::Matrix<double, 6, 1> stress_from_gradient(const ElasticMaterial& material, const Eigen::Matrix3d& H);

}  // namespace parafab::xfem
