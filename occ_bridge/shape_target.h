// Target-shape objective of shape optimization (thesis §6.2.3, objective type three, Eq. 6.6:
// f(x(p)) = g(x), "the rest shape ... optimized such that the deformed model matches a target
// shape under a predefined load"): the mean squared distance of one face's deformed points
// x = X + u(X) from a target surface,
//   J = (1/A) ∫_F d(X + u_h(X))² dA,
// d the signed distance from a plane, sphere, cylinder or torus (closed forms), A the face's
// area, integrated by the surface rules of the face's cut patches on the fixed grid of the
// linear XFEM solve (shape_compliance.h: same job). u_h is the nodal field (hex8 incompatible
// modes are element-internal and not part of it). The equilibrium is linear, or hyperelastic
// (ComplianceSetup::hyperelastic: Newton, large deflections; the thesis's lampshade ran a
// Mooney–Rivlin model). Gradient as the failure metric's (shape_failure.h): adjoint
// K λ = −∂J/∂u with the kept factorization (hyperelastic: the tangent H(u) at the solution), then
// dJ/ds = ∂J/∂s|_u + λᵀ ∂R/∂s|_u, R = K u − f (hyperelastic: the internal force plus the boundary
// terms minus the loads): by central differences over the re-cut cells only (target_derivative),
// or, linear, exactly by boundary integrals (target_gradient: §6.5.3's Eq. 6.30 with the face's
// own motion and its edges' slide, thesis Fig. 6.12's null-space completion at fillets).
#pragma once

#include <Eigen/Core>
#include <memory>
#include <string>

#include "face_model.h"
#include "shape_compliance.h"

namespace parafab::occ {

/// A fixed surface in space with a closed-form signed distance d(x):
///  plane:    d = n·(x − p)                 (n = axis, unit)
///  sphere:   d = |x − c| − r               (c = point)
///  cylinder: d = |(x − p)⊥| − r            (⊥: the part normal to the unit axis through p)
///  torus:    d = |(|(x − c)⊥| − R, (x − c)·a)| − r   (R = major_radius, r = radius)
struct TargetSurface {
  SurfaceType type = SurfaceType::plane;
  Vec3 point = Vec3::Zero();
  Vec3 axis = Vec3::UnitZ();
  double radius = 0, major_radius = 0;
};

/// d(x) and, if asked, ∇d (a unit vector wherever d is differentiable). Throws parafab::Error on
/// the axis of a cylinder or torus, at a sphere's centre (no direction there).
double signed_distance(const TargetSurface& target, const Vec3& x, Vec3* gradient = nullptr);

/// The surface of face `face` of `model` as read (plane, cylinder, sphere or torus): "keep this
/// face where the CAD model puts it, under the load". Throws parafab::Error naming the face and
/// its surface type for other types (a cone, a B-spline: give the target explicitly).
TargetSurface target_of_face(const FaceModel& model, int face);

/// Throws parafab::Error naming the field when the target is not a usable surface (zero axis,
/// non-positive radius, a torus with r ≥ R).
void check_target_surface(const TargetSurface& target, const std::string& path = "objective.target");

struct TargetOptions {
  int face = -1;          ///< the matched face (face model index; the write-back keeps indices)
  TargetSurface target;
};

struct TargetValue {
  bool done = false;
  std::string message;
  double objective = 0;      ///< J = I / A [length²]
  double integral = 0;       ///< I = ∫_F d² dA
  double area = 0;           ///< A = Σ surface rule weights of the face's patches
  double max_distance = 0;   ///< max |d| over the face's surface rule points
  int points = 0;            ///< surface rule points on the face
  Eigen::VectorXd gradient_u;  ///< ∂J/∂u (3 per DOF node); empty unless asked for
};

/// J of a solved state (and ∂J/∂u when with_gradient). Not done (message says why) when the
/// face has no cut patch on the grid.
TargetValue target_value(const ComplianceState& state, const ComplianceSetup& setup, const TargetOptions& options,
                         bool with_gradient = false);

/// λ = −K⁻¹ ∂J/∂u (value must carry gradient_u).
Eigen::VectorXd target_adjoint(const ComplianceState& state, const TargetValue& value);

/// dJ/ds along a perturbation (models plus at s = +h, minus at s = −h, either may be null):
/// Σ changed elements w·[λₑᵀ(Kₑuₑ − fₑ) + Iₑ(uₑ)/A − (I/A²)Aₑ], the face's patches of each
/// changed cell integrated again on the perturbed model with `state`'s nodal values.
ComplianceDerivative target_derivative(const ComplianceState& state, const TargetValue& value,
                                       const Eigen::VectorXd& adjoint, std::shared_ptr<const PartShape> plus,
                                       std::shared_ptr<const PartShape> minus, double h,
                                       const ComplianceSetup& setup, const TargetOptions& options);

/// The exact route of dJ/dp (linear elasticity only; adjoint_shape_gradient with λ above and
/// J's surface density g = (d(X + u_h)² − J)/A on the face, ∇g = 2d(I + ∇u_h)ᵀ∇d/A): every entry
/// at once, no re-cut, the same `incomplete` flags plus the face's own entries where
/// adjoint_shape_gradient cannot slide its edges (a B-spline face, a neighbour without a block,
/// a tangent neighbour other than a fillet into a plane). `adjoint` empty: solved here.
ComplianceGradient target_gradient(const ComplianceState& state, const TargetValue& value, const Eigen::VectorXd& adjoint,
                                   const ComplianceSetup& setup, const TargetOptions& options,
                                   const ShapeParameters& parameters, const Eigen::VectorXd& p,
                                   const std::vector<char>* moving = nullptr);

}  // namespace parafab::occ
