// The parameterization constraints c_para(p) = 0 of thesis §6.5.1 (Fig. 6.11) on plain vectors:
// mid-level parameters of analytic faces (plane, cylinder, cone, sphere, torus) in one vector p,
// the tangency relations between adjacent faces in a reduced independent form, unit axes, and
// user constraints (linear ties and fixes, mirror and rotational symmetry). Every scalar constraint carries its
// exact gradient and Hessian (jet.h), as the projection (Eq. 6.25-6.26, 6.29) needs.
#pragma once

#include <Eigen/Core>
#include <functional>
#include <string>
#include <vector>

#include "optimize/jet.h"

namespace parafab::optimize {

/// The primitive of a face and the layout of its block in p:
///   plane    n.x n.y n.z d            (the plane n·X = d, n = σ_u × σ_v unit)
///   cylinder c.x c.y c.z a.x a.y a.z r (axis point c, unit axis a, radius r)
///   cone     c a r α                   (radius r at c, half-angle α, radius grows along a)
///   sphere   c r
///   torus    c a R r                   (centre c, axis a, major R, minor r)
enum class PrimitiveKind { plane, cylinder, cone, sphere, torus };

const char* to_string(PrimitiveKind kind);
int block_size(PrimitiveKind kind);
/// Parameter names inside a block: "normal x", "offset", "axis point x", "axis x", "radius", ...
const std::vector<std::string>& block_parameter_names(PrimitiveKind kind);

/// One face's parameters in p: entries offset .. offset + block_size(kind) − 1.
struct ParameterBlock {
  int face = -1;
  PrimitiveKind kind = PrimitiveKind::plane;
  int offset = 0;
  int size() const { return block_size(kind); }
};

/// A scalar constraint c(p) = 0 of a few entries of p (vars: distinct indices into p).
struct ScalarConstraint {
  std::string name;
  std::vector<int> vars;
  std::function<Jet(const std::vector<Jet>&)> f;  ///< of the jets of p[vars[k]]
};

/// The vector c(p) with a fixed sparsity structure for its Jacobian and for the Hessian of the
/// Lagrangian ½‖p − p̃‖² + λᵀc (identity on the diagonal plus Σ λ_i ∇²c_i, lower triangle).
class ConstraintSystem {
 public:
  explicit ConstraintSystem(int parameters = 0) : n_(parameters) {}
  int parameters() const { return n_; }
  int size() const { return static_cast<int>(constraints_.size()); }
  const std::vector<ScalarConstraint>& constraints() const { return constraints_; }
  /// Adds one scalar constraint; throws parafab::Error if a var is out of range or repeated.
  void add(ScalarConstraint c);

  /// c(p).
  Eigen::VectorXd values(const Eigen::VectorXd& p) const;
  /// Dense Jacobian ∂c/∂p (size() × parameters()).
  Eigen::MatrixXd jacobian(const Eigen::VectorXd& p) const;
  /// Jacobian structure: row, column of each non-zero (order of jacobian_values).
  void jacobian_structure(std::vector<int>& rows, std::vector<int>& cols) const;
  void jacobian_values(const Eigen::VectorXd& p, double* values) const;
  /// Lower-triangular structure of the Lagrangian Hessian (diagonal first, every p index).
  void hessian_structure(std::vector<int>& rows, std::vector<int>& cols) const;
  /// objective_factor·I + Σ λ_i ∇²c_i on hessian_structure, plus Σ s_i ∇c_i ∇c_iᵀ when
  /// `outer` (s, one factor per constraint) is given: the Gauss–Newton part of ½Σ s_i c_i².
  void hessian_values(const Eigen::VectorXd& p, double objective_factor, const Eigen::VectorXd& lambda,
                      double* values, const Eigen::VectorXd* outer = nullptr) const;
  /// Σ λ_i ∇²c_i, dense.
  Eigen::MatrixXd constraint_hessian(const Eigen::VectorXd& p, const Eigen::VectorXd& lambda) const;

 private:
  void build_hessian_index() const;
  int n_ = 0;
  std::vector<ScalarConstraint> constraints_;
  mutable bool hessian_index_built_ = false;
  mutable std::vector<int> hessian_rows_, hessian_cols_;
  mutable std::vector<std::vector<int>> hessian_slot_;  ///< per constraint: k*m + l -> slot (l <= k)
};

/// |a|² − 1 = 0 for the unit vector (normal or axis) of `block` (none for a sphere).
void add_unit_axis(ConstraintSystem& system, const ParameterBlock& block, const std::string& label);

/// The tangency relation `kind` (face model names: "plane-cylinder", "cylinder-cylinder", ...)
/// between blocks a and b with side `sign`, in a reduced independent form: "parallel" becomes
/// two components of a × b, those other than the largest component of a at p0 (fixed here).
/// Returns the number of scalar equations added. Throws parafab::Error for a kind it does not
/// know or blocks of the wrong primitives.
int add_tangency(ConstraintSystem& system, const std::string& kind, const ParameterBlock& a,
                 const ParameterBlock& b, int sign, const Eigen::VectorXd& p0, const std::string& label);

/// Σ coefficients[k]·p[vars[k]] = rhs (ties, fixes).
void add_linear(ConstraintSystem& system, const std::vector<int>& vars, const std::vector<double>& coefficients,
                double rhs, const std::string& label);

/// Face b is the image of face a under the isometry X ↦ Q X + t (Q orthogonal; a symmetric copy
/// in a pattern): points map (a cylinder's axis point may slide along b's axis), axes map (sign
/// chosen at p0 so that b's axis ≈ Q a's), radii and half-angles equal; for planes n_b ∥ Q n_a
/// and d_b = s(d_a + (Q n_a)·t) with the orientation sign s at p0. Blocks must be of one
/// primitive kind. Returns the number of equations added (reduced: two per parallel pair).
int add_isometric_copy(ConstraintSystem& system, const ParameterBlock& a, const ParameterBlock& b,
                       const Eigen::Matrix3d& Q, const Eigen::Vector3d& t, const Eigen::VectorXd& p0,
                       const std::string& label);

/// Face b is the mirror image of face a in the plane e·X = m (add_isometric_copy with
/// Q = I − 2eeᵀ/|e|², t = 2m e/|e|).
int add_mirror(ConstraintSystem& system, const ParameterBlock& a, const ParameterBlock& b,
               const Eigen::Vector3d& e, double m, const Eigen::VectorXd& p0, const std::string& label);

/// Face b is face a turned by `angle` (radians, right-handed) about the axis through `point`
/// along `axis` (rotational symmetry of a pattern: add_isometric_copy with Q the rotation,
/// t = point − Q point).
int add_rotation(ConstraintSystem& system, const ParameterBlock& a, const ParameterBlock& b,
                 const Eigen::Vector3d& point, const Eigen::Vector3d& axis, double angle, const Eigen::VectorXd& p0,
                 const std::string& label);

/// The implicit function φ(X; block) of a primitive whose zero set is the face's surface and
/// |∇_X φ| = 1 on it when its axis is unit (plane: n·X − d; cylinder: distance to the axis − r;
/// cone: (ρ − r − h tan α) cos α; sphere: |X − c| − r; torus: √((ρ − R)² + h²) − r).
/// Returns its value with the gradient over (block parameters, X) in that order.
Dual implicit_function(PrimitiveKind kind, const double* block, const Eigen::Vector3d& X);

/// The mean curvature (sum of the principal curvatures) of φ's zero set at X, div(∇φ/|∇φ|) =
/// (Δφ − n̂ᵀ∇²φ n̂)/|∇φ| from φ's exact spatial Hessian, for the normal along ∇φ (a cylinder of
/// radius r: 1/r, a sphere: 2/r, a plane: 0). A surface integral over the face then changes by
/// ∫ κ g Vₙ dA (plus ∂ₙg and edge terms) when the face moves by Vₙ along that normal.
double implicit_mean_curvature(PrimitiveKind kind, const double* block, const Eigen::Vector3d& X);

/// The normal speed of a face per entry of its block and that speed's spatial gradient, for the
/// normal along ∇φ: Vₙ,k = −∂φ/∂p_k / |∇φ| (the zero set moves by Vₙ,k along ∇φ/|∇φ| per unit
/// step of p_k) and ∇_X Vₙ,k from φ's exact mixed Hessian. A surface integral ∫_Γ F(X, n) dA
/// whose integrand depends on the normal changes by −∫ ∂F/∂n·∇_Γ Vₙ dA through n' = −∇_Γ Vₙ
/// (the tangential part of `gradient`); `speed` equals implicit_function's −g_k/|∇_X φ|. Where
/// ∇φ = 0 (a cylinder's axis, a sphere's centre) `speed` is empty.
struct NormalSpeed {
  Eigen::Vector3d normal;               ///< ∇φ/|∇φ|
  Eigen::VectorXd speed;                ///< Vₙ,k, k over the block
  Eigen::Matrix<double, Eigen::Dynamic, 3> gradient;  ///< row k: ∇_X Vₙ,k
};
NormalSpeed implicit_normal_speed(PrimitiveKind kind, const double* block, const Eigen::Vector3d& X);

/// The point S of a swept primitive's spine nearest X, with its gradient over the block's
/// parameters (X held): cylinder, the axis line (S = c + a a·(X − c)/|a|²); torus, the centre
/// circle (S = c + R ρ̂, ρ̂ the unit radial direction of X); sphere, the centre. Where such a face
/// runs tangent into a fixed face along a curve, that curve moves with S when the tangency is
/// kept, so its speed across the curve per parameter is ν·∂S/∂p_k (thesis Fig. 6.12, case 2, the
/// null-space completion). Throws parafab::Error for planes and cones (no spine; a cone's
/// tangent line turns about its apex) and for X on the axis of a torus.
V3<Dual> spine_point(PrimitiveKind kind, const double* block, const Eigen::Vector3d& X);

}  // namespace parafab::optimize
