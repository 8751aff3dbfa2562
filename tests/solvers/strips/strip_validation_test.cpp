// Forward simulation (thesis §4.6.1) as the proof of the designs: the simulator against
// closed forms (circular arc under end moments, cantilever under its own weight), then
// designed strips (0–3 inflections, a spiral; with and without gravity) simulated back onto
// their target curves, converging under refinement; and the sag of a heavy strip designed
// without the gravity term.
#include <gtest/gtest.h>

#include <map>
#include <string>

#include <cmath>

#include "strips/strip_validation.h"
#include "strip_test_curves.h"

namespace parafab {
namespace {

TEST(PlaneRodSimulator, ConstantStiffnessBetweenClampsIsACircularArc) {
  const double r = 0.2, theta = 2.0, l = r * theta;
  PlaneRodProblem p;
  p.length = l;
  p.stiffness_s = {0, l};
  p.stiffness = {3.0, 3.0};
  p.start_point = {0, 0};
  p.end_point = {r * std::sin(theta), r * (1 - std::cos(theta))};
  p.start_angle = 0;
  p.end_angle = theta;
  for (int N : {100, 400}) {
    PlaneRodOptions o;
    o.edges = N;
    const PlaneRodResult res = simulate_plane_rod(p, o);
    ASSERT_TRUE(res.converged) << res.message;
    double err = 0;
    for (const auto& x : res.nodes) err = std::max(err, std::abs((x - Vec2(0, r)).norm() - r));
    EXPECT_LT(err / l, N == 100 ? 1e-3 : 1e-4) << "N = " << N;
    // Uniform curvature up to the O(h²) mismatch between the polygon and the clamps.
    for (size_t k = 1; k + 1 < res.curvature.size(); ++k)
      EXPECT_NEAR(res.curvature[k], 1 / r, (N == 100 ? 1e-3 : 1e-4) / r);
  }
}

TEST(PlaneRodSimulator, CantileverUnderOwnWeightMatchesBeamTheory) {
  // Clamped at s = 0, end free (position and angle): tip deflection q l⁴ / (8 K) for a
  // small uniform load q = K |e|; geometric nonlinearity is O((δ/l)²).
  const double l = 0.3, K = 1.0, q = 0.01;  // δ/l = q l³ / 8 = 3.4e-5
  PlaneRodProblem p;
  p.length = l;
  p.stiffness_s = {0, l};
  p.stiffness = {K, K};
  p.end_point = {l, 0};
  p.boundary.end = {true, true, true};
  p.load = {0, -q / K};
  PlaneRodOptions o;
  o.edges = 800;
  const PlaneRodResult res = simulate_plane_rod(p, o);
  ASSERT_TRUE(res.converged) << res.message;
  const double delta = -res.nodes.back().y();
  const double ref = q * std::pow(l, 4) / (8 * K);
  EXPECT_NEAR(delta, ref, 1e-3 * ref);
  // Root moment q l² / 2: κ(0) = −q l² / (2K).
  EXPECT_NEAR(res.curvature.front(), -q * l * l / (2 * K), 2e-3 * q * l * l / (2 * K));
}

StripDesignOptions cardboard(bool gravity) {
  StripDesignOptions o;
  o.gravity.enabled = gravity;  // βl³ = 8.86e-4 m³ (thesis, 200 gsm cardboard)
  return o;
}

struct Named { const char* name; BSplineCurve2 curve; };
std::vector<Named> designs() {
  return {{"no inflection (ellipse arc)", test::ellipse_arc()},
          {"one inflection", test::one_inflection()},
          {"two inflections", test::two_inflections()},
          {"three inflections", test::three_inflections()},
          {"spiral (1.5 turns)", test::spiral()}};
}

void expect_simulates_back(const Named& c, const StripDesignOptions& o, double bound) {
  const StripDesign d = design_strip(c.curve, o);
  ASSERT_TRUE(d.feasible) << c.name << ": " << d.reason;
  double prev = INFINITY;
  for (int N : {200, 400, 800}) {
    StripValidationOptions v;
    v.rod.edges = N;
    const StripValidation val = validate_strip(c.curve, d, o, v);
    ASSERT_TRUE(val.converged) << c.name << " N = " << N << ": " << val.message;
    std::printf("[ %s%s ] R = %.4f, N = %d: deviation %.3g (%d Newton it)\n", c.name,
                o.gravity.enabled ? ", gravity" : "", d.R, N, val.deviation, val.iterations);
    EXPECT_LT(val.deviation, prev) << c.name << ": not converging under refinement at N = " << N;
    prev = val.deviation;
  }
  EXPECT_LT(prev, bound) << c.name;
}

// Deviation at 800 edges as measured (2026-11-23); the bounds allow 50 % above it (the
// figures move with the design's sampling, not with the machine).
double measured_deviation(const std::string& name, bool gravity) {
  static const std::map<std::string, std::pair<double, double>> m = {  // without, with gravity
      {"no inflection (ellipse arc)", {9.3e-7, 9.1e-7}},
      {"one inflection", {2.2e-7, 6.1e-7}},
      {"two inflections", {9.3e-7, NAN}},
      {"three inflections", {5.4e-7, NAN}},
      {"spiral (1.5 turns)", {2.2e-6, 2.5e-6}},
      {"two inflections (gravity elastica)", {NAN, 4.9e-6}},
      {"three inflections (gravity elastica)", {NAN, 1.2e-5}}};
  const auto& v = m.at(name);
  return gravity ? v.second : v.first;
}

TEST(StripValidation, DesignsWithoutGravitySimulateOntoTheirTargets) {
  for (const auto& c : designs()) expect_simulates_back(c, cardboard(false), 1.5 * measured_deviation(c.name, false));
}

TEST(StripValidation, DesignsUnderGravitySimulateOntoTheirTargets) {
  // The generic curves with two and three inflections are infeasible under cardboard
  // gravity (reported below); curves with two and three inflections that are feasible are
  // taken from strips of constant stiffness integrated under gravity (the design does not
  // know that).
  auto cases = designs();
  const Vec2 e = cardboard(true).gravity.load();
  cases.push_back({"two inflections (gravity elastica)", test::gravity_elastica(e, {0, -300}, 8, 0, 0.4)});
  cases.push_back({"three inflections (gravity elastica)", test::gravity_elastica(e, {0, -300}, -8, 0.5, 0.4)});
  int feasible = 0;
  for (const auto& c : cases) {
    const StripDesign d = design_strip(c.curve, cardboard(true));
    if (!d.feasible) {
      std::printf("[ %s, gravity ] infeasible: %s\n", c.name, d.reason.c_str());
      continue;
    }
    ++feasible;
    expect_simulates_back(c, cardboard(true), 1.5 * measured_deviation(c.name, true));
  }
  EXPECT_EQ(feasible, 5);  // 0, 1 inflections and the spiral; 2 and 3 from the elasticae
}

TEST(StripValidation, EndForceOfTheLpMatchesTheSimulatorsReaction) {
  // b of the LP is the rotated end force (b = R n(l)); the simulator's multiplier of the
  // end-point constraint is the same force, found without any LP.
  for (bool gravity : {false, true}) {
    const BSplineCurve2 c = test::one_inflection();
    const StripDesignOptions o = cardboard(gravity);
    StripDesignOptions general = o;
    general.fixed_samples = 1025;
    const StripDesign d = design_strip(c, general);
    ASSERT_TRUE(d.feasible);
    StripValidationOptions v;
    v.rod.edges = 1600;
    const StripValidation val = validate_strip(c, d, general, v);
    ASSERT_TRUE(val.converged);
    const Vec2 f = val.simulation.end_force;
    std::printf("[ one inflection%s ] end force LP (%.6g, %.6g), simulator (%.6g, %.6g)\n",
                gravity ? ", gravity" : "", d.end_force.x(), d.end_force.y(), f.x(), f.y());
    EXPECT_LT((f - d.end_force).norm(), 2e-5 * d.end_force.norm());
  }
}

TEST(StripValidation, HeavyStripDesignedWithoutGravitySags) {
  // Cardboard strips designed with Eq. 4.4 sag under their weight; designed with Eq. 4.6
  // (gravity in the LP) they hold their shape (the spiral is the analogue of Fig. 4.7).
  // max_deviation: about 1.6-2x the deviation with gravity measured 2026-11-28 (9.1e-7,
  // 6.1e-7, 2.5e-6; before: 1e-5 for all three).
  struct Case { const char* name; BSplineCurve2 curve; double min_sag, max_deviation; };
  const std::vector<Case> cases = {{"ellipse arc", test::ellipse_arc(), 1e-2, 1.5e-6},
                                   {"one inflection", test::one_inflection(), 1e-2, 1.2e-6},
                                   {"spiral", test::spiral(), 5e-2, 4e-6}};
  const StripDesignOptions with = cardboard(true), without = cardboard(false);
  for (const auto& c : cases) {
    const StripDesign d0 = design_strip(c.curve, without), d1 = design_strip(c.curve, with);
    ASSERT_TRUE(d0.feasible && d1.feasible) << c.name << ": " << d1.reason;
    const StripValidation sag = validate_strip(c.curve, d0, with), ok = validate_strip(c.curve, d1, with);
    ASSERT_TRUE(sag.converged && ok.converged) << c.name << ": " << sag.message << ok.message;
    std::printf("[ %s, cardboard ] designed without gravity: deviation %.3g (%.1f mm); with "
                "gravity: %.3g\n", c.name, sag.deviation, 1e3 * sag.max_distance, ok.deviation);
    EXPECT_GT(sag.deviation, c.min_sag) << c.name;
    EXPECT_LT(ok.deviation, c.max_deviation) << c.name;
  }
}

}  // namespace
}  // namespace parafab
