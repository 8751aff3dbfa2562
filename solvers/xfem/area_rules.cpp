// Area rules by moment fitting (thesis §6.3.2, Eq. 6.9–6.14), surface rules (Eq. 6.15), and
// their quadrant refinement with loops clipped to the quadrants.
#include "xfem/area_rules.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>

#include "common/error.h"

namespace parafab::xfem {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
// |measure| / (bounding-box measure) at or below this is round-off: the region is empty.
constexpr double kEmptyFraction = 64 * std::numeric_limits<double>::epsilon();

CurveSegment2 chord(const Vec2& a, const Vec2& b) { return {a, 0.5 * (a + b), b, 1}; }

CurveSegment2 sub_segment(const CurveSegment2& s, double ta, double tb) {
  CurveSegment2 r = s;
  r.start = ta == 0 ? s.start : s.position(ta);
  r.end = tb == 1 ? s.end : s.position(tb);
  r.mid = s.order == 2 ? s.position(0.5 * (ta + tb)) : 0.5 * (r.start + r.end);
  return r;
}

// Parameters t ∈ (0, 1) where coordinate `axis` of the segment equals c, ascending.
std::vector<double> crossings(const CurveSegment2& s, int axis, double c) {
  const double c0 = s.start[axis] - c;
  const double c1 = s.order == 2 ? -3 * s.start[axis] + 4 * s.mid[axis] - s.end[axis]
                                 : s.end[axis] - s.start[axis];
  const double c2 = s.order == 2 ? 2 * s.start[axis] - 4 * s.mid[axis] + 2 * s.end[axis] : 0;
  std::vector<double> t;
  if (c2 == 0) {
    if (c1 != 0) t.push_back(-c0 / c1);
  } else {
    const double disc = c1 * c1 - 4 * c2 * c0;
    if (disc >= 0) {
      const double q = -0.5 * (c1 + std::copysign(std::sqrt(disc), c1));
      t.push_back(q / c2);
      if (q != 0) t.push_back(c0 / q);
    }
  }
  constexpr double margin = 1e-12;
  t.erase(
      std::remove_if(t.begin(), t.end(), [](double x) { return !(x > margin && x < 1 - margin); }),
      t.end());
  std::sort(t.begin(), t.end());
  return t;
}

// Sutherland–Hodgman step: the part of a closed loop where side·(x[axis] − c) ≤ 0.
UvLoop clip_half_plane(const UvLoop& loop, int axis, double c, double side) {
  struct Piece {
    CurveSegment2 segment;
    bool inside;
  };
  std::vector<Piece> pieces;
  for (const CurveSegment2& s : loop) {
    double ta = 0;
    std::vector<double> cuts = crossings(s, axis, c);
    cuts.push_back(1);
    for (double tb : cuts) {
      const CurveSegment2 piece = sub_segment(s, ta, tb);
      pieces.push_back({piece, side * (piece.position(0.5)[axis] - c) <= 0});
      ta = tb;
    }
  }
  const auto inside_count =
      std::count_if(pieces.begin(), pieces.end(), [](const Piece& p) { return p.inside; });
  if (inside_count == static_cast<long>(pieces.size())) return loop;
  if (inside_count == 0) return {};
  // Start at an entry (inside piece after an outside one); replace each outside run by a chord.
  const int n = static_cast<int>(pieces.size());
  int first = 0;
  while (!(pieces[first].inside && !pieces[(first + n - 1) % n].inside)) ++first;
  UvLoop out;
  bool outside = false;
  for (int k = 0; k < n; ++k) {
    const Piece& p = pieces[(first + k) % n];
    if (!p.inside) {
      outside = true;
      continue;
    }
    if (outside) out.push_back(chord(out.back().end, p.segment.start));
    outside = false;
    out.push_back(p.segment);
  }
  if (outside) out.push_back(chord(out.back().end, out.front().start));
  return out;
}

void check_refinement(const RefinementOptions& o) {
  PARAFAB_VERIFY(o.tolerance >= 0 && o.max_depth >= 0, "RefinementOptions: tolerance "
                                                           << o.tolerance << " and max_depth "
                                                           << o.max_depth << " must be ≥ 0");
}

}  // namespace

std::vector<UvLoop> clip_loops(const std::vector<UvLoop>& loops, const Vec2& lo, const Vec2& hi) {
  std::vector<UvLoop> out;
  for (UvLoop loop : loops) {
    for (int axis = 0; axis < 2 && !loop.empty(); ++axis) {
      if (std::isfinite(lo[axis])) loop = clip_half_plane(loop, axis, lo[axis], -1);
      if (!loop.empty() && std::isfinite(hi[axis])) loop = clip_half_plane(loop, axis, hi[axis], 1);
    }
    if (!loop.empty()) out.push_back(std::move(loop));
  }
  return out;
}

int area_points_per_direction(const AreaRuleOptions& o) {
  return o.points_per_direction > 0 ? o.points_per_direction : o.degree + 2 - o.degree % 2;
}

AreaRule area_rule(const std::vector<BoundaryLoop>& loops, const AreaRuleOptions& options) {
  return area_rule(to_uv_loops(loops), options);
}

AreaRule area_rule(const std::vector<UvLoop>& loops, const AreaRuleOptions& o) {
  PARAFAB_VERIFY(o.degree >= 0 && o.points_per_direction >= 0 && o.residual_tolerance >= 0,
                 "AreaRuleOptions: degree " << o.degree << ", points_per_direction "
                                            << o.points_per_direction << ", residual_tolerance "
                                            << o.residual_tolerance);
  const int p = o.degree;
  const FittingSystem& system = square_fitting_system(p, area_points_per_direction(o));
  AreaRule r;
  Vec2 lo(kInf, kInf), hi(-kInf, -kInf);
  for (const UvLoop& loop : loops)
    for (const CurveSegment2& s : loop) extend_bounding_box(s, lo, hi);
  const Vec2 size = hi - lo;
  if (!(size.minCoeff() > 1e-14 * size.maxCoeff())) {  // no loops, or a degenerate box
    r.status = RuleStatus::EmptyDomain;
    return r;
  }
  r.box_min = lo;
  r.box_max = hi;

  // Moments over the unit square (Eq. 6.12–6.13): b_i = ∮ n·P_i ds with
  // P_i = ½(I_a(ξ) L_b(η), L_a(ξ) I_b(η)) for the basis L_a(ξ) L_b(η).
  std::vector<CurveSegment2> unit;
  for (const UvLoop& loop : loops)
    for (CurveSegment2 s : loop) {
      for (Vec2* x : {&s.start, &s.mid, &s.end}) *x = (*x - lo).cwiseQuotient(size);
      unit.push_back(s);
    }
  CurveRuleOptions curve;
  curve.polynomial_degree = 2 * p + 1;
  const CurveRule2 c = curve_rule(unit, curve);
  const int m = p + 1;
  Eigen::MatrixXd B = Eigen::MatrixXd::Zero(m, m);
  std::vector<double> Lx(m), Ix(m), Ly(m), Iy(m);
  for (size_t j = 0; j < c.points.size(); ++j) {
    legendre_basis(c.points[j].x(), m, Lx.data(), Ix.data());
    legendre_basis(c.points[j].y(), m, Ly.data(), Iy.data());
    const double hy = 0.5 * c.dx[j].y(), hx = 0.5 * c.dx[j].x();
    for (int bb = 0; bb < m; ++bb)
      for (int a = 0; a < m; ++a) B(a, bb) += hy * Ix[a] * Ly[bb] - hx * Lx[a] * Iy[bb];
  }
  Eigen::VectorXd b(system.exponents.size());
  for (size_t i = 0; i < system.exponents.size(); ++i)
    b[i] = B(system.exponents[i][0], system.exponents[i][1]);

  if (std::abs(b[0]) <= kEmptyFraction) {
    r.status = RuleStatus::EmptyDomain;
    return r;
  }
  const WeightFitResult fit = fit_weights(system, b, o.fit);
  r.measure = b[0] * size.prod();
  r.moment_residual = fit.residual;
  const int n = static_cast<int>(fit.weights.size());
  r.rule.points.reserve(n);
  r.rule.weights.reserve(n);
  for (int j = 0; j < n; ++j) {
    r.rule.points.push_back(lo + size.cwiseProduct(system.points.col(j)));
    r.rule.weights.push_back(fit.weights[j] * size.prod());
  }
  if (b[0] < 0) {
    r.status = RuleStatus::NegativeMeasure;
  } else if (!(fit.residual <= o.residual_tolerance)) {
    r.status = RuleStatus::ResidualAboveTolerance;
  }
  return r;
}

RefinedAreaRule refined_area_rule(const std::vector<UvLoop>& loops, const AreaRuleOptions& area,
                                  const RefinementOptions& refinement, const UvIntegral& integral) {
  check_refinement(refinement);
  AreaRuleOptions higher = area;
  ++higher.degree;
  if (area.points_per_direction > 0) ++higher.points_per_direction;

  RefinedAreaRule r;
  r.integral = integral(QuadratureRule2{});
  r.status = RuleStatus::EmptyDomain;
  double tolerance = refinement.tolerance;
  bool root = true, converged = true;
  std::function<void(const std::vector<UvLoop>&, int)> process =
      [&](const std::vector<UvLoop>& region, int depth) {
        const AreaRule rp = area_rule(region, area);
        if (rp.status == RuleStatus::EmptyDomain) return;
        const AreaRule rq = area_rule(region, higher);
        const Eigen::VectorXd ip = integral(rp.rule);
        const Eigen::VectorXd iq = integral(rq.rule);
        if (root && refinement.relative) tolerance *= iq.cwiseAbs().maxCoeff();
        root = false;
        const double estimate = (ip - iq).cwiseAbs().maxCoeff();
        const double local = tolerance * std::pow(0.25, depth);
        if (refinement.tolerance > 0 && estimate > local && depth < refinement.max_depth) {
          const Vec2 mid = 0.5 * (rp.box_min + rp.box_max);
          for (int qu = 0; qu < 2; ++qu)
            for (int qv = 0; qv < 2; ++qv) {
              const Vec2 lo(qu ? mid.x() : -kInf, qv ? mid.y() : -kInf);
              const Vec2 hi(qu ? kInf : mid.x(), qv ? kInf : mid.y());
              process(clip_loops(region, lo, hi), depth + 1);
            }
          return;
        }
        if (refinement.tolerance > 0 && estimate > local) converged = false;
        r.rule.points.insert(r.rule.points.end(), rp.rule.points.begin(), rp.rule.points.end());
        r.rule.weights.insert(r.rule.weights.end(), rp.rule.weights.begin(), rp.rule.weights.end());
        r.integral += iq;
        r.error_estimate += estimate;
        r.moment_residual = std::max(r.moment_residual, rp.moment_residual);
        ++r.leaves;
        r.depth = std::max(r.depth, depth);
        r.status =
            r.status == RuleStatus::EmptyDomain ? rp.status : worse_status(r.status, rp.status);
      };
  process(loops, 0);
  if (!converged && r.status != RuleStatus::EmptyDomain)
    r.status = worse_status(r.status, RuleStatus::NotConverged);
  return r;
}

SurfaceRule surface_rule(const CutPatch& patch, const SurfaceRuleOptions& o) {
  PARAFAB_VERIFY(patch.surface, "CutPatch has no surface");
  PARAFAB_VERIFY(patch.orientation == 1 || patch.orientation == -1,
                 "CutPatch.orientation must be +1 or −1, got " << patch.orientation);
  const SurfaceMap& surface = *patch.surface;
  const UvIntegral area = [&](const QuadratureRule2& q) {
    Eigen::VectorXd a = Eigen::VectorXd::Zero(1);
    Vec3 X, Xu, Xv;
    for (size_t j = 0; j < q.points.size(); ++j) {
      surface.evaluate(q.points[j].x(), q.points[j].y(), X, Xu, Xv);
      a[0] += q.weights[j] * Xu.cross(Xv).norm();
    }
    return a;
  };
  const RefinedAreaRule uv =
      refined_area_rule(to_uv_loops(patch.loops), o.area, o.refinement, area);
  SurfaceRule r;
  r.status = uv.status;
  r.error_estimate = uv.error_estimate;
  r.moment_residual = uv.moment_residual;
  r.leaves = uv.leaves;
  r.uv = uv.rule.points;
  Vec3 X, Xu, Xv;
  for (size_t j = 0; j < uv.rule.points.size(); ++j) {
    surface.evaluate(uv.rule.points[j].x(), uv.rule.points[j].y(), X, Xu, Xv);
    const Vec3 n = Xu.cross(Xv);
    const double factor = n.norm();
    r.points.push_back(X);
    r.weights.push_back(uv.rule.weights[j] * factor);
    r.normals.push_back(factor > 0 ? Vec3(patch.orientation * n / factor) : Vec3::Zero());
    r.area += r.weights.back();
  }
  return r;
}

}  // namespace parafab::xfem
