// Space B-splines for the rod entry points: the interpolant passes through the points and
// reproduces a helix to O(h⁴) in position; the rational quadratic quarter circle is exact
// (curvature 1/r, zero torsion); invalid data names the field.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "common/error.h"
#include "rods/bspline_curve3.h"

namespace parafab {
namespace {

std::vector<Vec3> helix_points(int n, double r, double p, double t1) {
  std::vector<Vec3> pts;
  for (int i = 0; i < n; ++i) {
    const double t = t1 * i / (n - 1);
    pts.emplace_back(r * std::cos(t), r * std::sin(t), p * t);
  }
  return pts;
}

TEST(BSplineCurve3, InterpolatesPointsAndConvergesOnAHelix) {
  const double r = 0.1, p = 0.03, t1 = 3 * M_PI;
  double prev = 0;
  for (int n : {40, 80, 160}) {
    const auto pts = helix_points(n, r, p, t1);
    const BSplineCurve3 c = interpolate_points3(pts, 3);
    // Chord-length parameters: the i-th point at u = i/(n−1) (equal chords on a helix).
    for (int i = 0; i < n; ++i) EXPECT_LT((c.point(double(i) / (n - 1)) - pts[i]).norm(), 1e-12);
    const SpaceCurve sc = c.space_curve();
    const double L = t1 * std::hypot(r, p), kappa = r / (r * r + p * p);
    EXPECT_NEAR(sc.length(), L, 1e-4 * L);
    double err = 0;
    for (int k = 10; k <= 90; ++k)  // curvature away from the free ends
      err = std::max(err, std::abs(sc.at_arc_length(L * k / 100).kappa - kappa) / kappa);
    std::printf("[bspline3] helix n = %d: max rel. curvature error (interior) %.2e\n", n, err);
    if (prev > 0) EXPECT_LT(err, prev / 2.5);
    prev = err;
  }
}

TEST(BSplineCurve3, RationalQuarterCircleIsExact) {
  const double w = std::sqrt(0.5), r = 0.2;
  const BSplineCurve3 c(2, {0, 0, 0, 1, 1, 1}, {Vec3(r, 0, 0.5), Vec3(r, r, 0.5), Vec3(0, r, 0.5)},
                        {1, w, 1});
  const SpaceCurve sc = c.space_curve();
  EXPECT_NEAR(sc.length(), M_PI / 2 * r, 1e-12);
  for (double u : {0.0, 0.3, 0.7, 1.0}) {
    const RodSample s = sc.at_parameter(u);
    EXPECT_NEAR(s.point.head<2>().norm(), r, 1e-14);
    EXPECT_NEAR(s.kappa, 1 / r, 1e-9);
    EXPECT_NEAR(s.binormal.z(), 1.0, 1e-12);
  }
}

TEST(BSplineCurve3, InvalidInputNamesTheField) {
  auto msg = [](auto f) {
    try {
      f();
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_NE(msg([] { interpolate_points3({Vec3(0, 0, 0)}); }).find("need at least 2 points"), std::string::npos);
  EXPECT_NE(msg([] { interpolate_points3({Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(1, 0, 0)}); })
                .find("curve.points[2] repeats curve.points[1]"),
            std::string::npos);
  EXPECT_NE(msg([] { interpolate_points3({Vec3(0, 0, 0), Vec3(NAN, 0, 0)}); }).find("curve.points[1] is not finite"),
            std::string::npos);
  EXPECT_NE(msg([] { BSplineCurve3(3, {0, 1}, {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(2, 1, 0), Vec3(3, 0, 1)}); })
                .find("curve.bspline.knots: expected 8 knots"),
            std::string::npos);
  EXPECT_NE(msg([] { BSplineCurve3(1, {0, 0, 1, 1}, {Vec3(0, 0, 0), Vec3(1, 0, 0)}, {1, -1}); })
                .find("curve.bspline.weights[1] must be positive"),
            std::string::npos);
}

}  // namespace
}  // namespace parafab
