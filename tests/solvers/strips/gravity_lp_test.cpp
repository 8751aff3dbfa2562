// Gravity LP (thesis Eq. 4.6, §4.4.3) against independent references: without gravity it is
// the Eq. 4.4 program of stiffness_lp; a strip of constant stiffness integrated under
// gravity as an ODE (a "gravity elastica") must come back with R = 1; phase two keeps
// R ≤ R₁(1+ε) and removes the spikes of the literal Eq. 4.6 near inflections.
#include <gtest/gtest.h>

#include <algorithm>

#include "common/error.h"
#include "strips/gravity_lp.h"
#include "strips/stiffness_lp.h"
#include "strips/strip_design.h"
#include "strip_test_curves.h"

namespace parafab {
namespace {

using test::rk4;
using test::State;

std::vector<StripLpSample> lp_samples(const PlaneCurve& c, int n, std::vector<CurvePoint>* pts = nullptr,
                                      std::vector<CurvePoint>* zpts = nullptr) {
  const ZeroCurvatureResult z = find_zero_curvature(c);
  std::vector<StripLpSample> out;
  for (const auto& p : sample_by_arc_length(c, n, z.points)) {
    out.push_back({p.s, p.point, p.tangent, p.kappa, p.dkappa_ds, false, p.kappa});
    if (pts) pts->push_back(p);
  }
  for (const auto& q : z.points) {
    out.push_back({q.at.s, q.at.point, q.at.tangent, 0.0, q.at.dkappa_ds, true, 0.0});
    if (zpts) zpts->push_back(q.at);
  }
  std::sort(out.begin(), out.end(), [](auto& x, auto& y) { return x.s < y.s; });
  return out;
}

TEST(GravityLp, WithoutGravityItIsEq44) {
  const std::vector<BSplineCurve2> curves = {test::ellipse_arc(), test::one_inflection(),
                                             test::two_inflections()};
  for (size_t k = 0; k < curves.size(); ++k) {
    const PlaneCurve c(curves[k]);
    std::vector<CurvePoint> pts, zs;
    const auto smp = lp_samples(c, 401, &pts, &zs);
    std::vector<Vec2> line;
    for (const auto& z : zs) line.push_back(z.point);
    const StiffnessLpResult ref = solve_stiffness_lp(pts, zs, line, c.length());
    GravityLpOptions o;
    o.smooth = false;
    const GravityLpResult g = solve_gravity_lp(smp, c.length(), o);
    ASSERT_TRUE(ref.ok() && g.ok()) << k << ": " << g.message;
    EXPECT_NEAR(g.R, ref.R, 1e-9 * ref.R) << "curve " << k;
    // The line of the gravity LP, evaluated by the Eq. 4.4 code on the Eq. 4.4 samples, has
    // the same ratio (the optimal line itself need not be unique with < 2 inflections).
    double kmin = INFINITY, kmax = 0;
    for (const auto& p : pts) {
      const double K = stiffness_at(p, g.a, g.b, false);
      kmin = std::min(kmin, K), kmax = std::max(kmax, K);
    }
    for (const auto& z : zs) {
      const double K = stiffness_at(z, g.a, g.b, true);
      kmin = std::min(kmin, K), kmax = std::max(kmax, K);
    }
    EXPECT_NEAR(kmin, 1.0, 1e-9) << k;
    EXPECT_NEAR(kmax / kmin, ref.R, 1e-9 * ref.R) << k;
    if (zs.size() >= 2) {  // the line through two inflections is unique up to scale
      const double scale = g.b.norm() / ref.b.norm();
      EXPECT_NEAR(g.b.x(), scale * ref.b.x(), 1e-7 * g.b.norm()) << k;
      EXPECT_NEAR(g.a, scale * ref.a, 1e-7 * std::abs(g.a)) << k;
    }
    EXPECT_LT(g.max_violation, 1e-8);
  }
}

TEST(GravityLp, ConstantStiffnessUnderGravityHasUnitRatio) {
  StripGravity grav;
  grav.enabled = true;  // cardboard, βl³ = 8.86e-4 m³
  const Vec2 e = grav.load();
  struct Case { Vec2 b; double kappa0, alpha0, l; int inflections; };
  // An arch without inflection and an S-curve with one inflection under its own weight.
  const std::vector<Case> cases = {{{-300.0, 0.0}, -6.0, 0.8, 0.3, 0}, {{0.0, -60.0}, 9.0, 0.6, 0.35, 1}};
  for (const auto& cs : cases) {
    const BSplineCurve2 curve = test::gravity_elastica(e, cs.b, cs.kappa0, cs.alpha0, cs.l);
    const PlaneCurve c(curve);
    const auto zs = find_zero_curvature(c);
    int infl = 0;
    for (const auto& z : zs.points) infl += z.kind == ZeroKind::Inflection;
    ASSERT_EQ(infl, cs.inflections);
    for (int n : {101, 201, 401, 801}) {
      GravityLpOptions o;
      o.load = e;
      const GravityLpResult g = solve_gravity_lp(lp_samples(c, n), c.length(), o);
      ASSERT_TRUE(g.ok()) << g.message;
      const double err = g.R_first - 1;
      std::printf("[ gravity elastica, %d inflection(s) ] n = %d: R - 1 = %.3g\n", cs.inflections, n, err);
      // K ≡ 1 makes the trapezoidal F exact; what remains is the interpolation error of the
      // curve itself (κ of a quintic through 801 RK4 points), at every sample count.
      EXPECT_LT(err, 2e-5) << "n = " << n;
      if (n == 801) {
        // The line: b recovered (K ≡ 1 ⇒ same a, b as the integration).
        EXPECT_NEAR(g.b_first.x(), cs.b.x(), 2e-3 * cs.b.norm());
        EXPECT_NEAR(g.b_first.y(), cs.b.y(), 2e-3 * cs.b.norm());
        EXPECT_LE(g.R, g.R_first * 1.01 + 1e-12);
      }
    }
    // The same curve designed without gravity needs a different, non-constant profile.
    GravityLpOptions off;
    const GravityLpResult g0 = solve_gravity_lp(lp_samples(c, 401), c.length(), off);
    ASSERT_TRUE(g0.ok());
    EXPECT_GT(g0.R, 1.05);
  }
}

TEST(GravityLp, PhaseTwoRemovesSpikesOfTheLiteralProgram) {
  StripGravity grav;
  grav.enabled = true;
  {
    const PlaneCurve c(test::one_inflection());
    GravityLpOptions o;
    o.load = grav.load();
    o.inflection_rows = false;  // literal Eq. 4.6: no rows at the inflections
    const GravityLpResult g = solve_gravity_lp(lp_samples(c, 401), c.length(), o);
    ASSERT_TRUE(g.ok()) << g.message;
    ASSERT_TRUE(g.smoothed) << g.message;
    EXPECT_LE(g.R, g.R_first * (1 + o.smoothing_margin) * (1 + 1e-9));
    EXPECT_LT(g.tv, 0.1 * g.tv_first);  // the spikes of phase one are gone
    // With the inflection rows the profile is already smooth, and phase two keeps it so.
    o.inflection_rows = true;
    const GravityLpResult h = solve_gravity_lp(lp_samples(c, 401), c.length(), o);
    ASSERT_TRUE(h.ok()) << h.message;
    EXPECT_LE(h.R, h.R_first * 1.01 * (1 + 1e-9));
    EXPECT_LE(h.tv, h.tv_first * (1 + 1e-9));
    std::printf("[ literal Eq. 4.6 ] R1 %.6f TV(K') %.4g -> %.4g | with zero rows R1 %.6f TV %.4g -> %.4g\n",
                g.R_first, g.tv_first, g.tv, h.R_first, h.tv_first, h.tv);
  }
}

// Phase two (min Σ|ΔK′|) by ParaFab's dense solver (the primal simplex with long steps from
// phase one's optimum) against Clp's dual form on the same program, for three curves with and
// without inflection rows (the literal Eq. 4.6; the ellipse and the spiral have no inflection,
// so theirs are the same program twice): the same optimum, no fallback.
TEST(GravityLp, PhaseTwoDenseSolverMatchesClp) {
  StripGravity grav;
  grav.enabled = true;
  const std::vector<std::pair<const char*, BSplineCurve2>> curves = {
      {"ellipse", test::ellipse_arc()}, {"one inflection", test::one_inflection()},
      {"spiral", test::spiral()}};
  for (const auto& [name, curve] : curves)
    for (const bool rows : {true, false}) {
      const PlaneCurve c(curve);
      const auto smp = lp_samples(c, 401);
      GravityLpOptions dense, clp;
      dense.load = clp.load = grav.load();
      dense.inflection_rows = clp.inflection_rows = rows;
      clp.form = LpForm::Dual;
      const GravityLpResult a = solve_gravity_lp(smp, c.length(), dense);
      clp.phase_one = &a.phase_one_lp;  // the same phase one: the two phase-two programs are one
      const GravityLpResult b = solve_gravity_lp(smp, c.length(), clp);
      SCOPED_TRACE(::testing::Message() << name << (rows ? "" : ", literal Eq. 4.6"));
      ASSERT_TRUE(a.ok() && a.smoothed) << a.message;
      ASSERT_TRUE(b.ok() && b.smoothed) << b.message;
      EXPECT_EQ(a.phase_two_lp.solved_by, LpForm::Dense);
      EXPECT_EQ(a.phase_two_lp.fallback, "");
      EXPECT_EQ(b.phase_two_lp.solved_by, LpForm::Dual);
      const double fa = a.phase_two_lp.objective, fb = b.phase_two_lp.objective;
      std::printf("[ phase two %s%s ] objective %.12g (dense, %d steps) vs %.12g (Clp, %d): %.1e; TV %.10g vs %.10g\n",
                  name, rows ? "" : " literal", fa, a.iterations_second, fb, b.iterations_second, std::abs(fa / fb - 1),
                  a.tv, b.tv);
      EXPECT_NEAR(fa, fb, 1e-10 * fb);  // measured ≤ 6.6e-13
      EXPECT_NEAR(a.phase_two_lp.dual_objective, fa, 1e-10 * fb);
      // The optimum need not be unique (the spiral's two solutions have TV 1.5e-7 apart), so the
      // profiles are compared by their bound only.
      EXPECT_LE(a.R, a.R_first * (1 + dense.smoothing_margin) * (1 + 1e-9));
    }
}

// The work of a 400-sample gravity LP in simplex steps (deterministic; its time is
// bench_strip_scene's and bench_strip_python's): phase one's dense dual simplex, phase two's
// primal long steps from phase one's optimum (measured 15 and 29).
TEST(GravityLp, FourHundredSamplesTakeFewSimplexSteps) {
  StripGravity grav;
  grav.enabled = true;
  const PlaneCurve c(test::one_inflection());
  GravityLpOptions o;
  o.load = grav.load();
  const GravityLpResult g = solve_gravity_lp(lp_samples(c, 400), c.length(), o);
  ASSERT_TRUE(g.ok() && g.smoothed) << g.message;
  std::printf("[ gravity LP 400 samples ] phase one %d steps, phase two %d steps\n", g.iterations_first,
              g.iterations_second);
  EXPECT_LE(g.iterations_first, 18);
  EXPECT_LE(g.iterations_second, 35);
  EXPECT_EQ(g.phase_two_lp.fallback, "");
}

TEST(GravityLp, RejectsUnsortedSamples) {
  std::vector<StripLpSample> s(3);
  s[0].s = 0, s[1].s = 0.5, s[2].s = 0.4;
  for (auto& q : s) q.mu = 1;
  EXPECT_THROW(solve_gravity_lp(s, 1.0), Error);
}

TEST(GravityLp, GravitoBendingParameterFromMaterial) {
  // βl³ = E h² / (12 ρ g): cardboard-like E = 2 GPa, h = 0.3 mm, ρ = 667 kg/m³ (200 gsm).
  EXPECT_NEAR(gravito_bending_parameter(2e9, 0.3e-3, 0.2 / 0.3e-3, 9.81),
              2e9 * 0.09e-6 / (12 * 666.6666666666666 * 9.81), 1e-15);
  EXPECT_THROW(gravito_bending_parameter(2e9, 0, 600), Error);
  const StripGravity g = StripGravity::from_material(2e9, 0.3e-3, 0.2 / 0.3e-3);
  EXPECT_TRUE(g.enabled);
  EXPECT_NEAR(g.load().y(), -1 / g.gravito_bending, 1e-12);
}

}  // namespace
}  // namespace parafab

namespace parafab {
namespace {

TEST(GravityDesign, GeneralPathWithoutGravityMatchesTheEq44Design) {
  for (const auto& curve : {test::ellipse_arc(), test::one_inflection(), test::two_inflections(),
                            test::three_inflections()}) {
    const StripDesign ref = design_strip(curve, StripDesignOptions{});  // estimated gap 1e-6
    StripDesignOptions o;
    o.fixed_samples = 2049;  // routes through the gravity LP with gravity off
    const StripDesign g = design_strip(curve, o);
    ASSERT_TRUE(ref.feasible && g.feasible) << g.reason;
    EXPECT_TRUE(g.general_lp);
    EXPECT_FALSE(g.smoothed);  // no smoothing without gravity
    EXPECT_NEAR(g.R, ref.R, 2e-6 * ref.R);
  }
}

Vec2 rotate(const Vec2& p, double phi) {
  return {std::cos(phi) * p.x() - std::sin(phi) * p.y(), std::sin(phi) * p.x() + std::cos(phi) * p.y()};
}

TEST(GravityDesign, RotatingCurveAndGravityTogetherChangesNothing) {
  const BSplineCurve2 c = test::one_inflection();
  const double phi = 0.7;
  std::vector<Vec2> poles;
  for (const auto& p : c.poles()) poles.push_back(rotate(p, phi));
  const BSplineCurve2 rc(c.degree(), c.knots(), poles);
  StripDesignOptions o;
  o.gravity.enabled = true;
  o.fixed_samples = 513;
  const StripDesign d = design_strip(c, o);
  o.gravity.direction = rotate({0, -1}, phi);
  const StripDesign r = design_strip(rc, o);
  ASSERT_TRUE(d.feasible && r.feasible) << d.reason << r.reason;
  EXPECT_NEAR(r.R, d.R, 1e-7 * d.R);
  EXPECT_NEAR(r.R_first, d.R_first, 1e-9 * d.R_first);
  ASSERT_EQ(r.samples.size(), d.samples.size());
  double worst = 0;
  for (size_t i = 0; i < d.samples.size(); ++i) worst = std::max(worst, std::abs(r.samples[i].K - d.samples[i].K));
  EXPECT_LT(worst, 1e-6 * d.R);
  // The same rotated curve with gravity still along −y is a different (sheared) problem.
  o.gravity.direction = {0, -1};
  const StripDesign other = design_strip(rc, o);
  ASSERT_TRUE(other.feasible);
  EXPECT_GT(std::abs(other.R_first / d.R_first - 1), 1e-3);
}

TEST(GravityDesign, StiffnessProfileIsStableUnderRefinement) {
  // K on coarser grids against 4097 samples. The difference is not monotone in n: the
  // minimax line follows the sampled extrema of K, whose offsets from the true extrema vary
  // with the grid; it stays within a few 1e-5 (K ∈ [1, 1.76]).
  const BSplineCurve2 c = test::ellipse_arc();
  StripDesignOptions o;
  o.gravity.enabled = true;
  o.smooth = false;
  auto K_at = [](const StripDesign& d, double s) {
    for (size_t i = 1; i < d.samples.size(); ++i)
      if (d.samples[i].s >= s) {
        const double t = (s - d.samples[i - 1].s) / (d.samples[i].s - d.samples[i - 1].s);
        return d.samples[i - 1].K + t * (d.samples[i].K - d.samples[i - 1].K);
      }
    return d.samples.back().K;
  };
  o.fixed_samples = 4097;
  const StripDesign fine = design_strip(c, o);
  std::vector<double> err;
  for (int n : {65, 129, 257, 513}) {
    o.fixed_samples = n;
    const StripDesign d = design_strip(c, o);
    double e = 0;
    for (const auto& s : d.samples) e = std::max(e, std::abs(s.K - K_at(fine, s.s)));
    err.push_back(e);
    std::printf("[ ellipse arc, gravity ] n = %d: max |K_n - K_4097| = %.3g\n", n, e);
  }
  for (double e : err) EXPECT_LT(e, 3e-5);
}

}  // namespace
}  // namespace parafab
