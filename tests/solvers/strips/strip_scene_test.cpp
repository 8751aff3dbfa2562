// design_strips (a scene of independent strips over TBB workers): every result equals
// design_strip on the same curve, bit for bit, on 1 and 2 threads; an error names the strip.
#include <gtest/gtest.h>

#include <cmath>

#include <tbb/task_arena.h>

#include "common/error.h"
#include "strips/jacobi_stability.h"
#include "strips/strip_design.h"
#include "strip_test_curves.h"

namespace parafab {
namespace {

void expect_same(const StripDesign& a, const StripDesign& b) {
  ASSERT_EQ(a.feasible, b.feasible);
  EXPECT_EQ(a.reason_code, b.reason_code);
  if (!a.feasible) return;
  EXPECT_EQ(a.R, b.R);
  if (!std::isnan(a.R_first)) EXPECT_EQ(a.R_first, b.R_first);
  EXPECT_EQ(std::isnan(a.R_first), std::isnan(b.R_first));
  EXPECT_EQ(a.a, b.a);
  EXPECT_EQ(a.b, b.b);
  ASSERT_EQ(a.samples.size(), b.samples.size());
  for (size_t k = 0; k < a.samples.size(); ++k) {
    EXPECT_EQ(a.samples[k].s, b.samples[k].s);
    EXPECT_EQ(a.samples[k].K, b.samples[k].K);
  }
  EXPECT_EQ(a.outline, b.outline);
}

TEST(StripScene, ThreadedScenesEqualSingleDesigns) {
  std::vector<BSplineCurve2> curves;
  for (int i = 0; i < 6; ++i) curves.push_back(test::ellipse_arc(0.2, 0.12 + 0.01 * i));
  curves.push_back(test::one_inflection());
  curves.push_back(test::two_inflections());
  for (const bool gravity : {false, true}) {
    StripDesignOptions o;
    o.gravity.enabled = gravity;
    std::vector<StripDesign> single;
    for (const auto& c : curves) single.push_back(design_strip(c, o));
    for (const int threads : {1, 2}) {
      const std::vector<StripDesign> scene = design_strips(curves, o, threads);
      ASSERT_EQ(scene.size(), curves.size());
      for (size_t i = 0; i < curves.size(); ++i) {
        SCOPED_TRACE(testing::Message() << "strip " << i << ", threads " << threads << ", gravity " << gravity);
        expect_same(scene[i], single[i]);
      }
    }
  }
}

// Warm-started LPs (the default) against cold starts: the same optimum bit for bit on these
// curves (Eq. 4.4, and the gravity LP with and without phase two), in fewer iterations.
TEST(StripScene, WarmStartedLpsEqualColdStarts) {
  int warm_iterations = 0, cold_iterations = 0;
  for (const auto& c : {test::ellipse_arc(), test::one_inflection(), test::two_inflections(), test::spiral()}) {
    for (const int mode : {0, 1, 2}) {  // Eq. 4.4; gravity; gravity with phase two
      StripDesignOptions o;
      o.gravity.enabled = mode > 0;
      o.smooth = mode == 2;
      o.warm_start_eq44 = true;
      const StripDesign warm = design_strip(c, o);
      o.warm_start = false;
      o.warm_start_eq44 = false;
      const StripDesign cold = design_strip(c, o);
      expect_same(warm, cold);
      warm_iterations += warm.lp_iterations;
      cold_iterations += cold.lp_iterations;
    }
  }
  EXPECT_LT(warm_iterations, cold_iterations);
}

// The arc-length table, the zero scan, a grid's new samples and the stability verdict's fine
// polyline run on TBB workers: on one thread the same bits. A 400-point interpolant (the
// Python benchmark's cubic with one inflection), long enough for every loop to be split.
TEST(StripScene, TbbLoopsGiveTheSameBitsAsOneThread) {
  std::vector<Vec2> pts;
  for (int i = 0; i < 400; ++i) {
    const double x = -0.135 + 0.27 * i / 399, u = x / 0.15;
    pts.emplace_back(x, 0.06 * (u * u * u - u));
  }
  const BSplineCurve2 c = interpolate_points(pts, 4);
  for (const bool gravity : {false, true}) {
    SCOPED_TRACE(gravity ? "gravity" : "Eq. 4.4");
    StripDesignOptions o;
    o.gravity.enabled = gravity;
    auto run = [&](int threads) {
      std::pair<StripDesign, StripStability> r{StripDesign{}, StripStability{}};
      tbb::task_arena(threads).execute([&] {
        r.first = design_strip(c, o);
        r.second = strip_stability(c, r.first, o);
      });
      return r;
    };
    const auto one = run(1), two = run(2);
    expect_same(one.first, two.first);
    EXPECT_EQ(one.second.stable, two.second.stable);
    EXPECT_EQ(std::isnan(one.second.sigma), std::isnan(two.second.sigma));
    if (!std::isnan(one.second.sigma)) EXPECT_EQ(one.second.sigma, two.second.sigma);
    EXPECT_EQ(one.second.jacobi.Z_raw, two.second.jacobi.Z_raw);
  }
}

TEST(StripScene, ErrorNamesTheStrip) {
  // Strip 1 has collapsed poles (zero speed): design_strip throws, design_strips names it.
  std::vector<BSplineCurve2> curves{test::ellipse_arc(),
                                    BSplineCurve2(2, {0, 0, 0, 1, 1, 1}, {Vec2(0, 0), Vec2(0, 0), Vec2(0, 0)})};
  try {
    design_strips(curves, {}, 2);
    FAIL() << "expected parafab::Error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("strip 1: "), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("zero speed"), std::string::npos) << e.what();
  }
  EXPECT_THROW(design_strips(curves, {}, -1), Error);
}

}  // namespace
}  // namespace parafab
