// B-spline evaluation, interpolation and arc-length geometry against closed forms.
#include <gtest/gtest.h>

#include <cmath>

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

TEST(PlaneCurve, ParameterAtInvertsArcLength) {
  const PlaneCurve c(quarter_circle(2.0));
  for (double s = 0; s <= c.length(); s += c.length() / 17) {
    EXPECT_NEAR(c.arc_length_at(c.parameter_at(s)), s, 1e-12);
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
