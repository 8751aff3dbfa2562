// Parallel equilibrium curves from the ODE of Eq. 5.14 (thesis §5.6.2, CVODE): α = π/2 with
// the matching constant curvature is the single helix of Fig. 5.11; any κ(s) > 0 gives a
// curve whose tangent lines lie in the complex (Eq. 5.13a) and whose design is twist-free.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "common/error.h"
#include "rods/parallel_curve.h"
#include "rods/rod_design.h"

namespace parafab {
namespace {

TEST(RodParallelCurve, SingleHelixAtQuarterTurn) {
  ParallelCurveOptions o;
  o.r = 0.5, o.p = 0.5, o.alpha = M_PI / 2;
  // Helix (r cos φ, r sin φ, h φ) with tangent ∥ (0, p, −r) at φ = 0: h = −r²/p.
  const double r = o.r, h = -r * r / o.p, w = std::sqrt(r * r + h * h), kappa = r / (w * w);
  const double L = 4 * M_PI * w;
  const ParallelCurveResult res = generate_parallel_curve([&](double) { return kappa; }, L, 201, o);
  ASSERT_TRUE(res.ok()) << res.message;
  double err = 0;
  for (const auto& p : res.samples) {
    const double phi = p.s / w;
    err = std::max(err, (p.point - Vec3(r * std::cos(phi), r * std::sin(phi), h * phi)).norm());
    EXPECT_NEAR(p.kappa, kappa, 1e-9);
    EXPECT_NEAR(p.torsion, h / (w * w), 1e-6);  // helix torsion h/(r²+h²)
  }
  std::printf("[parallel] helix: max |gamma - closed form| = %.2e m, %ld CVODE steps\n", err, res.steps);
  EXPECT_LT(err, 1e-7);
}

TEST(RodParallelCurve, VaryingCurvatureGivesTwistFreeDesign) {
  ParallelCurveOptions o;
  o.r = 0.3, o.p = 0.2, o.alpha = 1.0;
  auto kappa = [](double s) { return 2.0 + 1.0 * std::sin(3 * s); };
  const ParallelCurveResult res = generate_parallel_curve(kappa, 4.0, 401, o);
  ASSERT_TRUE(res.ok()) << res.message;
  double in_complex = 0;
  for (const auto& p : res.samples) {
    const Vec3 hh = res.c.cross(p.point) + res.c_bar;
    in_complex = std::max(in_complex, std::abs(p.tangent.dot(hh)) / hh.norm());  // Eq. 5.13a
    EXPECT_NEAR(p.kappa, kappa(p.s), 1e-9);
  }
  const RodDesign d = design_rod(res.samples);
  ASSERT_TRUE(d.ok()) << d.message;
  double tw = 0;
  for (const auto& s : d.sections) tw = std::max(tw, std::abs(s.twist) * 4.0);
  std::printf("[parallel] varying kappa: |<T, h>|/|h| %.2e, LP twist ratio %.2e, max |twist|*L %.2e\n",
              in_complex, d.lp.twist_ratio, tw);
  EXPECT_LT(in_complex, 1e-8);
  EXPECT_TRUE(d.lp.parallel);
  EXPECT_LT(tw, 1e-6);
  // The LP recovers the generator's complex up to scale.
  const Eigen::Matrix<double, 6, 1> a = (Eigen::Matrix<double, 6, 1>() << d.lp.c, d.lp.c_bar).finished().normalized();
  const Eigen::Matrix<double, 6, 1> b = (Eigen::Matrix<double, 6, 1>() << res.c, res.c_bar).finished().normalized();
  EXPECT_GT(a.dot(b), 1 - 1e-8);
}

TEST(RodParallelCurve, InvalidInputThrows) {
  EXPECT_THROW(generate_parallel_curve([](double s) { return 1.0 - s; }, 2.0, 10), Error);
  ParallelCurveOptions o;
  o.r = 0;
  EXPECT_THROW(generate_parallel_curve([](double) { return 1.0; }, 2.0, 10, o), Error);
}

}  // namespace
}  // namespace parafab
