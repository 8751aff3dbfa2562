// Curve rules of thesis §6.3.1: segments parameterized over [0, 1], integrated with
// Gauss–Legendre rules; Lagrange (parabolic) interpolation of sampled curves.
#include "xfem/curve_rules.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "common/error.h"
#include "xfem/quadrature_rule.h"

namespace parafab::xfem {

Vec2 CurveSegment2::position(double t) const {
  if (order == 1) return (1 - t) * start + t * end;
  return (1 - t) * (1 - 2 * t) * start + 4 * t * (1 - t) * mid + t * (2 * t - 1) * end;
}

Vec2 CurveSegment2::derivative(double t) const {
  if (order == 1) return end - start;
  return (4 * t - 3) * start + (4 - 8 * t) * mid + (4 * t - 1) * end;
}

UvLoop to_uv_loop(const BoundaryLoop& loop) {
  const int n = static_cast<int>(loop.points.size());
  PARAFAB_VERIFY(loop.order == 1 || loop.order == 2,
                 "BoundaryLoop.order must be 1 or 2, got " << loop.order);
  PARAFAB_VERIFY(n >= 3 && (loop.order == 1 || n % 2 == 1),
                 "BoundaryLoop of order " << loop.order << " has " << n
                                          << " points (need ≥ 3, odd for order 2)");
  Vec2 lo = loop.points[0], hi = loop.points[0];
  for (const Vec2& p : loop.points) {
    PARAFAB_VERIFY(p.allFinite(), "BoundaryLoop has a non-finite point " << p.transpose());
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  const double gap = (loop.points.back() - loop.points.front()).norm();
  PARAFAB_VERIFY(gap <= 1e-9 * (hi - lo).norm(), "BoundaryLoop is not closed: last point "
                                                     << loop.points.back().transpose() << " is "
                                                     << gap << " away from the first "
                                                     << loop.points.front().transpose());
  UvLoop segments;
  for (int k = 0; k + loop.order < n; k += loop.order) {
    CurveSegment2 s;
    s.order = loop.order;
    s.start = loop.points[k];
    s.end = loop.points[k + loop.order];
    s.mid = loop.order == 2 ? loop.points[k + 1] : 0.5 * (s.start + s.end);
    segments.push_back(s);
  }
  if (gap > 0) segments.push_back({loop.points.back(), {0, 0}, loop.points.front(), 1});
  return segments;
}

std::vector<UvLoop> to_uv_loops(const std::vector<BoundaryLoop>& loops) {
  std::vector<UvLoop> out;
  out.reserve(loops.size());
  for (const BoundaryLoop& l : loops) out.push_back(to_uv_loop(l));
  return out;
}

void extend_bounding_box(const CurveSegment2& s, Vec2& lo, Vec2& hi) {
  lo = lo.cwiseMin(s.start).cwiseMin(s.end);
  hi = hi.cwiseMax(s.start).cwiseMax(s.end);
  if (s.order != 2) return;
  // x(t) = start + c1 t + c2 t²; an interior extreme at t = −c1 / (2 c2).
  const Vec2 c1 = -3 * s.start + 4 * s.mid - s.end;
  const Vec2 c2 = 2 * s.start - 4 * s.mid + 2 * s.end;
  for (int a = 0; a < 2; ++a) {
    if (c2[a] == 0) continue;
    const double t = -c1[a] / (2 * c2[a]);
    if (t <= 0 || t >= 1) continue;
    const double x = s.position(t)[a];
    lo[a] = std::min(lo[a], x);
    hi[a] = std::max(hi[a], x);
  }
}

CurveRule2 curve_rule(const std::vector<CurveSegment2>& segments, const CurveRuleOptions& o) {
  PARAFAB_VERIFY(o.points_per_segment >= 0 && o.polynomial_degree >= 0,
                 "CurveRuleOptions: points_per_segment "
                     << o.points_per_segment << " and polynomial_degree " << o.polynomial_degree
                     << " must be ≥ 0");
  CurveRule2 r;
  for (int k = 0; k < static_cast<int>(segments.size()); ++k) {
    const CurveSegment2& s = segments[k];
    PARAFAB_VERIFY(s.order == 1 || s.order == 2,
                   "curve_rule: segment " << k << " has order " << s.order);
    // Integrand degree in t: order·d for g(x(t)) plus order − 1 for x'(t).
    const int n = o.points_per_segment > 0 ? o.points_per_segment
                                           : (s.order * o.polynomial_degree + s.order - 1) / 2 + 1;
    const QuadratureRule1& g = gauss_legendre(n);
    for (int j = 0; j < n; ++j) {
      r.points.push_back(s.position(g.points[j]));
      r.dx.push_back(g.weights[j] * s.derivative(g.points[j]));
    }
  }
  return r;
}

ParabolicSampling sample_parabolic(const std::function<Vec2(double)>& curve, double t0, double t1,
                                   const ParabolicSamplingOptions& o) {
  PARAFAB_VERIFY(o.tolerance > 0 && o.initial_segments >= 1 && o.max_segments >= o.initial_segments,
                 "ParabolicSamplingOptions: tolerance " << o.tolerance << ", initial_segments "
                                                        << o.initial_segments << ", max_segments "
                                                        << o.max_segments);
  PARAFAB_VERIFY(std::isfinite(t0) && std::isfinite(t1) && t0 != t1,
                 "sample_parabolic: parameter range [" << t0 << ", " << t1 << "] is empty");
  struct Piece {
    double a, b;
    Vec2 pa, pm, pb;
    double deviation;
  };
  auto make = [&](double a, double b, const Vec2& pa, const Vec2& pb) {
    Piece p{a, b, pa, curve(0.5 * (a + b)), pb, 0};
    const CurveSegment2 s{pa, p.pm, pb, 2};
    for (double q : {0.25, 0.75})
      p.deviation = std::max(p.deviation, (curve(a + q * (b - a)) - s.position(q)).norm());
    return p;
  };
  // Depth-first bisection in curve order (max_segments is a safety cap on the total).
  std::vector<Piece> stack;
  Vec2 prev = curve(t0);
  for (int k = 0; k < o.initial_segments; ++k) {
    const double a = t0 + (t1 - t0) * k / o.initial_segments;
    const double b =
        k + 1 == o.initial_segments ? t1 : t0 + (t1 - t0) * (k + 1) / o.initial_segments;
    const Vec2 pb = curve(b);
    stack.push_back(make(a, b, prev, pb));
    prev = pb;
  }
  std::reverse(stack.begin(), stack.end());
  int count = o.initial_segments;
  ParabolicSampling r;
  r.points.push_back(stack.back().pa);
  r.parameters.push_back(t0);
  while (!stack.empty()) {
    const Piece p = stack.back();
    stack.pop_back();
    if (p.deviation > o.tolerance && count < o.max_segments) {
      const double m = 0.5 * (p.a + p.b);
      const Piece left = make(p.a, m, p.pa, p.pm);
      stack.push_back(make(m, p.b, p.pm, p.pb));
      stack.push_back(left);
      ++count;
      continue;
    }
    r.max_deviation = std::max(r.max_deviation, p.deviation);
    r.points.push_back(p.pm);
    r.points.push_back(p.pb);
    r.parameters.push_back(0.5 * (p.a + p.b));
    r.parameters.push_back(p.b);
  }
  r.converged = r.max_deviation <= o.tolerance;
  return r;
}

}  // namespace parafab::xfem
