// B-spline evaluation, interpolation and arc-length geometry against closed forms.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>

#include "common/bspline.h"
#include "common/error.h"
#include "common/plane_curve.h"

namespace parafab {
namespace {

// Exact NURBS quarter circle of radius r (degree 2, weights 1, √2/2, 1).
BSplineCurve2 quarter_circle(double r) {
  return BSplineCurve2(2, {0, 0, 0, 1, 1, 1}, {{r, 0}, {r, r}, {0, r}},
                       {1.0, std::sqrt(0.5), 1.0});
}

TEST(BSplineCurve2, RationalQuarterCircleHasConstantCurvature) {
  const double r = 0.37;
  const PlaneCurve c(quarter_circle(r));
  EXPECT_NEAR(c.length(), M_PI * r / 2, 1e-12);
  for (double u = 0; u <= 1.0; u += 0.05) {
    const CurvePoint p = c.at_parameter(u);
    EXPECT_NEAR(p.point.norm(), r, 1e-14);
    EXPECT_NEAR(p.kappa, 1.0 / r, 1e-10);
    EXPECT_NEAR(p.dkappa_ds, 0.0, 1e-8);
    // Arc length from the angle of the point.
    EXPECT_NEAR(p.s, r * std::atan2(p.point.y(), p.point.x()), 1e-12);
  }
}

// Textbook Cox–de Boor recursion (N_{i,0} = [u_i ≤ u < u_{i+1}], N_{i,p} from N_{i,p−1} and
// N_{i+1,p−1}) and its derivative formula d^k N_{i,p} = p (d^{k−1}N_{i,p−1}/(u_{i+p} − u_i)
// − d^{k−1}N_{i+1,p−1}/(u_{i+p+1} − u_{i+1})): an evaluation independent of bspline.cpp's.
double textbook_basis(const std::vector<double>& U, int i, int p, int k, double u, int last_span) {
  if (k > p) return 0.0;
  if (p == 0) {
    // The half-open interval, except that the last non-empty span also owns its end.
    return (U[i] <= u && (u < U[i + 1] || (i == last_span && u <= U[i + 1]))) ? 1.0 : 0.0;
  }
  auto ratio = [](double a, double b) { return b == 0.0 ? 0.0 : a / b; };
  if (k == 0)
    return ratio(u - U[i], U[i + p] - U[i]) * textbook_basis(U, i, p - 1, 0, u, last_span) +
           ratio(U[i + p + 1] - u, U[i + p + 1] - U[i + 1]) *
               textbook_basis(U, i + 1, p - 1, 0, u, last_span);
  return p * (ratio(textbook_basis(U, i, p - 1, k - 1, u, last_span), U[i + p] - U[i]) -
              ratio(textbook_basis(U, i + 1, p - 1, k - 1, u, last_span), U[i + p + 1] - U[i + 1]));
}

// C^(k)(u), k = 0..3, of a (rational) curve from the textbook basis and the quotient rule.
std::array<Vec2, 4> textbook_derivatives(const BSplineCurve2& c, double u) {
  const auto& U = c.knots();
  int last_span = static_cast<int>(U.size()) - 2;
  while (!(U[last_span + 1] > U[last_span])) --last_span;
  std::array<Vec2, 4> A;
  std::array<double, 4> W{};
  for (int k = 0; k < 4; ++k) {
    A[k].setZero();
    for (int i = 0; i < c.pole_count(); ++i) {
      const double w = c.rational() ? c.weights()[i] : 1.0;
      const double N = textbook_basis(U, i, c.degree(), k, u, last_span);
      A[k] += N * w * c.poles()[i];
      W[k] += N * w;
    }
  }
  if (!c.rational()) return A;
  std::array<Vec2, 4> C;
  C[0] = A[0] / W[0];
  C[1] = (A[1] - W[1] * C[0]) / W[0];
  C[2] = (A[2] - 2 * W[1] * C[1] - W[2] * C[0]) / W[0];
  C[3] = (A[3] - 3 * W[1] * C[2] - 3 * W[2] * C[1] - W[3] * C[0]) / W[0];
  return C;
}

// derivatives() sums per-span Taylor forms found through a bucket index; on random curves of every degree 1..7 (a double
// interior knot, rational and not, poles ~100 away from the origin) it must agree with the
// textbook recursion, also at the knots and the ends, to round-off of each derivative's size.
TEST(BSplineCurve2, TaylorFormsMatchTheTextbookRecursionForEveryDegree) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  double worst = 0.0;
  for (int degree = 1; degree <= 7; ++degree)
    for (int rational = 0; rational < 2; ++rational) {
      const int poles = degree + 6;
      std::vector<double> knots(degree + 1, -0.3);
      std::vector<double> interior;
      for (int i = 0; i < poles - degree - 1; ++i) interior.push_back(-0.3 + 2.1 * unit(rng));
      std::sort(interior.begin(), interior.end());
      if (degree >= 2) interior[2] = interior[1];  // a double knot
      knots.insert(knots.end(), interior.begin(), interior.end());
      knots.insert(knots.end(), degree + 1, 1.8);
      std::vector<Vec2> P;
      std::vector<double> w;
      for (int i = 0; i < poles; ++i) {
        P.emplace_back(100 + 5 * unit(rng), -60 + 5 * unit(rng));
        if (rational) w.push_back(0.4 + unit(rng));
      }
      const BSplineCurve2 c(degree, knots, P, w);
      std::vector<double> us;
      for (int j = 0; j <= 200; ++j) us.push_back(-0.3 + 2.1 * j / 200);
      for (double k : interior)  // the knots and their neighbours (find_span's bucket edges)
        for (double u : {std::nextafter(k, -1e9), k, std::nextafter(k, 1e9)}) us.push_back(u);
      std::array<double, 4> scale{};
      std::vector<std::array<Vec2, 4>> ref;
      for (double u : us) {
        ref.push_back(textbook_derivatives(c, u));
        for (int k = 0; k < 4; ++k) scale[k] = std::max(scale[k], ref.back()[k].norm());
      }
      for (size_t j = 0; j < us.size(); ++j) {
        const auto d = c.derivatives(us[j]);
        for (int k = 0; k < 4; ++k) {
          if (scale[k] == 0.0) continue;  // a line's second and third derivatives
          const double e = (d[k] - ref[j][k]).norm() / scale[k];
          worst = std::max(worst, e);
          ASSERT_LT(e, 1e-13) << "degree " << degree << (rational ? " rational" : "") << " u = "
                              << us[j] << " derivative " << k;
        }
      }
    }
  std::printf("largest difference to the textbook recursion: %.2e of the derivative's size\n", worst);
}

// parameter_at (Newton that may stop on the predicted size of its last step's residual)
// against bisection on arc_length_at, on a rational arc and a 400-point interpolant.
TEST(PlaneCurve, ParameterAtInvertsArcLength) {
  std::vector<Vec2> pts;
  for (int i = 0; i < 400; ++i) {
    const double x = -0.135 + 0.27 * i / 399, t = x / 0.15;
    pts.emplace_back(x, 0.06 * (t * t * t - t));
  }
  for (const PlaneCurve& c : {PlaneCurve(quarter_circle(2.0)), PlaneCurve(interpolate_points(pts, 4))}) {
    const double l = c.length();
    double worst_s = 0, worst_u = 0;
    for (int k = 0; k <= 1000; ++k) {
      const double s = l * k / 1000, u = c.parameter_at(s);
      double lo = c.first_parameter(), hi = c.last_parameter();
      for (int it = 0; it < 200 && hi - lo > 0; ++it) {
        const double mid = 0.5 * (lo + hi);
        if (mid <= lo || mid >= hi) break;
        (c.arc_length_at(mid) < s ? lo : hi) = mid;
      }
      const double speed = c.bspline().derivatives(u, 1)[1].norm();
      worst_s = std::max(worst_s, std::abs(c.arc_length_at(u) - s) / l);
      worst_u = std::max(worst_u, std::abs(u - 0.5 * (lo + hi)) * speed / l);  // in units of length
    }
    std::printf("parameter_at: |s(u) - s| <= %.1e l, |u - u_bisection| |γ'| <= %.1e l\n", worst_s, worst_u);
    EXPECT_LE(worst_s, 2e-15);
    EXPECT_LE(worst_u, 4e-15);
  }
}

TEST(Interpolation, PassesThroughPointsAndReproducesCubics) {
  std::vector<Vec2> pts;
  for (int i = 0; i <= 20; ++i) {
    const double x = -1.0 + 0.1 * i;
    pts.emplace_back(x, x * x * x - x);
  }
  const BSplineCurve2 c = interpolate_points(pts, 4);
  EXPECT_EQ(c.degree(), 4);
  const PlaneCurve pc(c);
  // Interpolation at the chord-length parameters: every point is on the curve.
  for (const Vec2& p : pts) {
    double best = 1e9;
    for (int k = 0; k <= 4000; ++k) best = std::min(best, (c.point(k / 4000.0) - p).norm());
    EXPECT_LT(best, 2e-3);
  }
  EXPECT_NEAR((c.point(c.first_parameter()) - pts.front()).norm(), 0.0, 1e-12);
  EXPECT_NEAR((c.point(c.last_parameter()) - pts.back()).norm(), 0.0, 1e-12);
}

TEST(Interpolation, RejectsBadPointsNamingThem) {
  EXPECT_THROW(interpolate_points({}, 4), Error);
  EXPECT_THROW(interpolate_points({{0, 0}}, 4), Error);
  try {
    interpolate_points({{0, 0}, {1, 0}, {1, 0}, {2, 1}}, 3);
    FAIL() << "repeated point accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("curve.points[2] repeats curve.points[1]"), std::string::npos)
        << e.what();
  }
  try {
    interpolate_points({{0, 0}, {1, NAN}, {2, 1}}, 3);
    FAIL() << "NaN accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("curve.points[1]"), std::string::npos) << e.what();
  }
}

TEST(BSplineCurve2, RejectsInconsistentData) {
  EXPECT_THROW(BSplineCurve2(2, {0, 0, 0, 1, 1}, {{0, 0}, {1, 1}, {2, 0}}), Error);
  EXPECT_THROW(BSplineCurve2(2, {0, 0, 0, 1, 1, 1}, {{0, 0}, {1, 1}, {2, 0}}, {1, -1, 1}), Error);
  EXPECT_THROW(BSplineCurve2(2, {0, 0, 1, 0, 1, 1}, {{0, 0}, {1, 1}, {2, 0}}), Error);
  // Collapsed poles: zero speed everywhere.
  EXPECT_THROW(PlaneCurve(BSplineCurve2(1, {0, 0, 1, 1}, {{1, 1}, {1, 1}})), Error);
}

}  // namespace
}  // namespace parafab
