// Linear elasticity on a fixed hexahedral grid with cut elements (thesis §6.4): trilinear
// hexahedra; every cut subvolume is its own element with copies of its cell's nodal DOFs
// (the change of basis of Eq. 6.20), shared between subvolumes connected through grid faces;
// Dirichlet conditions on B-rep faces by symmetric Nitsche (Eq. 6.22), tractions (Eq. 6.23)
// and gravity; sparse Cholesky (CHOLMOD) solve.
#pragma once

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <array>
#include <memory>
#include <string>
#include <vector>

#include "xfem/cut_geometry.h"
#include "xfem/quadrature_rule.h"
#include "xfem/sparse_cholesky.h"

namespace parafab::xfem {

/// One element: an uncut interior cell (no patches) or one subvolume of a cut cell.
struct GridElement {
  std::array<int, 3> cell{0, 0, 0};  ///< grid cell index
  Box3 box;                          ///< the cell's box (trilinear shape functions live here)
  QuadratureRule3 rule;              ///< volume rule over the element's part of the solid
  const Subvolume* subvolume = nullptr;  ///< boundary patches (null for interior cells)
};

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
};

/// Traction (force per area) on B-rep face `face`.
struct TractionCondition {
  int face = -1;
  Vec3 traction{0, 0, 0};
};

struct LinearXfemOptions {
  /// Nitsche stabilization β: the penalty is β·E/h. 0 picks the default 100.
  double nitsche_beta = 0;
  Vec3 gravity{0, 0, 0};  ///< acceleration; body force ρ·g
  int surface_degree = 5; ///< patch rules for Nitsche and traction integrals
  /// Wilson–Taylor incompatible modes (statically condensed) against bending locking of the
  /// trilinear hexahedra; off: plain hex8.
  bool incompatible_modes = true;
  double incompatible_min_fraction = 1e-3;  ///< not on elements with a smaller volume fraction
  /// Small cut cells (the thesis is silent; cf. aggregated FEM, Badia et al. 2018): a DOF node
  /// used only by elements whose volume fraction is below this follows the trilinear field of
  /// the largest face-connected normal element (extrapolated), so conditioning stays bounded
  /// as fractions go to 0. 0 turns it off.
  double aggregation_fraction = 0.05;
};

struct LinearXfemResult {
  bool solved = false;
  std::string message;
  int dofs = 0, elements = 0, cut_elements = 0;
  Eigen::VectorXd u;                     ///< 3 per DOF node
  std::vector<std::array<int, 8>> node;  ///< per element: DOF node of each corner
  double assemble_seconds = 0, solve_seconds = 0;
  double energy = 0;                     ///< ½ uᵀKu − fᵀu at the solution
  int aggregated_nodes = 0;              ///< DOF nodes tied to a neighbour (small cut cells)
  /// Elements whose stiffness was copied from the one uncut interior cell integrated (all
  /// interior cells of a grid have the same box size and rule, hence the same matrix).
  int reused_element_matrices = 0;
  /// The factorization of the reduced stiffness TᵀKT (null if the solve failed). Shared with
  /// the LinearXfemSolver that made it: its next solve factorizes again in place.
  std::shared_ptr<const SparseCholesky> factorization;
  /// The aggregation map T (u = T u_reduced); empty (0 × 0) when nothing is aggregated (T = I).
  Eigen::SparseMatrix<double> aggregation;

  /// The displacement (every DOF node) under another load vector f (size dofs, e.g. an adjoint
  /// right-hand side) with the kept factorization: T (TᵀKT)⁻¹ Tᵀ f. Throws parafab::Error when
  /// there is no factorization or f has the wrong size.
  Eigen::VectorXd solve_again(const Eigen::VectorXd& f) const;

  /// Displacement at X inside element e (trilinear interpolation of its DOF nodes).
  Vec3 displacement(const std::vector<GridElement>& elements, int e, const Vec3& X) const;
};

/// Trilinear shape functions of the cell `box` at X (physical coordinates, not restricted to
/// the box): values N and gradients G (8×3), corners numbered as in `corner`.
void trilinear_shape(const Box3& box, const Vec3& X, Eigen::Matrix<double, 8, 1>& N,
                     Eigen::Matrix<double, 8, 3>& G);

/// Corner k of a cell box in the node order used everywhere: bit 0 → x, bit 1 → y, bit 2 → z.
Vec3 corner(const Box3& box, int k);

/// DOF-node numbering: corners of elements connected through a grid face (`adjacent` pairs of
/// element indices) share a DOF node where they share a grid node.
std::vector<std::array<int, 8>> number_dof_nodes(const std::vector<GridElement>& elements,
                                                 const std::vector<std::array<int, 2>>& adjacent,
                                                 int& count);

/// Assembled stiffness and load (no Dirichlet conditions folded in unless given). Element
/// matrices are computed in parallel (TBB) and scattered in element order: the result is
/// bit-identical for every thread count. Uncut interior cells of one size get one matrix.
struct LinearSystem {
  Eigen::SparseMatrix<double> K;
  Eigen::VectorXd f;
  int reused_element_matrices = 0;  ///< uncut elements given the one interior cell matrix
};
LinearSystem assemble_linear(const std::vector<GridElement>& elements,
                             const std::vector<std::array<int, 8>>& node, int node_count,
                             const ElasticMaterial& material,
                             const std::vector<DirichletCondition>& dirichlet,
                             const std::vector<TractionCondition>& tractions,
                             const LinearXfemOptions& options, bool include_bulk = true);

/// The map u = T u_reduced of cell aggregation (see LinearXfemOptions::aggregation_fraction):
/// identity rows for ordinary DOF nodes, extrapolation rows for floating ones.
Eigen::SparseMatrix<double> aggregation_map(const std::vector<GridElement>& elements,
                                            const std::vector<std::array<int, 2>>& adjacent,
                                            const std::vector<std::array<int, 8>>& node, int count,
                                            double fraction, int* aggregated = nullptr);

LinearXfemResult solve_linear(const std::vector<GridElement>& elements,
                              const std::vector<std::array<int, 2>>& adjacent,
                              const ElasticMaterial& material,
                              const std::vector<DirichletCondition>& dirichlet,
                              const std::vector<TractionCondition>& tractions,
                              const LinearXfemOptions& options = {});

/// solve_linear with a kept sparse Cholesky: a later solve whose reduced stiffness has the
/// same pattern (the same grid: a re-solve after a load or material change, an unchanged
/// re-cut) reuses the symbolic analysis; every result shares the factorization.
class LinearXfemSolver {
 public:
  LinearXfemSolver() : cholesky_(std::make_shared<SparseCholesky>()) {}
  LinearXfemResult solve(const std::vector<GridElement>& elements, const std::vector<std::array<int, 2>>& adjacent,
                         const ElasticMaterial& material, const std::vector<DirichletCondition>& dirichlet,
                         const std::vector<TractionCondition>& tractions, const LinearXfemOptions& options = {});
  const SparseCholesky& cholesky() const { return *cholesky_; }

 private:
  std::shared_ptr<SparseCholesky> cholesky_;
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

}  // namespace parafab::xfem
