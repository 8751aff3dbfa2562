// Strip design (thesis §4.3) against closed forms: elasticae sampled from constant-stiffness
// equilibria (Eq. 4.3) must give R = 1 and recover the line; circles give b = 0; every
// reason of Theorem 1 is produced by a curve built to fail it.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>

#include "common/error.h"
#include "strips/strip_design.h"

namespace parafab {
namespace {

// Curvature as a function of arc length and position: κ(s, γ).
using CurvatureLaw = std::function<double(double s, const Vec2& g)>;

// Integrates γ' = (cos α, sin α), α' = κ(s, γ) with classical RK4 from s0 (where γ = g0,
// α = alpha0) to s1 in `steps` steps; returns every `stride`-th point.
std::vector<Vec2> integrate_curve(const CurvatureLaw& kappa, Vec2 g0, double alpha0, double s0,
                                  double s1, int steps, int stride) {
  Eigen::Vector3d y(g0.x(), g0.y(), alpha0);
  auto f = [&](double s, const Eigen::Vector3d& q) {
    return Eigen::Vector3d(std::cos(q(2)), std::sin(q(2)), kappa(s, q.head<2>()));
  };
  const double h = (s1 - s0) / steps;
  std::vector<Vec2> out{y.head<2>()};
  for (int i = 0; i < steps; ++i) {
    const double s = s0 + i * h;
    const Eigen::Vector3d k1 = f(s, y), k2 = f(s + h / 2, y + h / 2 * k1),
                          k3 = f(s + h / 2, y + h / 2 * k2), k4 = f(s + h, y + h * k3);
    y += h / 6 * (k1 + 2 * k2 + 2 * k3 + k4);
    if ((i + 1) % stride == 0) out.push_back(y.head<2>());
  }
  return out;
}

// Curve through κ(s) on [s0, s1] whose point at s = 0 is the origin with tangent +x.
BSplineCurve2 curve_from_curvature(const std::function<double(double)>& kappa, double s0,
                                   double s1, int points = 801) {
  const auto law = [&](double s, const Vec2&) { return kappa(s); };
  const int stride = 20;
  // Backwards from the origin: the reversed curve has curvature −κ(−σ).
  auto back = integrate_curve([&](double s, const Vec2& g) { return -law(-s, g); }, {0, 0}, M_PI,
                              0.0, -s0, (points / 2) * stride, stride);
  auto fwd = integrate_curve(law, {0, 0}, 0.0, 0.0, s1, (points / 2) * stride, stride);
  std::vector<Vec2> pts(back.rbegin(), back.rend() - 1);
  pts.insert(pts.end(), fwd.begin(), fwd.end());
  return interpolate_points(pts, 5);
}

StripDesignOptions options() {
  StripDesignOptions o;
  o.youngs_modulus = 3e9;
  o.thickness = 0.5e-3;
  o.min_width = 0.01;
  return o;
}

// Elastica of Eq. 4.3 with constant K: κ = (a + ⟨b, γ⟩)/K, sampled and interpolated.
BSplineCurve2 elastica(double a, const Vec2& b, Vec2 g0, double alpha0, double length) {
  const double K = 1.0;
  const auto law = [&](double, const Vec2& g) { return (a + b.dot(g)) / K; };
  return interpolate_points(integrate_curve(law, g0, alpha0, 0.0, length, 40000, 20), 5);
}

TEST(StripDesign, ElasticaWithoutInflectionHasUnitRatioAndItsLine) {
  const double a = 1.0;
  const Vec2 b(0.4, -0.3);
  const StripDesign d = design_strip(elastica(a, b, {0, 0}, 0.3, 2.0), options());
  ASSERT_TRUE(d.feasible) << d.reason;
  EXPECT_TRUE(d.zeros.empty());
  EXPECT_NEAR(d.R, 1.0, 1e-6);
  EXPECT_NEAR(d.b.x() / d.a, b.x() / a, 1e-6);
  EXPECT_NEAR(d.b.y() / d.a, b.y() / a, 1e-6);
  EXPECT_TRUE(d.converged);
}

TEST(StripDesign, ElasticaWithInflectionsHasUnitRatioAndLineThroughThem) {
  // κ = 0.5 − 3y: inflections on the line y = 1/6.
  const double a = 0.5;
  const Vec2 b(0.0, -3.0);
  const StripDesign d = design_strip(elastica(a, b, {0, 0.5}, 0.0, 6.0), options());
  ASSERT_TRUE(d.feasible) << d.reason;
  ASSERT_GE(d.zeros.size(), 2u);
  for (const auto& z : d.zeros) EXPECT_NEAR(z.at.point.y(), 1.0 / 6.0, 1e-7);
  EXPECT_NEAR(d.R, 1.0, 1e-6);
  EXPECT_NEAR(d.b.x() / d.a, b.x() / a, 1e-6);
  EXPECT_NEAR(d.b.y() / d.a, b.y() / a, 1e-6);
}

TEST(StripDesign, CircularArcNeedsConstantStiffness) {
  // Exact rational quadratic arc of 120° and radius 0.25 m.
  const double r = 0.25, w = std::cos(M_PI / 3);
  const BSplineCurve2 arc(2, {0, 0, 0, 1, 1, 1},
                          {{r, 0}, {r, r * std::tan(M_PI / 3)}, {r * std::cos(2 * M_PI / 3), r * std::sin(2 * M_PI / 3)}},
                          {1, w, 1});
  const StripDesign d = design_strip(arc, options());
  ASSERT_TRUE(d.feasible);
  EXPECT_NEAR(d.R, 1.0, 1e-9);
  EXPECT_LT(d.b.norm() * r / std::abs(d.a), 1e-9);  // b = 0: the line is at infinity
  EXPECT_NEAR(d.length, r * 2 * M_PI / 3, 1e-12);
  // Width and outline: constant min_width, closed polygon around the straight centreline.
  for (double wdt : d.width) EXPECT_NEAR(wdt, 0.01, 1e-11);
  ASSERT_EQ(d.outline.size(), 2 * d.samples.size());
  EXPECT_NEAR(d.outline.front().y(), -0.005, 1e-12);
  EXPECT_NEAR(d.outline.back().y(), 0.005, 1e-12);
  EXPECT_NEAR(d.bending_stiffness[0], 3e9 * 0.01 * std::pow(0.5e-3, 3) / 12, 1e-12);
}

TEST(StripDesign, TwoInflectionsGiveTheLineThroughThem) {
  // y = x⁴ − x² on [−0.8, 0.8]: inflections at x = ±1/√6, y = −5/36.
  std::vector<Vec2> pts;
  for (int i = 0; i <= 400; ++i) {
    const double x = -0.8 + 1.6 * i / 400;
    pts.emplace_back(x, x * x * x * x - x * x);
  }
  const StripDesign d = design_strip(interpolate_points(pts, 5), options());
  ASSERT_TRUE(d.feasible) << d.reason;
  ASSERT_EQ(d.zeros.size(), 2u);
  EXPECT_NEAR(d.zeros[0].at.point.x(), -1 / std::sqrt(6.0), 1e-7);
  EXPECT_NEAR(d.zeros[1].at.point.x(), 1 / std::sqrt(6.0), 1e-7);
  // The line a + b·x = 0 is y = −5/36: b ∥ (0, 1) and a/b_y = 5/36.
  EXPECT_LT(std::abs(d.b.x()) / std::abs(d.b.y()), 1e-7);
  EXPECT_NEAR(d.a / d.b.y(), 5.0 / 36.0, 1e-7);
  EXPECT_GT(d.R, 1.0);
}

TEST(StripDesign, DualAndPrimalLpFormsAgree) {
  std::vector<Vec2> pts;
  for (int i = 0; i <= 200; ++i) {
    const double t = 0.2 + 2.5 * i / 200;
    pts.emplace_back(2 * std::cos(t), std::sin(t));
  }
  const BSplineCurve2 c = interpolate_points(pts, 4);
  StripDesignOptions o = options();
  const StripDesign dual = design_strip(c, o);
  o.lp_form = LpForm::Primal;
  const StripDesign primal = design_strip(c, o);
  ASSERT_TRUE(dual.feasible && primal.feasible);
  EXPECT_NEAR(dual.R, primal.R, 1e-9);
  EXPECT_NEAR(dual.a, primal.a, 1e-7 * std::abs(primal.a));
}

TEST(StripDesign, StraightCurveTakesAnyConstantStiffness) {
  const StripDesign d = design_strip(BSplineCurve2(1, {0, 0, 1, 1}, {{0, 0}, {0.3, 0.4}}), options());
  ASSERT_TRUE(d.feasible);
  EXPECT_EQ(d.R, 1.0);
  EXPECT_NEAR(d.length, 0.5, 1e-14);
  for (const auto& s : d.samples) EXPECT_EQ(s.K, 1.0);
}

// ---- Theorem 1: one curve per reason ---------------------------------------------------

TEST(StripInfeasible, InflectionLineCrossesCurve) {
  std::vector<Vec2> pts;  // y = x⁴ − x² on [−1.2, 1.2] meets y = −5/36 again at x = ±0.9129
  for (int i = 0; i <= 400; ++i) {
    const double x = -1.2 + 2.4 * i / 400;
    pts.emplace_back(x, x * x * x * x - x * x);
  }
  const BSplineCurve2 c = interpolate_points(pts, 5);
  const StripDesign d = design_strip(c, options());
  EXPECT_FALSE(d.feasible);
  EXPECT_EQ(d.reason_code, "line_crosses_curve");
  const Vec2 at = PlaneCurve(c).at_arc_length(d.reason_s).point;
  EXPECT_NEAR(std::abs(at.x()), std::sqrt(5.0 / 6.0), 1e-6);
  EXPECT_NE(d.reason.find("crosses"), std::string::npos);
}

TEST(StripInfeasible, InflectionsNotCollinear) {
  std::vector<Vec2> pts;  // y = sin x + 0.05 x²: three inflections off any common line
  for (int i = 0; i <= 600; ++i) {
    const double x = -0.5 + 7.5 * i / 600;
    pts.emplace_back(x, std::sin(x) + 0.05 * x * x);
  }
  const StripDesign d = design_strip(interpolate_points(pts, 5), options());
  EXPECT_FALSE(d.feasible);
  EXPECT_EQ(d.reason_code, "inflections_not_collinear");
  EXPECT_EQ(d.zeros.size(), 3u);
}

TEST(StripInfeasible, LineTangentAtInflection) {
  // κ = c s (3 − s)(1 + 0.3 s): inflections at s = 0 (the origin, tangent +x) and s = 3; c is
  // chosen (bisection on y(3)) so the second inflection lies on the x axis, which is the
  // tangent at the first.
  const auto kappa = [](double c) {
    return [c](double s) { return c * s * (3 - s) * (1 + 0.3 * s); };
  };
  const auto y_at_3 = [&](double c) {
    const auto k = kappa(c);
    return integrate_curve([&](double s, const Vec2&) { return k(s); }, {0, 0}, 0, 0, 3, 20000, 20000).back();
  };
  double lo = 0.8, hi = 0.85;  // y(3) changes sign in here, with x(3) ≈ 0.33
  ASSERT_LT(y_at_3(lo).y() * y_at_3(hi).y(), 0.0);
  for (int i = 0; i < 60; ++i) {
    const double mid = 0.5 * (lo + hi);
    (y_at_3(mid).y() * y_at_3(lo).y() > 0 ? lo : hi) = mid;
  }
  const double c = 0.5 * (lo + hi);
  ASSERT_GT(std::abs(y_at_3(c).x()), 0.1);
  const StripDesign d =
      design_strip(curve_from_curvature(kappa(c), -0.3, 3.3), options());
  EXPECT_FALSE(d.feasible);
  EXPECT_EQ(d.reason_code, "line_tangent_at_inflection") << d.reason;
  EXPECT_NEAR(d.reason_s, 0.3, 1e-6);  // the first inflection, 0.3 from the start
}

TEST(StripInfeasible, CurvatureNotSecantBounded) {
  for (int power : {4, 5}) {  // y = x⁴: κ touches 0; y = x⁵: κ ∝ x³ has κ' = 0
    std::vector<Vec2> pts;
    for (int i = 0; i <= 200; ++i) {
      const double x = -1.0 + 2.0 * i / 200;
      pts.emplace_back(x, std::pow(x, power));
    }
    const StripDesign d = design_strip(interpolate_points(pts, 5), options());
    EXPECT_FALSE(d.feasible) << "y = x^" << power;
    EXPECT_EQ(d.reason_code, "not_secant_bounded") << "y = x^" << power << ": " << d.reason;
  }
}

TEST(StripInfeasible, StraightPieceInsideBentCurve) {
  // Cubic B-spline whose first span has four collinear poles: κ ≡ 0 there.
  const BSplineCurve2 c(3, {0, 0, 0, 0, 1, 2, 3, 3, 3, 3},
                        {{0, 0}, {1, 0}, {2, 0}, {3, 0}, {4, 1}, {5, 3}});
  const StripDesign d = design_strip(c, options());
  EXPECT_FALSE(d.feasible);
  EXPECT_EQ(d.reason_code, "curvature_vanishes_on_interval");
}

TEST(StripInfeasible, NoLineThroughSingleInflectionAvoidsCurve) {
  // One inflection at s = 0; the arm beyond it spirals outwards by more than a full turn,
  // so it surrounds the inflection and every line through it.
  const auto kappa = [](double s) { return s / std::sqrt(s * s + 0.09) / (1 + 0.15 * std::abs(s)); };
  const StripDesign d = design_strip(curve_from_curvature(kappa, -2.0, 10.0, 1201), options());
  EXPECT_FALSE(d.feasible);
  EXPECT_EQ(d.reason_code, "no_line_avoids_curve") << d.reason;
  EXPECT_NEAR(d.reason_s, 2.0, 1e-6);
}

TEST(StripDesign, RejectsInvalidMaterialNamingTheField) {
  const BSplineCurve2 c(1, {0, 0, 1, 1}, {{0, 0}, {1, 0}});
  StripDesignOptions o = options();
  o.thickness = 0;
  try {
    design_strip(c, o);
    FAIL() << "zero thickness accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("material.thickness"), std::string::npos) << e.what();
  }
  o = options();
  o.youngs_modulus = -1;
  EXPECT_THROW(design_strip(c, o), Error);
}

}  // namespace
}  // namespace parafab
