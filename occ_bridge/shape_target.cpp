// Target-shape objective (thesis §6.2.3 Eq. 6.6) and its adjoint shape derivative; see
// shape_target.h.
#include "shape_target.h"

#include <tbb/parallel_for.h>

#include <cmath>

#include "common/error.h"
#include "xfem/area_rules.h"

namespace parafab::occ {

namespace {

// Interpolation functions of an element with n (8 or 27) nodes at X.
Eigen::VectorXd shape_values(const xfem::Box3& box, int n, const xfem::Vec3& X) {
  if (n == 8) {
    Eigen::Matrix<double, 8, 1> N;
    Eigen::Matrix<double, 8, 3> G;
    xfem::trilinear_shape(box, X, N, G);
    return N;
  }
  Eigen::Matrix<double, 27, 1> N;
  Eigen::Matrix<double, 27, 3> G;
  xfem::triquadratic_shape(box, X, N, G);
  return N;
}

// The integrand d² is of degree 2 in u_h (degree 1 per coordinate for hex8, 2 for hex27) times
// the patch's own curvature: the rules of the solver's traction terms, one degree higher. No
// adaptive refinement: the rule must vary smoothly with the patch (a refinement switch would be
// a jump in J along a line search).
xfem::SurfaceRuleOptions rule_options(const ComplianceSetup& setup) {
  xfem::SurfaceRuleOptions so;
  so.area.degree = setup.solver.element == xfem::ElementType::Hex27 ? std::max(setup.solver.surface_degree, 8) + 1
                                                                    : setup.solver.surface_degree + 1;
  return so;
}

struct ElementTarget {
  double integral = 0, area = 0, max_distance = 0;
  int points = 0;
  Eigen::VectorXd gradient;  ///< ∂I_e/∂u_e (if asked)
};

// I_e = Σ_q w_q d(X_q + u_h(X_q))² over the element's patches on the matched face.
ElementTarget element_target(const xfem::GridElement& el, const Eigen::VectorXd& ue, const TargetOptions& o,
                             const xfem::SurfaceRuleOptions& so, bool with_gradient) {
  ElementTarget r;
  if (with_gradient) r.gradient = Eigen::VectorXd::Zero(ue.size());
  if (!el.subvolume) return r;
  const int n = static_cast<int>(ue.size() / 3);
  for (const xfem::CutPatch& patch : el.subvolume->patches) {
    if (patch.source_face != o.face) continue;
    const xfem::SurfaceRule sr = xfem::surface_rule(patch, so);
    for (size_t q = 0; q < sr.points.size(); ++q) {
      const Eigen::VectorXd N = shape_values(el.box, n, sr.points[q]);
      Vec3 u = Vec3::Zero();
      for (int a = 0; a < n; ++a) u += N[a] * ue.segment<3>(3 * a);
      Vec3 grad;
      const double d = signed_distance(o.target, sr.points[q] + u, with_gradient ? &grad : nullptr);
      const double w = sr.weights[q];
      r.integral += w * d * d;
      r.area += w;
      r.max_distance = std::max(r.max_distance, std::abs(d));
      ++r.points;
      if (with_gradient)
        for (int a = 0; a < n; ++a) r.gradient.segment<3>(3 * a) += (2 * w * d * N[a]) * grad;
    }
  }
  return r;
}

Vec3 unit(const Vec3& v, const char* what) {
  const double n = v.norm();
  PARAFAB_VERIFY(n > 0 && std::isfinite(n), "target surface: the " << what << " is zero or not finite");
  return v / n;
}

}  // namespace

double signed_distance(const TargetSurface& t, const Vec3& x, Vec3* gradient) {
  const Vec3 w = x - t.point;
  switch (t.type) {
    case SurfaceType::plane: {
      const Vec3 n = unit(t.axis, "plane normal");
      if (gradient) *gradient = n;
      return n.dot(w);
    }
    case SurfaceType::sphere: {
      const double r = w.norm();
      PARAFAB_VERIFY(r > 0, "target sphere: a point lies at its centre (" << x.transpose() << ")");
      if (gradient) *gradient = w / r;
      return r - t.radius;
    }
    case SurfaceType::cylinder: {
      const Vec3 a = unit(t.axis, "cylinder axis");
      const Vec3 perp = w - w.dot(a) * a;
      const double r = perp.norm();
      PARAFAB_VERIFY(r > 0, "target cylinder: a point lies on its axis (" << x.transpose() << ")");
      if (gradient) *gradient = perp / r;
      return r - t.radius;
    }
    case SurfaceType::torus: {
      const Vec3 a = unit(t.axis, "torus axis");
      const double z = w.dot(a);
      const Vec3 perp = w - z * a;
      const double rho = perp.norm();
      PARAFAB_VERIFY(rho > 0, "target torus: a point lies on its axis (" << x.transpose() << ")");
      const double s = rho - t.major_radius, r = std::hypot(s, z);
      PARAFAB_VERIFY(r > 0, "target torus: a point lies on its spine circle (" << x.transpose() << ")");
      if (gradient) *gradient = (s / r) * (perp / rho) + (z / r) * a;
      return r - t.radius;
    }
    default:
      PARAFAB_INPUT_ERROR("target surface: only a plane, sphere, cylinder or torus has a closed-form distance");
  }
}

TargetSurface target_of_face(const FaceModel& model, int face) {
  PARAFAB_VERIFY(face >= 0 && face < static_cast<int>(model.faces.size()),
                 "target face " << face << " outside 0.." << model.faces.size() - 1);
  const Primitive& p = model.faces[face].primitive;
  TargetSurface t;
  t.type = p.type;
  t.point = p.location;
  t.axis = p.axis;
  t.radius = p.radius;
  t.major_radius = p.major_radius;
  if (p.type != SurfaceType::plane && p.type != SurfaceType::sphere && p.type != SurfaceType::cylinder &&
      p.type != SurfaceType::torus)
    PARAFAB_INPUT_ERROR("objective.target: face " << face << " is a " << to_string(p.type)
                                                  << "; its own surface is a target only for planes, spheres, "
                                                     "cylinders and tori (give \"target\": {\"plane\" | \"sphere\" | "
                                                     "\"cylinder\" | \"torus\": ...})");
  return t;
}

void check_target_surface(const TargetSurface& t, const std::string& path) {
  const bool axial = t.type != SurfaceType::sphere;
  if (axial && !(t.axis.norm() > 1e-12 && t.axis.allFinite()))
    PARAFAB_INPUT_ERROR(path << ": the " << (t.type == SurfaceType::plane ? "normal" : "axis") << " is zero or not finite");
  if (!t.point.allFinite()) PARAFAB_INPUT_ERROR(path << ": the point is not finite");
  if (t.type != SurfaceType::plane && !(t.radius > 0 && std::isfinite(t.radius)))
    PARAFAB_INPUT_ERROR(path << ": radius must be positive, got " << t.radius);
  if (t.type == SurfaceType::torus && !(t.major_radius > t.radius && std::isfinite(t.major_radius)))
    PARAFAB_INPUT_ERROR(path << ": major_radius must exceed radius (" << t.radius << "), got " << t.major_radius);
  if (t.type != SurfaceType::plane && t.type != SurfaceType::sphere && t.type != SurfaceType::cylinder &&
      t.type != SurfaceType::torus)
    PARAFAB_INPUT_ERROR(path << ": a target is a plane, sphere, cylinder or torus");
}

TargetValue target_value(const ComplianceState& state, const ComplianceSetup& setup, const TargetOptions& o,
                         bool with_gradient) {
  check_target_surface(o.target);
  TargetValue v;
  if (!state.done || !state.model) {
    v.message = "the elasticity state is not solved: " + state.message;
    return v;
  }
  const auto& elements = state.model->elements;
  const xfem::SurfaceRuleOptions so = rule_options(setup);
  std::vector<ElementTarget> per(elements.size());
  try {
    tbb::parallel_for(size_t(0), elements.size(), [&](size_t e) {
      per[e] = element_target(elements[e], element_values(state.solution.u, state.solution.node[e]), o, so, with_gradient);
    });
  } catch (const Error& e) {
    v.message = e.what();
    return v;
  }
  for (const ElementTarget& r : per) {  // element order: deterministic
    v.integral += r.integral;
    v.area += r.area;
    v.points += r.points;
    v.max_distance = std::max(v.max_distance, r.max_distance);
  }
  if (!(v.area > 0)) {
    v.message = "face " + std::to_string(o.face) + " has no cut patch on the grid (area " + std::to_string(v.area) + ")";
    return v;
  }
  v.objective = v.integral / v.area;
  if (with_gradient) {
    v.gradient_u = Eigen::VectorXd::Zero(state.solution.u.size());
    for (size_t e = 0; e < elements.size(); ++e) {
      if (per[e].points == 0) continue;
      const std::vector<int>& nodes = state.solution.node[e];
      for (size_t a = 0; a < nodes.size(); ++a)
        v.gradient_u.segment<3>(3 * nodes[a]) += per[e].gradient.segment<3>(3 * a) / v.area;
    }
  }
  v.done = true;
  v.message = "ok";
  return v;
}

Eigen::VectorXd target_adjoint(const ComplianceState& state, const TargetValue& value) {
  PARAFAB_VERIFY(value.done, "target_adjoint: the value is not computed");
  return adjoint_of(state, value.gradient_u, "target_adjoint");
}

ComplianceDerivative target_derivative(const ComplianceState& state, const TargetValue& value,
                                       const Eigen::VectorXd& adjoint, std::shared_ptr<const PartShape> plus,
                                       std::shared_ptr<const PartShape> minus, double h,
                                       const ComplianceSetup& setup, const TargetOptions& o) {
  PARAFAB_VERIFY(value.done, "target_derivative: the value is not computed");
  const Eigen::VectorXd lambda = adjoint.size() ? adjoint : target_adjoint(state, value);
  PARAFAB_VERIFY(lambda.size() == state.solution.u.size(),
                 "target_derivative: adjoint of size " << lambda.size() << ", expected " << state.solution.u.size());
  const xfem::SurfaceRuleOptions so = rule_options(setup);
  const double A = value.area, I = value.integral;
  return element_difference(
      state, std::move(plus), std::move(minus), h, setup,
      [&](const xfem::GridElement& el, const std::vector<xfem::TractionCondition>& tractions, int base) {
        const std::vector<int>& nodes = state.solution.node[base];
        const Eigen::VectorXd ue = element_values(state.solution.u, nodes), le = element_values(lambda, nodes);
        const ElementTarget et = element_target(el, ue, o, so, false);
        return le.dot(element_residual(el, tractions, ue, setup)) + et.integral / A - I / (A * A) * et.area;
      });
}

ComplianceGradient target_gradient(const ComplianceState& state, const TargetValue& value, const Eigen::VectorXd& adjoint,
                                   const ComplianceSetup& setup, const TargetOptions& o, const ShapeParameters& sp,
                                   const Eigen::VectorXd& p, const std::vector<char>* moving) {
  PARAFAB_VERIFY(value.done, "target_gradient: the value is not computed");
  ShapeAdjoint a;
  a.lambda = adjoint.size() ? adjoint : target_adjoint(state, value);
  a.surface_face = o.face;
  const double A = value.area, J = value.objective;
  // J = I/A: dJ = (dI − J dA)/A, so g = (d² − J)/A; with u_h frozen, ∇_X[d(X + u_h(X))²] =
  // 2d (I + ∇u_h)ᵀ ∇d.
  a.surface_density = [&](int e, const std::vector<xfem::Vec3>& points, std::vector<double>& g,
                          std::vector<xfem::Vec3>& dg) {
    const xfem::GridElement& el = state.model->elements[e];
    const Eigen::VectorXd ue = element_values(state.solution.u, state.solution.node[e]);
    const int n = static_cast<int>(ue.size() / 3);
    g.assign(points.size(), 0.0);
    dg.assign(points.size(), xfem::Vec3::Zero());
    Eigen::Matrix<double, 27, 1> N27;
    Eigen::Matrix<double, 27, 3> G27;
    Eigen::Matrix<double, 8, 1> N8;
    Eigen::Matrix<double, 8, 3> G8;
    for (size_t q = 0; q < points.size(); ++q) {
      Vec3 u = Vec3::Zero();
      Eigen::Matrix3d F = Eigen::Matrix3d::Identity();  // I + ∇u_h, F_ij = δ_ij + ∂u_i/∂X_j
      if (n == 8) xfem::trilinear_shape(el.box, points[q], N8, G8);
      else xfem::triquadratic_shape(el.box, points[q], N27, G27);
      for (int k = 0; k < n; ++k) {
        const Vec3 uk = ue.segment<3>(3 * k);
        const Eigen::RowVector3d gk = n == 8 ? Eigen::RowVector3d(G8.row(k)) : Eigen::RowVector3d(G27.row(k));
        u += (n == 8 ? N8(k) : N27(k)) * uk;
        F += uk * gk;
      }
      Vec3 grad;
      const double d = signed_distance(o.target, points[q] + u, &grad);
      g[q] = (d * d - J) / A;
      dg[q] = (2 * d / A) * (F.transpose() * grad);
    }
  };
  return adjoint_shape_gradient(state, setup, sp, p, a, moving);
}

}  // namespace parafab::occ
