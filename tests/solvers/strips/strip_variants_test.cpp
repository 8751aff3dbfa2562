// Boundary-condition variants and natural curvature (thesis §4.3.3), nonlinear moment laws
// and plasticity (Appendix A.5): each design is checked against its defining property (line
// direction, vanishing end force, κ at a free end) and simulated back with the same
// supports and law by the plane rod simulator.
#include <gtest/gtest.h>

#include <cmath>

#include "common/error.h"
#include "strips/strip_validation.h"
#include "strip_test_curves.h"

namespace parafab {
namespace {

double simulate_back(const BSplineCurve2& c, const StripDesign& d, const StripDesignOptions& o,
                     const char* name) {
  StripValidationOptions v;
  v.rod.edges = 800;
  const StripValidation val = validate_strip(c, d, o, v);
  EXPECT_TRUE(val.converged) << name << ": " << val.message;
  std::printf("[ %s ] R = %.4f, deviation %.3g\n", name, d.R, val.deviation);
  return val.deviation;
}

TEST(StripBoundary, FreeXAtTheEndMakesTheLineVertical) {
  const BSplineCurve2 c = test::ellipse_arc();
  StripDesignOptions o;
  o.boundary.end.free_x = true;
  const StripDesign d = design_strip(c, o);
  ASSERT_TRUE(d.feasible) << d.reason;
  EXPECT_LT(std::abs(d.b.y()), 1e-9 * d.b.norm());       // a + b₁ x = 0: vertical
  EXPECT_LT(std::abs(d.end_force.x()), 1e-9 * d.end_force.norm());
  EXPECT_LT(simulate_back(c, d, o, "ellipse arc, end free in x"), 1e-5);
  // The kinematic design has a different, better line.
  const StripDesign k = design_strip(c, StripDesignOptions{});
  EXPECT_LT(k.R, d.R);
}

TEST(StripBoundary, FreeYMakesTheLineHorizontalAndFreeEndsForbidInflections) {
  const BSplineCurve2 c = test::ellipse_arc();
  StripDesignOptions o;
  o.boundary.start.free_y = true;
  const StripDesign d = design_strip(c, o);
  ASSERT_TRUE(d.feasible) << d.reason;
  EXPECT_LT(std::abs(d.b.x()), 1e-9 * d.b.norm());  // a + b₂ y = 0: horizontal
  EXPECT_LT(simulate_back(c, d, o, "ellipse arc, start free in y"), 1e-5);
  // Both ends free in x and in y: b = 0, K = a/κ, R = max κ / min κ.
  o.boundary.end.free_x = o.boundary.end.free_y = true;
  o.boundary.start.free_x = true;
  const StripDesign f = design_strip(c, o);
  ASSERT_TRUE(f.feasible) << f.reason;
  EXPECT_LT(f.b.norm() * 0.2, 1e-9 * std::abs(f.a));
  double kmin = INFINITY, kmax = 0;
  for (const auto& p : f.samples) kmin = std::min(kmin, std::abs(p.kappa)), kmax = std::max(kmax, std::abs(p.kappa));
  EXPECT_NEAR(f.R, kmax / kmin, 1e-9 * f.R);
  // … which no curve with an inflection satisfies.
  const StripDesign g = design_strip(test::one_inflection(), o);
  EXPECT_FALSE(g.feasible);
  EXPECT_NE(g.reason.find("free end directions"), std::string::npos) << g.reason;
}

TEST(StripBoundary, FreeYAtTheStartUnderGravityHasNoVerticalReaction) {
  const BSplineCurve2 c = test::ellipse_arc();
  StripDesignOptions o;
  o.gravity.enabled = true;
  o.boundary.start.free_y = true;
  const StripDesign d = design_strip(c, o);
  ASSERT_TRUE(d.feasible) << d.reason;
  EXPECT_LT(std::abs(d.start_force.y()), 1e-8 * d.start_force.norm() + 1e-9);
  EXPECT_LT(simulate_back(c, d, o, "ellipse arc, gravity, start free in y"), 1e-4);  // R ≈ 116
}

TEST(StripBoundary, FreeAngleNeedsZeroCurvatureAtThatEnd) {
  StripDesignOptions o;
  o.boundary.end.free_angle = true;
  try {
    design_strip(test::ellipse_arc(), o);
    FAIL() << "free end angle with κ ≠ 0 accepted";
  } catch (const Error& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("boundary.end.free_angle"), std::string::npos) << msg;
    EXPECT_NE(msg.find("κ = "), std::string::npos) << msg;
  }
  // κ(s) = 12 s (0.3 − s)…: zero at the start, a pin there.
  const BSplineCurve2 c = test::curve_from_curvature([](double s) { return 40 * s * (1.2 - s); }, 0.35, 0.3);
  o = StripDesignOptions{};
  o.boundary.start.free_angle = true;
  const StripDesign d = design_strip(c, o);
  ASSERT_TRUE(d.feasible) << d.reason;
  ASSERT_FALSE(d.zeros.empty());
  EXPECT_EQ(d.zeros.front().kind, ZeroKind::AtEnd);
  // The line passes through the pinned end: a + ⟨b, γ(0)⟩ = 0.
  EXPECT_LT(std::abs(d.a + d.b.dot(d.samples.front().point)), 1e-9 * std::abs(d.a) + 1e-9);
  EXPECT_LT(simulate_back(c, d, o, "pinned start"), 1e-5);
  // Under gravity as well.
  o.gravity.enabled = true;
  const StripDesign g = design_strip(c, o);
  ASSERT_TRUE(g.feasible) << g.reason;
  EXPECT_LT(simulate_back(c, g, o, "pinned start, gravity"), 1e-5);
}

TEST(StripNaturalCurvature, ArcWithOtherNaturalCurvatureNeedsConstantStiffness) {
  const double r = 0.25;
  const BSplineCurve2 arc = test::curve_from_curvature([&](double) { return 1 / r; }, 1.5 * r);
  StripDesignOptions o;
  o.natural_curvature = 2.0;  // κ − κ₀ = 2 1/m everywhere
  const StripDesign d = design_strip(arc, o);
  ASSERT_TRUE(d.feasible) << d.reason;
  EXPECT_NEAR(d.R, 1.0, 1e-6);
  EXPECT_LT(simulate_back(arc, d, o, "arc, natural curvature 2/m"), 1e-5);
}

TEST(StripNaturalCurvature, ZerosOfKappaMinusKappa0FixTheLine) {
  // Ellipse arc 0.2 × 0.12: κ runs from ~3 to ~14 1/m; κ₀ = 8 gives two zeros of κ − κ₀,
  // symmetric about the y axis, so the line is horizontal through them.
  const BSplineCurve2 c = test::ellipse_arc(0.2, 0.12, 0.3, M_PI - 0.3);
  StripDesignOptions o;
  o.natural_curvature = 8.0;
  const StripDesign d = design_strip(c, o);
  ASSERT_TRUE(d.feasible) << d.reason;
  ASSERT_EQ(d.zeros.size(), 2u);
  EXPECT_NEAR(d.zeros[0].at.point.y(), d.zeros[1].at.point.y(), 1e-9);
  EXPECT_LT(std::abs(d.b.x()), 1e-7 * d.b.norm());
  EXPECT_LT(simulate_back(c, d, o, "ellipse arc, natural curvature 8/m"), 1e-5);
  // The same strip without its natural curvature lands elsewhere.
  StripDesignOptions plain = o;
  plain.natural_curvature = 0;
  StripValidationOptions v;
  const StripValidation wrong = validate_strip(c, d, plain, v);
  EXPECT_GT(wrong.deviation, 1e-3);  // 1.6e-3, against 8e-7 with κ₀
}

TEST(StripMaterialLaw, HardeningLawDesignSimulatesBackAndDiffersFromLinear) {
  const BSplineCurve2 c = test::ellipse_arc();
  StripDesignOptions o;
  o.law.cubic = 2e-3;  // m = κ + 0.002 κ³: +39 % moment at κ = 14 1/m
  const StripDesign d = design_strip(c, o);
  ASSERT_TRUE(d.feasible) << d.reason;
  EXPECT_LT(simulate_back(c, d, o, "cubic hardening"), 1e-5);
  // The linear design simulated with the hardening law misses the target.
  const StripDesign lin = design_strip(c, StripDesignOptions{});
  StripValidationOptions v;
  EXPECT_GT(validate_strip(c, lin, o, v).deviation, 1e-3);
}

TEST(StripMaterialLaw, NonInjectiveLawsAreRejectedNamingTheField) {
  const BSplineCurve2 c = test::ellipse_arc();  // max κ ≈ 13.9 1/m
  StripDesignOptions o;
  o.law.cubic = -2.5e-3;  // m' = 0 at |κ| = 11.5 1/m
  try {
    design_strip(c, o);
    FAIL() << "softening law beyond its maximum accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("material.law.cubic"), std::string::npos) << e.what();
  }
  o.law.cubic = -1e-3;  // m' = 0 at 18.3 1/m: injective on the used range
  const StripDesign soft = design_strip(c, o);
  ASSERT_TRUE(soft.feasible);
  EXPECT_LT(simulate_back(c, soft, o, "cubic softening"), 1e-5);

  o = StripDesignOptions{};
  // Ideal plasticity (H = 0) is designed with κ_eff (strip_review_test.cpp, StripPlasticity).
  o.law.curvature_limit = 10.0;
  o.law.plastic_hardening = 0.2;  // linear hardening beyond the limit: injective
  const StripDesign pl = design_strip(c, o);
  ASSERT_TRUE(pl.feasible) << pl.reason;
  EXPECT_GT(pl.max_plastic_curvature, 10.0);
  EXPECT_LT(simulate_back(c, pl, o, "plastic beyond 10/m, hardening 0.2"), 1e-5);
}

TEST(StripMaterialLaw, TabulatedLawMatchesTheCubicItSamples) {
  // m = κ + 0.002 κ³ tabulated every 0.25 1/m up to 20 1/m: the design follows the cubic
  // law to the interpolation error, and the simulator with the table reproduces the target.
  const BSplineCurve2 c = test::ellipse_arc();
  StripDesignOptions cubic;
  cubic.law.cubic = 2e-3;
  StripDesignOptions table;
  for (int i = 0; i <= 80; ++i) {
    const double k = 0.25 * i;
    table.law.table_curvature.push_back(k);
    table.law.table_moment.push_back(k + 2e-3 * k * k * k);
  }
  const StripDesign dc = design_strip(c, cubic), dt = design_strip(c, table);
  ASSERT_TRUE(dc.feasible && dt.feasible) << dt.reason;
  EXPECT_NEAR(dt.R, dc.R, 2e-3 * dc.R);  // chord error of the table ≈ 6e-3·κ³·h² / 8
  EXPECT_LT(simulate_back(c, dt, table, "tabulated hardening law"), 1e-5);
  // A table that turns down inside the used range is rejected naming the entry.
  StripDesignOptions bad = table;
  bad.law.table_moment[40] = bad.law.table_moment[39];  // flat at |κ| = 9.75 1/m
  try {
    design_strip(c, bad);
    FAIL() << "non-injective table accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("material.law.table_moment[40]"), std::string::npos) << e.what();
  }
  bad.law.table_curvature[5] = bad.law.table_curvature[4];
  EXPECT_THROW(design_strip(c, bad), Error);
}

}  // namespace
}  // namespace parafab
