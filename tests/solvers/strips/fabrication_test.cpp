// Composite and perforated strips (thesis §4.7.1). Composite: the closed-form thickness
// ratio threshold against a bisection on the feasibility test, and the stiffness identity
// c K = P₁ w₁ + P₂ w₂. Perforated: the material width across sections, measured by
// intersecting the diamond polygons, against the solid width the stiffness needs.
#include <gtest/gtest.h>

#include <cmath>

#include "strips/composite_strip.h"
#include "strips/perforated_strip.h"
#include "strips/strip_design.h"
#include "strip_test_curves.h"

namespace parafab {
namespace {

struct Profile { std::vector<double> s, K, width; };
Profile designed_profile() {
  const StripDesign d = design_strip(test::spiral(), StripDesignOptions{});  // R ≈ 2.25
  Profile p;
  for (size_t i = 0; i < d.samples.size(); ++i)
    p.s.push_back(d.samples[i].s), p.K.push_back(d.samples[i].K), p.width.push_back(d.width[i]);
  return p;
}

TEST(CompositeStrip, ThicknessRatioThresholdMatchesBisection) {
  const Profile p = designed_profile();
  // Outer width: a taper from 30 to 20 mm.
  std::vector<double> w1;
  for (double s : p.s) w1.push_back(0.03 - 0.01 * s / p.s.back());
  CompositeStripOptions o;
  o.inner_thickness = 0.3e-3;
  o.outer_thickness = 0.3e-3;
  const CompositeStripResult r = design_composite_strip(p.s, p.K, w1, o);
  const double closed = r.max_thickness_ratio;
  ASSERT_TRUE(std::isfinite(closed) && closed > 0);
  // Bisection on h₁/h₂ with the feasibility test itself.
  double lo = 1e-3, hi = 100;
  for (int it = 0; it < 80; ++it) {
    const double mid = std::sqrt(lo * hi);
    o.outer_thickness = mid * o.inner_thickness;
    (design_composite_strip(p.s, p.K, w1, o).feasible ? lo : hi) = mid;
  }
  EXPECT_NEAR(lo, closed, 1e-9 * closed);
  o.outer_thickness = 1.01 * closed * o.inner_thickness;
  const CompositeStripResult bad = design_composite_strip(p.s, p.K, w1, o);
  EXPECT_FALSE(bad.feasible);
  EXPECT_NE(bad.message.find("at most"), std::string::npos) << bad.message;
  std::printf("[ composite, spiral R = 2.25, w1 30->20 mm ] max h1/h2 = %.4f\n", closed);
}

TEST(CompositeStrip, InnerWidthRealizesTheStiffness) {
  const Profile p = designed_profile();
  std::vector<double> w1(p.s.size(), 0.03);
  CompositeStripOptions o;
  o.outer_thickness = 0.15e-3;  // h₁/h₂ = 1/2.4 as in the thesis' models
  o.inner_thickness = 0.36e-3;
  const CompositeStripResult r = design_composite_strip(p.s, p.K, w1, o);
  ASSERT_TRUE(r.feasible) << r.message;
  const double h1 = o.outer_thickness, h2 = o.inner_thickness;
  const double P1 = h1 * h1 * h1, P2 = std::pow(h1 + h2, 3) - P1;
  double max_ratio = 0;
  for (size_t i = 0; i < p.s.size(); ++i) {
    EXPECT_GE(r.inner_width[i], 0.0);
    EXPECT_LE(r.inner_width[i], w1[i]);
    EXPECT_NEAR(r.scale * p.K[i], P1 * w1[i] + P2 * r.inner_width[i], 1e-12 * r.scale * p.K[i]);
    max_ratio = std::max(max_ratio, r.inner_width[i] / w1[i]);
  }
  EXPECT_NEAR(max_ratio, 1.0, 1e-12);  // as wide as possible: touches the outer edge
}

// Holes cut by the section s = at, from the diamond polygons (edge intersections).
double material_from_polygons(const PerforatedStripResult& r, double outer, double at) {
  double holes = 0;
  for (const auto& d : r.diamonds) {
    const auto c = d.corners();
    std::vector<double> ys;
    for (int k = 0; k < 4; ++k) {
      const Vec2 a = c[k], b = c[(k + 1) % 4];
      if ((a.x() <= at && at < b.x()) || (b.x() <= at && at < a.x())) ys.push_back(a.y() + (b.y() - a.y()) * (at - a.x()) / (b.x() - a.x()));
    }
    if (ys.size() == 2) holes += std::abs(ys[1] - ys[0]);
  }
  return outer - holes;
}

TEST(PerforatedStrip, ConstantProfileIsExactAcrossEverySection) {
  const std::vector<double> s = {0, 0.4}, w = {0.04, 0.04}, wk = {0.025, 0.025};
  PerforatedStripOptions o;
  o.min_ligament = 1.5e-3;
  const PerforatedStripResult r = design_perforated_strip(s, w, wk, o);
  ASSERT_TRUE(r.feasible) << r.message;
  EXPECT_GE(r.columns, 2);
  double worst = 0;
  for (int i = 0; i <= 1000; ++i) {
    const double at = r.perforated_from + (r.perforated_to - r.perforated_from) * (i + 0.5) / 1001;
    worst = std::max(worst, std::abs(material_from_polygons(r, 0.04, at) - 0.025));
  }
  EXPECT_LT(worst, 1e-12);
  // Strands: across sections, holes are separated by at least min_ligament.
  for (int i = 0; i < 200; ++i) {
    const double at = r.perforated_from + (r.perforated_to - r.perforated_from) * (i + 0.5) / 200;
    std::vector<std::pair<double, double>> iv;
    for (const auto& d : r.diamonds) {
      const double t = std::abs(at - d.s);
      if (t < 0.5 * d.length) {
        const double half = 0.5 * d.width * (1 - 2 * t / d.length);
        iv.push_back({d.offset - half, d.offset + half});
      }
    }
    std::sort(iv.begin(), iv.end());
    ASSERT_FALSE(iv.empty());
    EXPECT_GE(iv.front().first + 0.02, o.min_ligament * (1 - 1e-9));
    EXPECT_GE(0.02 - iv.back().second, o.min_ligament * (1 - 1e-9));
    for (size_t k = 1; k < iv.size(); ++k) EXPECT_GE(iv[k].first - iv[k - 1].second, o.min_ligament * (1 - 1e-9));
  }
}

TEST(PerforatedStrip, DesignedProfileIsReachedAtAGivenOuterWidth) {
  Profile p = designed_profile();
  // Solid widths 17 … 38 mm inside an outer width of 40 mm: holes up to 57 % of the width.
  for (double& x : p.width) x *= 1.7;
  std::vector<double> w(p.s.size(), 0.04);
  double prev = INFINITY;
  for (double aspect : {8.0, 4.0, 2.0}) {
    PerforatedStripOptions o;
    o.cell_aspect = aspect;
    o.min_ligament = 1e-3;
    const PerforatedStripResult r = design_perforated_strip(p.s, w, p.width, o);
    ASSERT_TRUE(r.feasible) << r.message;
    double worst = 0;
    for (int i = 0; i <= 2000; ++i) {
      const double at = r.perforated_from + (r.perforated_to - r.perforated_from) * i / 2000.0;
      double need = 0;  // solid width at `at`, linear between samples
      const auto it = std::upper_bound(p.s.begin(), p.s.end(), at);
      const size_t j = std::min<size_t>(std::max<size_t>(it - p.s.begin(), 1), p.s.size() - 1);
      need = p.width[j - 1] + (p.width[j] - p.width[j - 1]) * (at - p.s[j - 1]) / (p.s[j] - p.s[j - 1]);
      worst = std::max(worst, std::abs(material_from_polygons(r, 0.04, at) - need) / need);
      EXPECT_NEAR(perforated_material_width(r, p.s, w, at), material_from_polygons(r, 0.04, at), 1e-12);
    }
    std::printf("[ perforated spiral strip, aspect %.0f ] %d columns, pitch %.1f mm, %zu diamonds, "
                "max relative error of the solid width %.3g\n", aspect, r.columns, 1e3 * r.pitch,
                r.diamonds.size(), worst);
    EXPECT_LT(worst, prev);  // finer rows follow the profile better
    prev = worst;
  }
  EXPECT_LT(prev, 0.03);
  // Infeasible: the stiffness needs more than the outer width somewhere.
  std::vector<double> narrow(p.s.size(), 0.03);
  const PerforatedStripResult bad = design_perforated_strip(p.s, narrow, p.width);
  EXPECT_FALSE(bad.feasible);
  EXPECT_GT(bad.worst_s, 0.0);
}

}  // namespace
}  // namespace parafab
