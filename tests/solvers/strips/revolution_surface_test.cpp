// Surfaces of revolution (thesis §4.8.4): CVODE meridians against a closed form (the sphere:
// a = 0, b = e₁/ρ gives κ = 1/ρ) and against RK4; the tiling strips (width ∝ distance to the
// axis) simulated by the plane rod simulator bend back onto the meridian.
#include <gtest/gtest.h>

#include <cmath>

#include "common/error.h"
#include "strips/plane_rod_simulator.h"
#include "strips/revolution_surface.h"
#include "strip_test_curves.h"

namespace parafab {
namespace {

TEST(RevolutionSurface, SphereMeridianIsACircle) {
  const double rho = 0.3;
  RevolutionMeridianOptions o;
  o.a = 0;
  o.b = {1 / rho, 0};
  o.start = {rho, 0};
  o.start_angle = M_PI / 2;
  o.length = 0.45 * M_PI * rho;  // just below the pole
  const RevolutionMeridian m = integrate_revolution_meridian(o);
  ASSERT_TRUE(m.complete) << m.message;
  double err = 0;
  for (size_t k = 0; k < m.points.size(); ++k) {
    err = std::max(err, std::abs(m.points[k].norm() - rho));
    err = std::max(err, (m.points[k] - rho * Vec2(std::cos(m.s[k] / rho), std::sin(m.s[k] / rho))).norm());
  }
  EXPECT_LT(err / rho, 1e-8);
  EXPECT_LT(m.residual, 1e-4);  // central differences of α on 401 points
}

TEST(RevolutionSurface, MeridianAgreesWithRk4AndStopsAtTheAxis) {
  RevolutionMeridianOptions o;
  o.a = 1.5;
  o.b = {2.0, -25.0};
  o.start = {0.12, 0};
  o.start_angle = 1.3;
  o.length = 0.5;
  const RevolutionMeridian m = integrate_revolution_meridian(o);
  ASSERT_TRUE(m.complete) << m.message;
  auto f = [&](double, const test::State<3>& q) {
    return test::State<3>(std::cos(q(2)), std::sin(q(2)), (o.a + o.b.x() * q(0) + o.b.y() * q(1)) / q(0));
  };
  const auto ref = test::rk4<3>(f, test::State<3>(o.start.x(), o.start.y(), o.start_angle), 0, o.length, 40000, 100);
  ASSERT_EQ(ref.size(), m.points.size());
  double err = 0;
  for (size_t k = 0; k < ref.size(); ++k) err = std::max(err, (m.points[k] - Vec2(ref[k](0), ref[k](1))).norm());
  std::printf("[ meridian a = 1.5, b = (2, -25) ] max |CVODE - RK4| = %.3g m, %ld CVODE steps\n", err, m.steps);
  EXPECT_LT(err, 1e-8);
  // A meridian heading for the axis stops there with a reason.
  RevolutionMeridianOptions in = o;
  in.start_angle = M_PI;  // straight at the axis
  in.a = 0, in.b = {0, 0};
  const RevolutionMeridian stop = integrate_revolution_meridian(in);
  EXPECT_FALSE(stop.complete);
  EXPECT_NEAR(stop.reached_length, 0.12, 1e-6);
  EXPECT_NE(stop.message.find("axis"), std::string::npos);
  in.start = {0, 0};
  EXPECT_THROW(integrate_revolution_meridian(in), Error);
}

TEST(RevolutionSurface, TilingStripsBendOntoTheMeridian) {
  // A vase-like meridian with an inflection: κ = (1.5 + 2x − 25y)/x changes sign.
  RevolutionMeridianOptions o;
  o.a = 1.5;
  o.b = {2.0, -25.0};
  o.start = {0.12, 0};
  o.start_angle = 1.3;
  o.length = 0.5;
  const RevolutionMeridian m = integrate_revolution_meridian(o);
  ASSERT_TRUE(m.complete);
  int sign_changes = 0;
  for (size_t k = 1; k < m.kappa.size(); ++k) sign_changes += (m.kappa[k] > 0) != (m.kappa[k - 1] > 0);
  EXPECT_GE(sign_changes, 1);
  const RevolutionStrips strips = revolution_strips(m, {16, 3e9, 0.5e-3});
  for (size_t k = 0; k < m.s.size(); ++k)
    EXPECT_NEAR(strips.width[k], 2 * std::tan(M_PI / 16) * m.points[k].x(), 1e-15);
  // Simulate one strip with K ∝ width, clamped at the meridian's end points and angles.
  PlaneRodProblem p;
  p.length = o.length;
  p.stiffness_s = strips.s;
  p.stiffness = strips.bending_stiffness;
  p.start_point = m.points.front();
  p.end_point = m.points.back();
  p.start_angle = m.angle.front();
  p.end_angle = m.angle.back();
  PlaneRodOptions ro;
  ro.edges = 800;
  // Initial guess: the chord angles of the meridian's 401 outputs, two edges per chord.
  for (int j = 0; j < ro.edges; ++j) {
    const Vec2 d = m.points[j / 2 + 1] - m.points[j / 2];
    p.initial_angles.push_back(std::atan2(d.y(), d.x()));
  }
  const PlaneRodResult r = simulate_plane_rod(p, ro);
  ASSERT_TRUE(r.converged) << r.message;
  double dev = 0;
  for (int k = 0; k < 401; ++k) {
    const size_t node = static_cast<size_t>(k * 2);  // 800 edges, 401 outputs: every 2nd node
    dev = std::max(dev, (r.nodes[node] - m.points[k]).norm());
  }
  std::printf("[ tiling strip, 16 around, R = %.3f ] deviation of the simulated strip %.3g\n",
              strips.R, dev / o.length);
  EXPECT_LT(dev / o.length, 1e-5);
}

}  // namespace
}  // namespace parafab
