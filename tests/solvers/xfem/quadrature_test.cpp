// Hierarchical moment-fitting quadrature (thesis §6.3): Gauss rules, curve rules, area,
// surface and volume rules checked against closed forms (polygon and polyhedron moments,
// the circle-cut square of Müller, Kummer & Oberlack 2013, sphere octant, cylinder).
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <functional>
#include <memory>
#include <thread>

#include "common/error.h"
#include "xfem/area_rules.h"
#include "xfem/curve_rules.h"
#include "xfem/linear_xfem.h"
#include "xfem/nnls.h"
#include "xfem/quadrature_rule.h"
#include "xfem/volume_rules.h"
#include "surface_maps.h"

namespace parafab::xfem {
namespace {

const double kPi = std::acos(-1.0);

// ---------------------------------------------------------------------------------------
// Surface maps.

using testing::CylinderMap;  // σ(θ, z) = (cx + R cos θ, cy + R sin θ, z) (surface_maps.h)
using testing::PlaneMap;     // σ(u, v) = origin + u e1 + v e2

/// σ(θ, φ) = c + R (sin φ cos θ, sin φ sin θ, cos φ); σθ × σφ points inwards.
class SphereMap : public SurfaceMap {
 public:
  SphereMap(Vec3 center, double radius) : c_(center), r_(radius) {}
  void evaluate(double t, double p, Vec3& X, Vec3& Xu, Vec3& Xv) const override {
    X = c_ + r_ * Vec3(std::sin(p) * std::cos(t), std::sin(p) * std::sin(t), std::cos(p));
    Xu = r_ * Vec3(-std::sin(p) * std::sin(t), std::sin(p) * std::cos(t), 0);
    Xv = r_ * Vec3(std::cos(p) * std::cos(t), std::cos(p) * std::sin(t), -std::sin(p));
  }

 private:
  Vec3 c_;
  double r_;
};


// ---------------------------------------------------------------------------------------
// Closed forms.

double binomial(int n, int k) {
  double r = 1;
  for (int i = 1; i <= k; ++i) r = r * (n - k + i) / i;
  return r;
}

/// ∫ x^i y^j over a polygon (vertices counter-clockwise, holes as separate clockwise
/// polygons), from ∮ x^{i+1} y^j / (i+1) dy with each edge integrated in closed form.
long double polygon_moment(const std::vector<std::vector<Vec2>>& polygons, int i, int j) {
  long double sum = 0;
  for (const auto& poly : polygons)
    for (size_t k = 0; k < poly.size(); ++k) {
      const Vec2 a = poly[k], d = poly[(k + 1) % poly.size()] - a;
      for (int p = 0; p <= i + 1; ++p)
        for (int q = 0; q <= j; ++q)
          sum += binomial(i + 1, p) * binomial(j, q) * std::pow((long double)a.x(), i + 1 - p) *
                 std::pow((long double)d.x(), p) * std::pow((long double)a.y(), j - q) *
                 std::pow((long double)d.y(), q) / (p + q + 1) * d.y() / (i + 1);
    }
  return sum;
}

BoundaryLoop polygon_loop(const std::vector<Vec2>& poly, int order = 1) {
  BoundaryLoop l;
  l.order = order;
  for (size_t k = 0; k <= poly.size(); ++k) {
    const Vec2 a = poly[k % poly.size()];
    if (order == 2 && k > 0) l.points.push_back(0.5 * (l.points.back() + a));
    l.points.push_back(a);
  }
  return l;
}

/// Σ_j w_j x_j^i y_j^j.
double apply(const QuadratureRule2& r, const std::function<double(const Vec2&)>& f) {
  double s = 0;
  for (size_t j = 0; j < r.points.size(); ++j) s += r.weights[j] * f(r.points[j]);
  return s;
}
double apply(const QuadratureRule3& r, const std::function<double(const Vec3&)>& f) {
  double s = 0;
  for (size_t j = 0; j < r.points.size(); ++j) s += r.weights[j] * f(r.points[j]);
  return s;
}

/// ∫ f over the tetrahedron (a, b, c, d) (signed by orientation) by collapsed coordinates:
/// exact for polynomials up to degree 2·8 − 3.
double tet_integral(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d,
                    const std::function<double(const Vec3&)>& f) {
  const QuadratureRule1& g = gauss_legendre(8);
  Eigen::Matrix3d J;
  J << b - a, c - a, d - a;
  double s = 0;
  for (int i = 0; i < 8; ++i)
    for (int j = 0; j < 8; ++j)
      for (int k = 0; k < 8; ++k) {
        const double u = g.points[i], v = g.points[j], w = g.points[k];
        const Vec3 ref(u, (1 - u) * v, (1 - u) * (1 - v) * w);
        s += g.weights[i] * g.weights[j] * g.weights[k] * (1 - u) * (1 - u) * (1 - v) *
             f(a + J * ref);
      }
  return s * J.determinant();
}

/// Convex polyhedron as faces (vertices counter-clockwise seen from outside).
using Faces = std::vector<std::vector<Vec3>>;

Faces box_faces(const Vec3& lo, const Vec3& hi) {
  auto P = [&](int x, int y, int z) {
    return Vec3(x ? hi.x() : lo.x(), y ? hi.y() : lo.y(), z ? hi.z() : lo.z());
  };
  return {{P(0, 0, 0), P(0, 0, 1), P(0, 1, 1), P(0, 1, 0)},
          {P(1, 0, 0), P(1, 1, 0), P(1, 1, 1), P(1, 0, 1)},
          {P(0, 0, 0), P(1, 0, 0), P(1, 0, 1), P(0, 0, 1)},
          {P(0, 1, 0), P(0, 1, 1), P(1, 1, 1), P(1, 1, 0)},
          {P(0, 0, 0), P(0, 1, 0), P(1, 1, 0), P(1, 0, 0)},
          {P(0, 0, 1), P(1, 0, 1), P(1, 1, 1), P(0, 1, 1)}};
}

/// Keeps n·x ≤ d: every face clipped (Sutherland–Hodgman), plus the cap polygon.
Faces clip_polyhedron(const Faces& faces, const Vec3& n, double d) {
  Faces out;
  std::vector<Vec3> cap;
  for (const auto& f : faces) {
    std::vector<Vec3> kept;
    for (size_t k = 0; k < f.size(); ++k) {
      const Vec3 a = f[k], b = f[(k + 1) % f.size()];
      const double sa = n.dot(a) - d, sb = n.dot(b) - d;
      if (sa <= 0) kept.push_back(a);
      if ((sa < 0 && sb > 0) || (sa > 0 && sb < 0)) {
        const Vec3 x = a + sa / (sa - sb) * (b - a);
        kept.push_back(x);
        cap.push_back(x);
      }
    }
    if (kept.size() >= 3) out.push_back(kept);
  }
  Vec3 c = Vec3::Zero();
  for (const Vec3& x : cap) c += x / cap.size();
  const Vec3 e1 = (cap[0] - c).normalized(), e2 = n.normalized().cross(e1);
  std::sort(cap.begin(), cap.end(), [&](const Vec3& a, const Vec3& b) {
    return std::atan2((a - c).dot(e2), (a - c).dot(e1)) <
           std::atan2((b - c).dot(e2), (b - c).dot(e1));
  });
  cap.erase(std::unique(cap.begin(), cap.end(),
                        [](const Vec3& a, const Vec3& b) { return (a - b).norm() < 1e-15; }),
            cap.end());
  out.push_back(cap);
  return out;
}

/// ∫ f over the polyhedron: tetrahedra from its first vertex to the faces' fans.
double polyhedron_integral(const Faces& faces, const std::function<double(const Vec3&)>& f) {
  const Vec3 p = faces[0][0];
  double s = 0;
  for (const auto& face : faces)
    for (size_t k = 1; k + 1 < face.size(); ++k)
      s += tet_integral(p, face[0], face[k], face[k + 1], f);
  return s;
}

/// Planar patch of a face; orientation −1 flips the parametrization (and the loop with it).
CutPatch face_patch(const std::vector<Vec3>& face, int orientation) {
  Vec3 n = Vec3::Zero();
  for (size_t k = 0; k < face.size(); ++k) n += face[k].cross(face[(k + 1) % face.size()]);
  n.normalize();
  const Vec3 e1 = (face[1] - face[0]).normalized();
  const Vec3 e2 = orientation * n.cross(e1);  // e1 × e2 = orientation · n
  std::vector<Vec2> uv;
  for (const Vec3& x : face) uv.push_back({(x - face[0]).dot(e1), (x - face[0]).dot(e2)});
  if (orientation < 0) std::reverse(uv.begin(), uv.end());
  CutPatch p;
  p.surface = std::make_shared<PlaneMap>(face[0], e1, e2);
  p.orientation = orientation;
  p.loops = {polygon_loop(uv)};
  return p;
}

Subvolume polyhedron_subvolume(const Faces& faces, const Box3& cell) {
  Subvolume sv;
  sv.cell = cell;
  for (size_t k = 0; k < faces.size(); ++k)
    sv.patches.push_back(face_patch(faces[k], k % 2 ? -1 : 1));
  return sv;
}

/// Appends parabolic samples of a curve to a loop (dropping a repeated joint point).
void append_parabolic(BoundaryLoop& loop, const std::function<Vec2(double)>& c, double t0,
                      double t1, double tolerance, int segments = 1) {
  ParabolicSamplingOptions o;
  o.tolerance = tolerance;
  o.initial_segments = segments;
  const ParabolicSampling s = sample_parabolic(c, t0, t1, o);
  const size_t first = loop.points.empty() ? 0 : 1;
  loop.points.insert(loop.points.end(), s.points.begin() + first, s.points.end());
}
void append_line(BoundaryLoop& loop, const Vec2& b) {
  if (loop.order == 2) loop.points.push_back(0.5 * (loop.points.back() + b));
  loop.points.push_back(b);
}

// ---------------------------------------------------------------------------------------
// Gauss–Legendre and tensor rules.

TEST(GaussLegendre, KnownRulesAndExactness) {
  const QuadratureRule1& g2 = gauss_legendre(2);
  EXPECT_NEAR(g2.points[0], 0.5 - 0.5 / std::sqrt(3.0), 1e-16);
  EXPECT_NEAR(g2.weights[1], 0.5, 2e-16);
  for (int n = 1; n <= kMaxGaussPoints; ++n) {
    const QuadratureRule1& g = gauss_legendre(n);
    double worst = 0;
    for (int d = 0; d <= 2 * n - 1; ++d) {
      double s = 0;
      for (int j = 0; j < n; ++j) s += g.weights[j] * std::pow(g.points[j], d);
      worst = std::max(worst, std::abs(s - 1.0 / (d + 1)));
    }
    EXPECT_LT(worst, 4e-15) << n << " points";
  }
  EXPECT_THROW(gauss_legendre(0), Error);
  EXPECT_THROW(gauss_legendre(kMaxGaussPoints + 1), Error);
}

TEST(TensorGauss, ExactForDegree2pMinus1PerVariable) {
  const Box3 box{{-1, 0.5, 2}, {0.5, 1.25, 4}};
  auto exact = [&](int a, int b, int c) {
    auto I = [](double lo, double hi, int k) {
      return (std::pow(hi, k + 1) - std::pow(lo, k + 1)) / (k + 1);
    };
    return I(box.min.x(), box.max.x(), a) * I(box.min.y(), box.max.y(), b) *
           I(box.min.z(), box.max.z(), c);
  };
  for (int p = 1; p <= 6; ++p) {
    const QuadratureRule3 r = tensor_gauss_rule(box, p);
    ASSERT_EQ(r.points.size(), size_t(p * p * p));
    for (int a = 0; a <= 2 * p - 1; ++a)
      for (int b : {0, 2 * p - 1})
        for (int c : {0, 2 * p - 1}) {
          const double s = apply(r, [&](const Vec3& x) {
            return std::pow(x.x(), a) * std::pow(x.y(), b) * std::pow(x.z(), c);
          });
          EXPECT_NEAR(s, exact(a, b, c), 1e-12 * std::abs(exact(a, b, c)))
              << p << ": " << a << b << c;
        }
    // Degree 2p is not integrated exactly (sharpness).
    const double s = apply(r, [&](const Vec3& x) { return std::pow(x.z(), 2 * p); });
    EXPECT_GT(std::abs(s - exact(0, 0, 2 * p)), 1e-10 * exact(0, 0, 2 * p));
  }
}

// ---------------------------------------------------------------------------------------
// Curve and area rules.

TEST(CurveRule, ExactFluxOnParabolicSegments) {
  // Region under the parabola y = 1 − x² (x ∈ [−1, 1]) closed by the x axis: the parabola
  // is one order-2 segment, so area 4/3 and ∫x²y⁴ follow exactly from Green's theorem.
  BoundaryLoop l;
  l.order = 2;
  l.points = {{-1, 0}, {0, 0}, {1, 0}, {0, 1}, {-1, 0}};  // (1,0) → (0,1) → (−1,0) is y = 1 − x²
  const UvLoop loop = to_uv_loop(l);
  CurveRuleOptions o;
  o.polynomial_degree = 7;
  const CurveRule2 c = curve_rule(loop, o);
  double area = 0, m = 0;
  for (size_t j = 0; j < c.points.size(); ++j) {
    const Vec2 x = c.points[j];
    area += x.x() * c.dx[j].y();  // P = (x, 0)
    m += std::pow(x.x(), 3) / 3 * std::pow(x.y(), 4) * c.dx[j].y();
  }
  EXPECT_NEAR(area, 4.0 / 3, 1e-15);
  // ∫_{−1}^{1} x² (1 − x²)⁵ / 5 dx = 2/5 · B(3/2, 6) = 256/45045 · … computed by Gauss here:
  const QuadratureRule1& g = gauss_legendre(10);
  double exact = 0;
  for (int j = 0; j < 10; ++j) {
    const double x = 2 * g.points[j] - 1;
    exact += 2 * g.weights[j] * x * x * std::pow(1 - x * x, 5) / 5;
  }
  EXPECT_NEAR(m, exact, 1e-16);
}

// Müller et al.'s regression case: [−1, 1]² cut by (x − 1.5)² + (y − 1.5)² = 5/2.
struct CircleCut {
  const Vec2 c{1.5, 1.5};
  const double r = std::sqrt(2.5);
  const double a0 = std::atan2(-1.5, -0.5), a1 = std::atan2(-0.5, -1.5);  // (1,0) → (0,1)
  // The region inside the square and OUTSIDE the circle has area 3.34088097749782 (the part
  // inside both is 4 − 3.3408… = 0.659…): square minus triangle minus circular segment.
  const double theta = std::acos(0.6);
  const double area = 4 - 0.5 - 0.5 * r * r * (theta - 0.8);
  const double arc = r * theta;
  Vec2 point(double t) const {
    return c + r * Vec2(std::cos(a0 + t * (a1 - a0)), std::sin(a0 + t * (a1 - a0)));
  }
  // CCW loop of the region with the arc as N uniform segments of the given order.
  BoundaryLoop loop(int segments, int order) const {
    BoundaryLoop l;
    l.order = order;
    l.points = {{-1, -1}};
    append_line(l, {1, -1});
    append_line(l, {1, 0});
    for (int k = 1; k <= segments * order; ++k)
      l.points.push_back(point(double(k) / (segments * order)));
    l.points.back() = {0, 1};
    append_line(l, {-1, 1});
    append_line(l, {-1, -1});
    return l;
  }
};

TEST(AreaRule, CircleCutSquareConvergenceAndAccuracy) {
  const CircleCut cc;
  // The published values agree with the closed forms to 1.6e-13 and 2.7e-14.
  EXPECT_NEAR(cc.area, 3.34088097749782, 2e-13);
  EXPECT_NEAR(cc.arc, 1.46618247613376, 5e-14);
  std::printf("  segments | area error linear | area error parabolic | arc error parabolic\n");
  double prev_lin = 0, prev_par = 0;
  for (int n = 2; n <= 128; n *= 2) {
    const AreaRule lin = area_rule(std::vector<BoundaryLoop>{cc.loop(n, 1)});
    const AreaRule par = area_rule(std::vector<BoundaryLoop>{cc.loop(n, 2)});
    ASSERT_EQ(par.status, RuleStatus::Ok);
    const double el = std::abs(apply(lin.rule, [](const Vec2&) { return 1.0; }) - cc.area);
    const double ep = std::abs(apply(par.rule, [](const Vec2&) { return 1.0; }) - cc.area);
    // Arc length along the arc segments only (the last 2·(segment) … skip the straight ones).
    const UvLoop loop = to_uv_loop(cc.loop(n, 2));
    CurveRuleOptions co;
    co.points_per_segment = 12;
    const CurveRule2 c = curve_rule(UvLoop(loop.begin() + 2, loop.end() - 2), co);
    double length = 0;
    for (const Vec2& d : c.dx) length += d.norm();
    std::printf("  %8d | %17.3e | %20.3e | %19.3e\n", n, el, ep, std::abs(length - cc.arc));
    if (n >= 8) {
      EXPECT_GT(prev_lin / el, 3.5) << "linear: O(h²)";
      EXPECT_GT(prev_par / ep, 12.0) << "parabolic: O(h⁴)";
    }
    if (n == 128) {
      EXPECT_LT(ep, 1e-10);
    }
    prev_lin = el;
    prev_par = ep;
  }
  // Adaptive parabolic sampling of the arc to 1e-11 deviation: area and length to 1e-10.
  BoundaryLoop l;
  l.order = 2;
  l.points = {{-1, -1}};
  append_line(l, {1, -1});
  append_line(l, {1, 0});
  const size_t arc_begin = l.points.size() - 1;
  const ParabolicSampling s = sample_parabolic([&](double t) { return cc.point(t); }, 0, 1, {1e-9});
  ASSERT_TRUE(s.converged);
  EXPECT_LE(s.max_deviation, 1e-9);
  ASSERT_EQ(s.parameters.size(), s.points.size());
  for (size_t k = 0; k < s.points.size(); ++k) EXPECT_EQ(s.points[k], cc.point(s.parameters[k]));
  l.points.insert(l.points.end(), s.points.begin() + 1, s.points.end());
  const size_t arc_end = l.points.size() - 1;
  append_line(l, {-1, 1});
  append_line(l, {-1, -1});
  const AreaRule r = area_rule(std::vector<BoundaryLoop>{l});
  EXPECT_EQ(r.status, RuleStatus::Ok);
  EXPECT_NEAR(apply(r.rule, [](const Vec2&) { return 1.0; }), 3.34088097749782, 1e-10);
  EXPECT_NEAR(r.measure, cc.area, 1e-11);
  const UvLoop loop = to_uv_loop(l);
  CurveRuleOptions co;
  co.points_per_segment = 12;
  const CurveRule2 c =
      curve_rule(UvLoop(loop.begin() + arc_begin / 2, loop.begin() + arc_end / 2), co);
  double length = 0;
  for (const Vec2& d : c.dx) length += d.norm();
  EXPECT_NEAR(length, 1.46618247613376, 1e-10);
  EXPECT_NEAR(length, cc.arc, 1e-11);
  std::printf(
      "  adaptive sampling: %zu arc segments, area error %.2e, arc error %.2e, residual %.1e\n",
      (arc_end - arc_begin) / 2, std::abs(r.measure - cc.area), std::abs(length - cc.arc),
      r.moment_residual);
}

TEST(AreaRule, StraightCutIsExact) {
  // [−1, 1]² minus the corner beyond the line through (0.2, 1) and (1, −0.4).
  const std::vector<Vec2> poly{{-1, -1}, {1, -1}, {1, -0.4}, {0.2, 1}, {-1, 1}};
  for (int order : {1, 2}) {
    const AreaRule r = area_rule(std::vector<BoundaryLoop>{polygon_loop(poly, order)});
    ASSERT_EQ(r.status, RuleStatus::Ok);
    for (auto [i, j] :
         std::vector<std::pair<int, int>>{{0, 0}, {1, 0}, {0, 1}, {2, 0}, {1, 1}, {0, 2}}) {
      const double exact = double(polygon_moment({poly}, i, j));
      const double s =
          apply(r.rule, [&](const Vec2& x) { return std::pow(x.x(), i) * std::pow(x.y(), j); });
      EXPECT_NEAR(s, exact, 1e-14) << "x^" << i << " y^" << j << ", order " << order;
    }
  }
}

TEST(AreaRule, IntegratesBasisExactlyOnPolygonWithHole) {
  // Non-convex polygon with a clockwise hole, off-centre coordinates.
  const std::vector<Vec2> outer{{0.3, 0.1}, {2.1, 0.4}, {1.9, 1.7}, {1.2, 0.9}, {0.5, 1.9}};
  std::vector<Vec2> hole{{0.7, 0.5}, {1.4, 0.6}, {0.9, 0.8}};
  std::reverse(hole.begin(), hole.end());
  for (int degree : {4, 5}) {
    AreaRuleOptions o;
    o.degree = degree;
    const AreaRule r = area_rule({polygon_loop(outer), polygon_loop(hole, 2)}, o);
    ASSERT_EQ(r.status, RuleStatus::Ok);
    double worst = 0;
    for (int i = 0; i <= degree; ++i)
      for (int j = 0; j <= degree; ++j) {
        const double exact = double(polygon_moment({outer, hole}, i, j));
        const double s =
            apply(r.rule, [&](const Vec2& x) { return std::pow(x.x(), i) * std::pow(x.y(), j); });
        worst = std::max(worst, std::abs(s - exact) / std::max(1.0, std::abs(exact)));
      }
    EXPECT_LT(worst, 5e-14) << "degree " << degree;
    std::printf("  degree %d: worst relative error over x^i y^j (i, j ≤ %d): %.1e, residual %.1e\n",
                degree, degree, worst, r.moment_residual);
  }
}

TEST(AreaRule, NonNegativeWeights) {
  // With (p + 2)² points a non-negative exact rule need not exist; more points make one likely.
  const CircleCut cc;
  const std::vector<BoundaryLoop> loops{cc.loop(64, 2)};
  const AreaRule mn = area_rule(loops);
  for (int q : {6, 8, 10}) {
    AreaRuleOptions o;
    o.fit = WeightFit::NonNegative;
    o.points_per_direction = q;
    const AreaRule r = area_rule(loops, o);
    double min_w = 1e300, worst = 0;
    int positive = 0;
    for (double w : r.rule.weights) min_w = std::min(min_w, w), positive += w > 0;
    EXPECT_GE(min_w, 0.0);
    for (int i = 0; i <= 2; ++i)
      for (int j = 0; i + j <= 2; ++j) {
        auto f = [&](const Vec2& x) { return std::pow(x.x(), i) * std::pow(x.y(), j); };
        worst = std::max(worst, std::abs(apply(r.rule, f) - apply(mn.rule, f)));
      }
    std::printf(
        "  NNLS area rule, %2d² points: status %s, residual %.1e, %d weights > 0, degree ≤ 2 error "
        "%.1e\n",
        q, to_string(r.status), r.moment_residual, positive, worst);
    if (q == 6) {
      EXPECT_EQ(r.status, RuleStatus::ResidualAboveTolerance);
    } else {
      EXPECT_EQ(r.status, RuleStatus::Ok);
      EXPECT_LT(worst, 1e-10);
    }
  }
}

TEST(AreaRule, ClippedLoopsPartitionTheRegion) {
  const CircleCut cc;
  const std::vector<UvLoop> loops{to_uv_loop(cc.loop(16, 2))};
  const double total = area_rule(loops).measure;
  double sum = 0, sum_xy = 0;
  const double inf = std::numeric_limits<double>::infinity();
  for (double cx : {-0.3, 0.4})
    for (double cy : {0.2, 0.7}) {
      // Three vertical and three horizontal slabs: 9 pieces through (cx, cy) lines.
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) {
          const double xs[] = {-inf, cx, cx + 0.45, inf}, ys[] = {-inf, cy, cy + 0.2, inf};
          const auto piece = clip_loops(loops, {xs[i], ys[j]}, {xs[i + 1], ys[j + 1]});
          const AreaRule r = area_rule(piece);
          if (r.status == RuleStatus::EmptyDomain) continue;
          EXPECT_EQ(r.status, RuleStatus::Ok);
          sum += r.measure;
          sum_xy += apply(r.rule, [](const Vec2& x) { return x.x() * x.y() * x.y(); });
        }
    }
  const double xy =
      apply(area_rule(loops).rule, [](const Vec2& x) { return x.x() * x.y() * x.y(); });
  EXPECT_NEAR(sum, 4 * total, 1e-13);
  EXPECT_NEAR(sum_xy, 4 * xy, 1e-13);
}

TEST(AreaRule, RejectsMalformedLoops) {
  BoundaryLoop open;
  open.order = 1;
  open.points = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
  EXPECT_THROW(area_rule(std::vector<BoundaryLoop>{open}), Error);
  BoundaryLoop even = polygon_loop({{0, 0}, {1, 0}, {0, 1}}, 2);
  even.points.pop_back();
  EXPECT_THROW(area_rule(std::vector<BoundaryLoop>{even}), Error);
  std::vector<Vec2> cw{{0, 0}, {0, 1}, {1, 0}};
  EXPECT_EQ(area_rule(std::vector<BoundaryLoop>{polygon_loop(cw)}).status,
            RuleStatus::NegativeMeasure);
  EXPECT_EQ(area_rule(std::vector<BoundaryLoop>{}).status, RuleStatus::EmptyDomain);
}

TEST(AreaRule, DegreeBoostResolvesASmoothIntegrandWithFewerLeaves) {
  // A unit square turned by 0.5 rad (its bounding box is not its own), integrand
  // exp(k d1·x) along its first edge direction d1: ∫ = exp(k d1·c) (e^k − 1) / k, c the corner.
  const double th = 0.5, k = 4;
  const Vec2 c(0.1, 0.2), d1(std::cos(th), std::sin(th)), d2(-std::sin(th), std::cos(th));
  const std::vector<Vec2> square{c, c + d1, c + d1 + d2, c + d2};
  const auto loops = to_uv_loops(std::vector<BoundaryLoop>{polygon_loop(square, 1)});
  const UvIntegral f = [&](const QuadratureRule2& q) {
    Eigen::VectorXd v = Eigen::VectorXd::Zero(1);
    for (size_t j = 0; j < q.points.size(); ++j) v(0) += q.weights[j] * std::exp(k * d1.dot(q.points[j]));
    return v;
  };
  const double exact = std::exp(k * d1.dot(c)) * (std::exp(k) - 1) / k;
  RefinementOptions split{1e-12, false, 8, 0}, boost = split;
  boost.degree_boost = 6;
  const RefinedAreaRule rs = refined_area_rule(loops, AreaRuleOptions{5}, split, f);
  const RefinedAreaRule rb = refined_area_rule(loops, AreaRuleOptions{5}, boost, f);
  std::printf("  turned square, exp(4 d1·x): split only %d leaves (depth %d) error %.1e; boost 6: %d leaves "
              "(%d boosted, depth %d) error %.1e\n",
              rs.leaves, rs.depth, std::abs(rs.integral(0) - exact) / exact, rb.leaves, rb.boosted_leaves, rb.depth,
              std::abs(rb.integral(0) - exact) / exact);
  ASSERT_EQ(rs.status, RuleStatus::Ok);
  ASSERT_EQ(rb.status, RuleStatus::Ok);
  // measured 5.1e-16 and 3.8e-16 relative (tolerance asked 1e-12 absolute, exact ≈ 27)
  EXPECT_NEAR(rs.integral(0), exact, 1e-14 * exact);
  EXPECT_NEAR(rb.integral(0), exact, 1e-14 * exact);
  EXPECT_GT(rb.boosted_leaves, 0);
  EXPECT_LT(10 * rb.leaves, rs.leaves);  // measured 7 against 190
  // The leaves' own rules (not only the extrapolated integral) stay within their estimate.
  EXPECT_NEAR(f(rb.rule)(0), exact, 1e-14 * exact + rb.error_estimate);
}

TEST(AreaRule, RefinementStopsAtItsCapsAndCountsTheLeavesThere) {
  // Degree 5 (6 × 6 Gauss points on an uncut box) against 6 (8 × 8): degree 4's rule would be the
  // same 6 × 6 rule, with a zero estimate. A tolerance nothing meets (round-off alone is far
  // above it): at max_depth 2 every one of
  // the 16 quadrants is a leaf at the cap; at max_depth 64 (what a job may ask) the region
  // budget stops the splitting instead of 4^64 leaves.
  const auto loops = to_uv_loops(std::vector<BoundaryLoop>{polygon_loop({{0, 0}, {1, 0}, {1, 1}, {0, 1}}, 1)});
  const UvIntegral f = [](const QuadratureRule2& q) {
    Eigen::VectorXd v = Eigen::VectorXd::Zero(1);
    for (size_t j = 0; j < q.points.size(); ++j) v(0) += q.weights[j] * std::exp(3 * q.points[j].x() * q.points[j].y());
    return v;
  };
  const RefinedAreaRule shallow = refined_area_rule(loops, AreaRuleOptions{5}, RefinementOptions{1e-300, false, 2, 0}, f);
  EXPECT_EQ(shallow.status, RuleStatus::NotConverged);
  EXPECT_EQ(shallow.leaves, 16);
  // Measured 13: on 3 quadrants the two rules agree to the last bit (an estimate of 0).
  EXPECT_GE(shallow.capped_leaves, 12);
  EXPECT_LE(shallow.capped_leaves, 16);
  EXPECT_EQ(shallow.regions, 21);
  EXPECT_EQ(shallow.depth, 2);
  const RefinedAreaRule deep = refined_area_rule(loops, AreaRuleOptions{5}, RefinementOptions{1e-300, false, 64, 0}, f);
  std::printf("  max_depth 64: %d regions, %d leaves (%d at a cap), depth %d\n", deep.regions, deep.leaves,
              deep.capped_leaves, deep.depth);
  EXPECT_EQ(deep.status, RuleStatus::NotConverged);
  EXPECT_LE(deep.regions, RefinementOptions{}.max_regions + 3 * 64);
  // Measured 5613 regions, 4210 leaves, 4144 of them above their tolerance, depth 64.
  EXPECT_GT(deep.capped_leaves, 0.9 * deep.leaves);
  // The integral stays right: ∫∫ exp(3xy) = Σ_n 3^n / (n! (n+1)^2).
  double exact = 0, term = 1;
  for (int n = 0; n < 40; ++n, term *= 3.0 / n) exact += term / ((n + 1.0) * (n + 1.0));
  EXPECT_NEAR(deep.integral(0), exact, 1e-13 * exact);
  EXPECT_NEAR(shallow.integral(0), exact, 1e-13 * exact);
}

// ---------------------------------------------------------------------------------------
// Surface rules.

CutPatch sphere_octant_patch(double R) {
  CutPatch p;
  p.surface = std::make_shared<SphereMap>(Vec3::Zero(), R);
  p.orientation = -1;  // σθ × σφ points to the centre
  p.loops = {polygon_loop({{0, 0}, {kPi / 2, 0}, {kPi / 2, kPi / 2}, {0, kPi / 2}})};
  return p;
}

TEST(SurfaceRule, SphereOctantAreaAndNormals) {
  const double R = 0.9;
  SurfaceRuleOptions o;
  const SurfaceRule single = surface_rule(sphere_octant_patch(R), o);
  o.refinement.tolerance = 1e-15;  // relative: the single rule is at 5e-14
  const SurfaceRule refined = surface_rule(sphere_octant_patch(R), o);
  const double exact = kPi * R * R / 2;
  std::printf(
      "  sphere octant area: single rule error %.2e (estimate %.1e); refined %d leaves error %.2e "
      "(estimate %.1e)\n",
      std::abs(single.area - exact), single.error_estimate, refined.leaves,
      std::abs(refined.area - exact), refined.error_estimate);
  EXPECT_EQ(refined.status, RuleStatus::Ok);
  EXPECT_GT(refined.leaves, 1);
  EXPECT_NEAR(single.area, exact, 1e-12);
  EXPECT_NEAR(refined.area, exact, 1e-13);
  double flux = 0;  // ∫ n·X dS = R · area for outward normals
  for (size_t j = 0; j < refined.points.size(); ++j)
    flux += refined.weights[j] * refined.normals[j].dot(refined.points[j]);
  EXPECT_NEAR(flux, R * exact, 1e-11);
}

// ---------------------------------------------------------------------------------------
// Volume rules.

TEST(VolumeRule, CubeCutByPlaneIsExact) {
  const Box3 cell{{0, 0, 0}, {1, 1, 1}};
  const Vec3 n(0.3, 0.5, 0.8);
  const Faces faces = clip_polyhedron(box_faces(cell.min, cell.max), n, 0.7);
  const Subvolume sv = polyhedron_subvolume(faces, cell);
  const auto t0 = std::chrono::steady_clock::now();
  const VolumeRule r = volume_rule(sv);
  const double ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  ASSERT_EQ(r.status, RuleStatus::Ok) << to_string(r.status);
  EXPECT_LT(r.closure_defect, 1e-15);
  double worst = 0;
  for (int a = 0; a <= 4; ++a)
    for (int b = 0; a + b <= 4; ++b)
      for (int c = 0; a + b + c <= 4; ++c) {
        auto f = [&](const Vec3& x) {
          return std::pow(x.x(), a) * std::pow(x.y(), b) * std::pow(x.z(), c);
        };
        const double exact = polyhedron_integral(faces, f);
        const double err = std::abs(apply(r.rule, f) - exact);
        if (a + b + c <= 2) {  // volume, centroid, second moments
          EXPECT_NEAR(apply(r.rule, f), exact, 1e-13) << a << b << c;
        }
        worst = std::max(worst, err);
      }
  EXPECT_LT(worst, 1e-13);
  std::printf(
      "  cut cube: %zu faces, volume %.15f, worst error over degree ≤ 4 monomials %.1e, residual "
      "%.1e, %.2f ms\n",
      faces.size(), r.volume, worst, r.moment_residual, ms);

  // Beyond the basis (e.g. trilinear mass matrices need degree 6): default degree 4 versus
  // degree 6 (patch rules of degree 7 keep the flux of the degree-7 antiderivatives exact).
  for (int degree : {4, 6}) {
    VolumeRuleOptions o;
    o.degree = degree;
    o.points_per_direction = degree + 1;
    o.patch.degree = degree + 1;
    const VolumeRule rd = volume_rule(sv, o);
    std::array<double, 7> worst_of{};
    for (int a = 0; a <= 6; ++a)
      for (int b = 0; a + b <= 6; ++b)
        for (int c = 0; a + b + c <= 6; ++c) {
          auto f = [&](const Vec3& x) {
            return std::pow(x.x(), a) * std::pow(x.y(), b) * std::pow(x.z(), c);
          };
          double& w = worst_of[a + b + c];
          w = std::max(w, std::abs(apply(rd.rule, f) - polyhedron_integral(faces, f)));
        }
    std::printf("  cut cube, degree %d, %d³ points: worst error by monomial degree 0..6:", degree,
                o.points_per_direction);
    for (double w : worst_of) std::printf(" %.0e", w);
    std::printf("\n");
    for (int k = 0; k <= degree; ++k) EXPECT_LT(worst_of[k], 1e-13) << "degree " << k;
  }
}

// rule_frame recovers a rule's box from its first and last tensor Gauss points: the tight
// fitting box volume_rule reports (a cell cut by an oblique plane, 4 and 5 points per direction),
// an uncut cell's box, a frozen frame when one is set, the cell's box for a failed (empty) rule;
// a rule of other than n³ points is an error naming its size.
TEST(VolumeRule, RuleFrameIsTheFittingBox) {
  const Box3 cell{{0.25, -1, 2}, {1.75, 0.5, 3.5}};
  const Vec3 n = Vec3(0.3, 0.5, 0.8).normalized();
  const Faces faces = clip_polyhedron(box_faces(cell.min, cell.max), n, n.dot(cell.min + 0.3 * cell.size()));
  const Subvolume sv = polyhedron_subvolume(faces, cell);
  for (int per : {4, 5}) {
    VolumeRuleOptions o;
    o.degree = 3;
    o.points_per_direction = per;
    const VolumeRule r = volume_rule(sv, o);
    ASSERT_EQ(r.status, RuleStatus::Ok);
    ASSERT_LT(r.box.volume(), 0.99 * cell.volume());  // tight: not the cell
    GridElement el;
    el.box = cell;
    el.rule = r.rule;
    const Box3 b = rule_frame(el);
    EXPECT_LT((b.min - r.box.min).cwiseAbs().maxCoeff(), 1e-14) << per;
    EXPECT_LT((b.max - r.box.max).cwiseAbs().maxCoeff(), 1e-14) << per;
    el.frame = cell;
    EXPECT_EQ(rule_frame(el).min, cell.min);
  }
  GridElement uncut;
  uncut.box = cell;
  uncut.rule = tensor_gauss_rule(cell, 3);
  EXPECT_LT((rule_frame(uncut).min - cell.min).cwiseAbs().maxCoeff(), 1e-14);
  EXPECT_LT((rule_frame(uncut).max - cell.max).cwiseAbs().maxCoeff(), 1e-14);
  GridElement failed = uncut;  // a failed rule keeps the element with no points: its cell's box
  failed.rule = {};
  EXPECT_EQ(rule_frame(failed).min, cell.min);
  EXPECT_EQ(rule_frame(failed).max, cell.max);
  uncut.rule.points.pop_back();
  uncut.rule.weights.pop_back();
  try {
    rule_frame(uncut);
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("26 points"), std::string::npos) << e.what();
  }
}

// The hex27 cut-cell rule (occ::rules_for_element): total degree 10 with every exponent ≤ 4,
// 121 functions on 5³ points. Exact for every monomial of that span (the products of two
// gradients of triquadratic functions), on a cube cut by a plane oblique to the axes.
TEST(VolumeRule, CappedSpanIsExactForTriquadraticStiffnessMonomials) {
  const Box3 cell{{0, 0, 0}, {1, 1, 1}};
  const Vec3 n(0.3, 0.5, 0.8);
  const Faces faces = clip_polyhedron(box_faces(cell.min, cell.max), n, 0.7);
  const Subvolume sv = polyhedron_subvolume(faces, cell);
  VolumeRuleOptions o;
  o.degree = 10;
  o.max_exponent = 4;
  o.points_per_direction = 5;
  o.patch.degree = 10;
  const VolumeRule r = volume_rule(sv, o);
  ASSERT_EQ(r.status, RuleStatus::Ok) << to_string(r.status);
  EXPECT_EQ(r.rule.points.size(), 125u);
  double worst = 0, scale = 0;
  int monomials = 0;
  for (int a = 0; a <= 4; ++a)
    for (int b = 0; b <= 4; ++b)
      for (int c = 0; c <= 4 && a + b + c <= 10; ++c) {
        auto f = [&](const Vec3& x) { return std::pow(x.x(), a) * std::pow(x.y(), b) * std::pow(x.z(), c); };
        const double exact = polyhedron_integral(faces, f);
        worst = std::max(worst, std::abs(apply(r.rule, f) - exact));
        scale = std::max(scale, std::abs(exact));
        ++monomials;
      }
  std::printf("  capped span (degree 10, exponents ≤ 4): %d monomials on %zu points, worst error %.1e "
              "(largest integral %.2f)\n", monomials, r.rule.points.size(), worst, scale);
  EXPECT_EQ(monomials, 121);
  EXPECT_LT(worst, 5e-15);
}

/// Ball of radius R centred at the corner (1, 1, 1) of the cell [0, 1]³: one octant inside,
/// bounded by the sphere patch θ ∈ [π, 3π/2], φ ∈ [π/2, π] and three quarter disks on the
/// faces x, y, z = 1 (on the fitting box's max faces, so their curved loops matter).
Subvolume sphere_octant(double R, double arc_tolerance) {
  Subvolume sv;
  sv.cell = {{0, 0, 0}, {1, 1, 1}};
  CutPatch sphere;
  sphere.surface = std::make_shared<SphereMap>(Vec3(1, 1, 1), R);
  sphere.orientation = -1;  // σθ × σφ points to the centre
  sphere.loops = {
      polygon_loop({{kPi, kPi / 2}, {1.5 * kPi, kPi / 2}, {1.5 * kPi, kPi}, {kPi, kPi}})};
  sv.patches.push_back(sphere);
  // Quarter disk u, v ≤ 0 in σ = (1, 1, 1) + u e1 + v e2 with e1 × e2 = +x, +y, +z.
  const Vec3 X(1, 0, 0), Y(0, 1, 0), Z(0, 0, 1);
  for (auto [e1, e2] : std::vector<std::pair<Vec3, Vec3>>{{Y, Z}, {Z, X}, {X, Y}}) {
    CutPatch p;
    p.surface = std::make_shared<PlaneMap>(Vec3(1, 1, 1), e1, e2);
    BoundaryLoop l;
    l.order = 2;
    l.points = {{0, 0}};
    append_line(l, {-R, 0});
    append_parabolic(
        l, [&](double t) { return Vec2(R * std::cos(t), R * std::sin(t)); }, kPi, 1.5 * kPi,
        arc_tolerance);
    l.points.back() = {0, -R};
    append_line(l, {0, 0});
    p.loops = {l};
    sv.patches.push_back(p);
  }
  return sv;
}

TEST(VolumeRule, SphereOctant) {
  const double R = 0.9, exact = kPi * R * R * R / 6, exact_x = exact * (1 - 3 * R / 8);
  std::printf(
      "  sphere octant: arc tol | patch degree | flux tol | leaves | rel. volume error | rel. ∫x "
      "error | estimate | ms\n");
  for (double arc_tol : {1e-6, 1e-9})
    for (int degree : {5, 7})
      for (double flux_tol : {0.0, 1e-6, 1e-9, 1e-11}) {
        const Subvolume sv = sphere_octant(R, arc_tol);
        VolumeRuleOptions o;
        o.patch.degree = degree;
        o.flux_tolerance = flux_tol;
        const auto t0 = std::chrono::steady_clock::now();
        const VolumeRule r = volume_rule(sv, o);
        const double ms =
            std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0)
                .count();
        const double ev = std::abs(apply(r.rule, [](const Vec3&) { return 1.0; }) - exact) / exact;
        const double ex =
            std::abs(apply(r.rule, [](const Vec3& x) { return x.x(); }) - exact_x) / exact_x;
        std::printf("  %21.0e | %12d | %8.0e | %6d | %17.2e | %13.2e | %8.1e | %.1f\n", arc_tol,
                    degree, flux_tol, r.flux_leaves, ev, ex, r.flux_error_estimate, ms);
      }
  // Default options with the arcs sampled to 1e-9.
  const VolumeRule r = volume_rule(sphere_octant(R, 1e-9));
  EXPECT_EQ(r.status, RuleStatus::Ok) << to_string(r.status);
  EXPECT_NEAR(r.volume, exact, 1e-8 * exact);
  EXPECT_NEAR(apply(r.rule, [](const Vec3&) { return 1.0; }), exact, 1e-8 * exact);
  EXPECT_NEAR(apply(r.rule, [](const Vec3& x) { return x.x(); }), exact_x, 1e-8 * exact_x);
  EXPECT_LT(r.closure_defect, 1e-8);
}

/// Cylinder of radius r around (cx, cy) through the cell [0, 1]³ (inside = true), or the
/// cell minus the cylinder (end faces with clockwise circular holes).
Subvolume cylinder(double r, const Vec2& c, bool inside, double tolerance) {
  Subvolume sv;
  sv.cell = {{0, 0, 0}, {1, 1, 1}};
  CutPatch lateral;
  lateral.surface = std::make_shared<CylinderMap>(c, r);
  lateral.orientation = inside ? 1 : -1;
  lateral.loops = {polygon_loop({{0, 0}, {2 * kPi, 0}, {2 * kPi, 1}, {0, 1}})};
  sv.patches.push_back(lateral);
  const Vec3 X(1, 0, 0), Y(0, 1, 0), Z(0, 0, 1);
  // Bottom z = 0: uv = (y, x) (e1 × e2 = −z); top z = 1: uv = (x, y).
  for (bool top : {false, true}) {
    CutPatch p;
    p.surface =
        top ? std::make_shared<PlaneMap>(Z, X, Y) : std::make_shared<PlaneMap>(Vec3::Zero(), Y, X);
    const Vec2 cc = top ? c : Vec2(c.y(), c.x());
    BoundaryLoop circle;
    circle.order = 2;
    const double dir = inside ? 1 : -1;
    append_parabolic(
        circle, [&](double t) { return Vec2(cc + r * Vec2(std::cos(dir * t), std::sin(dir * t))); },
        0, 2 * kPi, tolerance, 4);
    circle.points.back() = circle.points.front();
    p.loops = {circle};
    if (!inside) p.loops.insert(p.loops.begin(), polygon_loop({{0, 0}, {1, 0}, {1, 1}, {0, 1}}));
    sv.patches.push_back(p);
  }
  if (!inside) {
    const Faces sides = box_faces(sv.cell.min, sv.cell.max);
    for (int k = 0; k < 4; ++k) sv.patches.push_back(face_patch(sides[k], 1));
  }
  return sv;
}

TEST(VolumeRule, CylinderAndComplement) {
  const double r = 0.3;
  const Vec2 c(0.55, 0.45);
  for (bool inside : {true, false}) {
    const double exact = inside ? kPi * r * r : 1 - kPi * r * r;
    // ∫ x over the cylinder = cx · πr²; over the complement 1/2 − cx · πr².
    const double exact_x = inside ? c.x() * kPi * r * r : 0.5 - c.x() * kPi * r * r;
    const Subvolume sv = cylinder(r, c, inside, 1e-10);
    const auto t0 = std::chrono::steady_clock::now();
    const VolumeRule v = volume_rule(sv);
    const double ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    EXPECT_EQ(v.status, RuleStatus::Ok) << to_string(v.status);
    const double ev = std::abs(apply(v.rule, [](const Vec3&) { return 1.0; }) - exact) / exact;
    const double ex =
        std::abs(apply(v.rule, [](const Vec3& x) { return x.x(); }) - exact_x) / exact_x;
    std::printf(
        "  cylinder %s: rel. volume error %.2e, rel. ∫x error %.2e, leaves %d (depth %d), estimate "
        "%.1e, closure %.1e, %.1f ms\n",
        inside ? "inside " : "outside", ev, ex, v.flux_leaves, v.flux_depth, v.flux_error_estimate,
        v.closure_defect, ms);
    EXPECT_LT(ev, 1e-8);
    EXPECT_LT(ex, 1e-8);
  }
}

TEST(VolumeRule, TinyCornerCut) {
  const Box3 cell{{0, 0, 0}, {1, 1, 1}};
  const double d = std::cbrt(6e-9);  // corner tetrahedron x + y + z ≤ d, volume d³/6 = 1e-9
  const Faces faces = clip_polyhedron(box_faces(cell.min, cell.max), Vec3(1, 1, 1), d);
  const Subvolume sv = polyhedron_subvolume(faces, cell);
  for (FittingBox box : {FittingBox::Tight, FittingBox::Cell}) {
    VolumeRuleOptions o;
    o.box = box;
    const VolumeRule r = volume_rule(sv, o);
    ASSERT_NE(r.status, RuleStatus::EmptyDomain);
    double worst = 0, wmin = 1e300, wmax = -1e300;
    for (double w : r.rule.weights) {
      ASSERT_TRUE(std::isfinite(w));
      wmin = std::min(wmin, w);
      wmax = std::max(wmax, w);
    }
    for (int a = 0; a <= 2; ++a)
      for (int b = 0; a + b <= 2; ++b)
        for (int c = 0; a + b + c <= 2; ++c) {
          auto f = [&](const Vec3& x) {
            return std::pow(x.x(), a) * std::pow(x.y(), b) * std::pow(x.z(), c);
          };
          const double exact = polyhedron_integral(faces, f);
          worst = std::max(worst, std::abs(apply(r.rule, f) - exact) / std::abs(exact));
        }
    std::printf(
        "  corner cut 1e-9 (%s box): status %s, volume %.10e, weights [%.2e, %.2e], worst rel. "
        "error (degree ≤ 2) %.1e\n",
        box == FittingBox::Tight ? "tight" : "cell ", to_string(r.status), r.volume, wmin, wmax,
        worst);
    EXPECT_NEAR(r.volume, 1e-9, (box == FittingBox::Tight ? 1e-13 : 1e-5) * 1e-9);
    EXPECT_LT(worst, box == FittingBox::Tight ? 1e-12 : 1e-2);
    EXPECT_LT(std::max(-wmin, wmax), box == FittingBox::Tight ? 1e-9 : 1e-6);
  }
}

TEST(VolumeRule, NonNegativeWeights) {
  const Box3 cell{{0, 0, 0}, {1, 1, 1}};
  const Faces faces = clip_polyhedron(box_faces(cell.min, cell.max), Vec3(0.3, 0.5, 0.8), 0.7);
  for (int q : {5, 6}) {
    VolumeRuleOptions o;
    o.fit = WeightFit::NonNegative;
    o.points_per_direction = q;
    const VolumeRule r = volume_rule(polyhedron_subvolume(faces, cell), o);
    double wmin = 1e300, worst = 0;
    int positive = 0;
    for (double w : r.rule.weights) wmin = std::min(wmin, w), positive += w > 0;
    for (int a = 0; a <= 2; ++a)
      for (int b = 0; a + b <= 2; ++b)
        for (int c = 0; a + b + c <= 2; ++c) {
          auto f = [&](const Vec3& x) {
            return std::pow(x.x(), a) * std::pow(x.y(), b) * std::pow(x.z(), c);
          };
          worst = std::max(worst, std::abs(apply(r.rule, f) - polyhedron_integral(faces, f)));
        }
    std::printf(
        "  NNLS volume rule (%d³ points): status %s, residual %.1e, %d weights > 0, degree ≤ 2 "
        "error %.1e\n",
        q, to_string(r.status), r.moment_residual, positive, worst);
    EXPECT_GE(wmin, 0.0);
    EXPECT_LT(worst, 1e-10);
  }
  // The sphere octant with non-negative weights.
  VolumeRuleOptions o;
  o.fit = WeightFit::NonNegative;
  const VolumeRule r = volume_rule(sphere_octant(0.9, 1e-9), o);
  double wmin = 1e300;
  for (double w : r.rule.weights) wmin = std::min(wmin, w);
  const double exact = kPi * 0.729 / 6;
  std::printf("  NNLS sphere octant: status %s, residual %.1e, rel. volume error %.1e\n",
              to_string(r.status), r.moment_residual, std::abs(r.volume - exact) / exact);
  EXPECT_GE(wmin, 0.0);
}

TEST(VolumeRule, ReportsReversedOrientationAndRejectsBadInput) {
  const Box3 cell{{0, 0, 0}, {1, 1, 1}};
  Subvolume sv = polyhedron_subvolume(
      clip_polyhedron(box_faces(cell.min, cell.max), Vec3(1, 1, 1), 1.5), cell);
  for (CutPatch& p : sv.patches) p.orientation = -p.orientation;
  EXPECT_EQ(volume_rule(sv).status, RuleStatus::NegativeMeasure);
  sv.patches[0].orientation = 0;
  EXPECT_THROW(volume_rule(sv), Error);
  sv.patches[0].orientation = 1;
  sv.patches[0].surface = nullptr;
  EXPECT_THROW(volume_rule(sv), Error);
  EXPECT_THROW(volume_rule(Subvolume{cell, {}}), Error);
}

TEST(VolumeRule, ConcurrentCallsShareTheCachedSystems) {
  // Different (degree, points) per thread: the fitting systems are built concurrently.
  const Box3 cell{{0, 0, 0}, {1, 1, 1}};
  const Subvolume sv = polyhedron_subvolume(
      clip_polyhedron(box_faces(cell.min, cell.max), Vec3(1, 2, 3), 2.5), cell);
  std::vector<double> serial, parallel(6);
  auto options = [](int k) {
    VolumeRuleOptions o;
    o.degree = 2 + k % 3;
    o.points_per_direction = 6 + k;
    o.patch.degree = 7 + k;
    return o;
  };
  std::vector<std::thread> threads;
  for (int k = 0; k < 6; ++k)
    threads.emplace_back([&, k] {
      parallel[k] =
          apply(volume_rule(sv, options(k)).rule, [](const Vec3& x) { return x.x() * x.y(); });
    });
  for (std::thread& t : threads) t.join();
  for (int k = 0; k < 6; ++k)
    EXPECT_EQ(parallel[k],
              apply(volume_rule(sv, options(k)).rule, [](const Vec3& x) { return x.x() * x.y(); }));
}

TEST(Nnls, MatchesKnownSolution) {
  // min ‖A x − b‖, x ≥ 0 where the unconstrained solution has a negative entry.
  Eigen::MatrixXd A(3, 2);
  A << 1, 0, 0, 1, 1, 1;
  const Eigen::Vector3d b(2, -1, 1);
  const NnlsResult r = solve_nnls(A, b);
  EXPECT_TRUE(r.converged);
  EXPECT_NEAR(r.x[0], 1.5, 1e-15);  // x₂ = 0 ⇒ min (x−2)² + (x−1)²
  EXPECT_EQ(r.x[1], 0.0);
}

}  // namespace
}  // namespace parafab::xfem
