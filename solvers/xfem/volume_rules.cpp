// Volume rules of thesis §6.3.3: moments ∫_V̄ φ_i = ∮ F_i · n̄ dĀ with F_i = ⅓(∫φ_i dξ, ∫φ_i dη,
// ∫φ_i dζ) and the box scaling S carried by the area vectors (Eq. 6.16), then Eq. 6.11.
#include "xfem/volume_rules.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>

#include "common/error.h"

namespace parafab::xfem {

VolumeRule volume_rule(const Subvolume& sv, const VolumeRuleOptions& o) {
  PARAFAB_VERIFY((sv.cell.max.array() > sv.cell.min.array()).all(),
                 "Subvolume.cell is empty: min " << sv.cell.min.transpose() << ", max "
                                                 << sv.cell.max.transpose());
  PARAFAB_VERIFY(!sv.patches.empty(), "Subvolume has no boundary patches");
  PARAFAB_VERIFY(o.flux_tolerance >= 0 && o.residual_tolerance >= 0,
                 "VolumeRuleOptions: flux_tolerance "
                     << o.flux_tolerance << " and residual_tolerance " << o.residual_tolerance
                     << " must be ≥ 0");
  const FittingSystem& system = cube_fitting_system(o.degree, o.points_per_direction);
  std::vector<std::vector<UvLoop>> loops;
  for (size_t k = 0; k < sv.patches.size(); ++k) {
    const CutPatch& patch = sv.patches[k];
    PARAFAB_VERIFY(patch.surface, "Subvolume.patches[" << k << "] has no surface");
    PARAFAB_VERIFY(
        patch.orientation == 1 || patch.orientation == -1,
        "Subvolume.patches[" << k << "].orientation must be ±1, got " << patch.orientation);
    loops.push_back(to_uv_loops(patch.loops));
  }

  VolumeRule r;
  r.box = sv.cell;
  Vec3 X, Xu, Xv;
  if (o.box == FittingBox::Tight) {
    constexpr double inf = std::numeric_limits<double>::infinity();
    Vec3 lo(inf, inf, inf), hi(-inf, -inf, -inf);
    auto extend = [&](const SurfaceMap& s, const Vec2& uv) {
      s.evaluate(uv.x(), uv.y(), X, Xu, Xv);
      lo = lo.cwiseMin(X);
      hi = hi.cwiseMax(X);
    };
    // The patch rules' points are the tensor Gauss points of the patches' uv boxes.
    const int q = area_points_per_direction(o.patch);
    for (size_t k = 0; k < sv.patches.size(); ++k) {
      const SurfaceMap& s = *sv.patches[k].surface;
      Vec2 uv_lo(inf, inf), uv_hi(-inf, -inf);
      for (const UvLoop& loop : loops[k])
        for (const CurveSegment2& seg : loop) {
          extend_bounding_box(seg, uv_lo, uv_hi);
          for (const Vec2& uv : {seg.start, seg.mid}) extend(s, uv);
        }
      if ((uv_hi.array() >= uv_lo.array()).all())
        for (const Vec2& uv : tensor_gauss_rule(uv_lo, uv_hi, q).points) extend(s, uv);
    }
    r.box.min = lo.cwiseMax(sv.cell.min);
    r.box.max = hi.cwiseMin(sv.cell.max);
  }
  const Vec3 S = r.box.size();
  if (!(S.minCoeff() > 1e-12 * sv.cell.size().maxCoeff())) {
    r.status = RuleStatus::EmptyDomain;
    return r;
  }

  // Flux of F_i through one patch in unit-cube coordinates ξ = S⁻¹(X − min): the area vector
  // maps as dĀ = det(S⁻¹) S dA (Eq. 6.16). Entries m..m+2 accumulate dĀ (closure check).
  const int m = static_cast<int>(system.exponents.size());
  const int nl = o.degree + 1;
  const double third = 1.0 / 3;
  const Vec3 area_scale(1 / (S.y() * S.z()), 1 / (S.x() * S.z()), 1 / (S.x() * S.y()));
  auto flux = [&](const CutPatch& patch) -> UvIntegral {
    return [&, surface = patch.surface.get(),
            sign = static_cast<double>(patch.orientation)](const QuadratureRule2& q) {
      Eigen::VectorXd v = Eigen::VectorXd::Zero(m + 3);
      Eigen::MatrixXd L(nl, 3), I(nl, 3);
      Vec3 Y, Yu, Yv;
      for (size_t j = 0; j < q.points.size(); ++j) {
        surface->evaluate(q.points[j].x(), q.points[j].y(), Y, Yu, Yv);
        const Vec3 dA = (sign * q.weights[j]) * Yu.cross(Yv).cwiseProduct(area_scale);
        const Vec3 xi = (Y - r.box.min).cwiseQuotient(S);
        for (int d = 0; d < 3; ++d) legendre_basis(xi[d], nl, &L(0, d), &I(0, d));
        for (int i = 0; i < m; ++i) {
          const auto& e = system.exponents[i];
          const double lx = L(e[0], 0), ly = L(e[1], 1), lz = L(e[2], 2);
          v[i] += third * (I(e[0], 0) * ly * lz * dA.x() + lx * I(e[1], 1) * lz * dA.y() +
                           lx * ly * I(e[2], 2) * dA.z());
        }
        v.tail<3>() += dA;
      }
      return v;
    };
  };
  const RefinementOptions refinement{o.flux_tolerance, false, o.max_depth};
  Eigen::VectorXd total = Eigen::VectorXd::Zero(m + 3);
  RuleStatus patch_status = RuleStatus::Ok;
  for (size_t k = 0; k < sv.patches.size(); ++k) {
    const RefinedAreaRule f = refined_area_rule(loops[k], o.patch, refinement, flux(sv.patches[k]));
    if (f.status == RuleStatus::EmptyDomain) continue;
    total += f.integral;
    r.flux_error_estimate += f.error_estimate;
    r.flux_leaves += f.leaves;
    r.flux_depth = std::max(r.flux_depth, f.depth);
    patch_status = worse_status(patch_status, f.status);
  }
  const Eigen::VectorXd b = total.head(m);
  r.closure_defect = total.tail<3>().cwiseAbs().maxCoeff();
  if (std::abs(b[0]) <= 64 * std::numeric_limits<double>::epsilon()) {
    r.status = RuleStatus::EmptyDomain;
    return r;
  }

  const WeightFitResult fit = fit_weights(system, b, o.fit);
  const double det = S.prod();
  r.volume = b[0] * det;
  r.moment_residual = fit.residual;
  const int n = static_cast<int>(fit.weights.size());
  r.rule.points.reserve(n);
  r.rule.weights.reserve(n);
  for (int j = 0; j < n; ++j) {
    r.rule.points.push_back(r.box.min + S.cwiseProduct(system.points.col(j)));
    r.rule.weights.push_back(fit.weights[j] * det);
  }
  r.status = patch_status;
  if (b[0] < 0) r.status = RuleStatus::NegativeMeasure;
  if (!(fit.residual <= o.residual_tolerance))
    r.status = worse_status(r.status, RuleStatus::ResidualAboveTolerance);
  return r;
}

}  // namespace parafab::xfem
