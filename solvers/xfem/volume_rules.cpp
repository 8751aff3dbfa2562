// Volume rules of thesis §6.3.3: moments ∫_V̄ φ_i = ∮ F_i · n̄ dĀ with F_i = ⅓(∫φ_i dξ, ∫φ_i dη,
// ∫φ_i dζ) and the box scaling S carried by the area vectors (Eq. 6.16), then Eq. 6.11.
#include "xfem/volume_rules.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
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
  const FittingSystem& system = cube_fitting_system(o.degree, o.points_per_direction, o.max_exponent);
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
  const int nl = (o.max_exponent >= 0 ? std::min(o.degree, o.max_exponent) : o.degree) + 1;
  const double third = 1.0 / 3;
  const Vec3 area_scale(1 / (S.y() * S.z()), 1 / (S.x() * S.z()), 1 / (S.x() * S.y()));
  // Basis i = (a, b, c): the flux integrand at point j is
  //   ⅓(I_a L_b L_c dA_x + L_a I_b L_c dA_y + L_a L_b I_c dA_z)
  //   = ⅓(U_ab L_c + V_ab I_c dA_z),  U_ab = I_a dA_x L_b + L_a I_b dA_y,  V_ab = L_a L_b,
  // evaluated for all points at once (rows of length n), surfaces evaluated once per point.
  std::vector<int> pair_of(m);  // index of (a, b) among the pairs of the basis
  std::vector<std::array<int, 2>> pairs;
  for (int i = 0; i < m; ++i) {
    const auto& e = system.exponents[i];
    auto it = std::find(pairs.begin(), pairs.end(), std::array<int, 2>{e[0], e[1]});
    pair_of[i] = static_cast<int>(it - pairs.begin());
    if (it == pairs.end()) pairs.push_back({e[0], e[1]});
  }
  const int np = static_cast<int>(pairs.size());
  auto flux = [&](const CutPatch& patch) -> UvIntegral {
    return [&, surface = patch.surface.get(),
            sign = static_cast<double>(patch.orientation)](const QuadratureRule2& q) {
      Eigen::VectorXd v = Eigen::VectorXd::Zero(m + 3);
      const int n = static_cast<int>(q.points.size());
      if (n == 0) return v;
      using Rows = Eigen::Array<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
      thread_local Rows xi, dA, L, I, U, V;
      thread_local std::vector<double> work;
      xi.resize(3, n);
      dA.resize(3, n);
      L.resize(3 * nl, n);
      I.resize(3 * nl, n);
      U.resize(np, n);
      V.resize(np, n);
      work.resize(3 * static_cast<size_t>(n));
      Vec3 Y, Yu, Yv;
      for (int j = 0; j < n; ++j) {
        surface->evaluate(q.points[j].x(), q.points[j].y(), Y, Yu, Yv);
        const Vec3 a = (sign * q.weights[j]) * Yu.cross(Yv).cwiseProduct(area_scale);
        const Vec3 x = (Y - r.box.min).cwiseQuotient(S);
        for (int d = 0; d < 3; ++d) {
          dA(d, j) = a[d];
          xi(d, j) = x[d];
        }
      }
      for (int d = 0; d < 3; ++d) {
        legendre_basis_rows(&xi(d, 0), n, n, nl, &L(d * nl, 0), &I(d * nl, 0), work.data());
        I.middleRows(d * nl, nl).rowwise() *= dA.row(d);  // I_k dA_d
      }
      for (int k = 0; k < np; ++k) {
        const int a = pairs[k][0], b = pairs[k][1];
        U.row(k) = I.row(a) * L.row(nl + b) + L.row(a) * I.row(nl + b);
        V.row(k) = L.row(a) * L.row(nl + b);
      }
      for (int i = 0; i < m; ++i) {
        const int k = pair_of[i], c = system.exponents[i][2];
        v[i] = third * (U.row(k) * L.row(2 * nl + c) + V.row(k) * I.row(2 * nl + c)).sum();
      }
      v.tail<3>() = dA.rowwise().sum().matrix();
      return v;
    };
  };
  const RefinementOptions refinement{o.flux_tolerance, false, o.max_depth, o.flux_degree_boost};
  Eigen::VectorXd total = Eigen::VectorXd::Zero(m + 3);
  RuleStatus patch_status = RuleStatus::Ok;
  for (size_t k = 0; k < sv.patches.size(); ++k) {
    const RefinedAreaRule f = refined_area_rule(loops[k], o.patch, refinement, flux(sv.patches[k]));
    if (f.status == RuleStatus::EmptyDomain) continue;
    total += f.integral;
    r.flux_error_estimate += f.error_estimate;
    r.flux_leaves += f.leaves;
    r.flux_depth = std::max(r.flux_depth, f.depth);
    r.flux_capped_leaves += f.capped_leaves;
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
