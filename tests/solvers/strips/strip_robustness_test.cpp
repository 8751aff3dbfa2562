// Robustness study of Fig. 4.15: the baseline reproduces the target, every defect moves the
// strip away from it, larger defects move it further, and a defect that the model cannot
// see (gravity changes of a strip designed and simulated without gravity) is absent.
#include <gtest/gtest.h>

#include "strips/strip_robustness.h"
#include "strip_test_curves.h"

namespace parafab {
namespace {

const StripRobustnessCase& find(const StripRobustness& r, const std::string& name) {
  for (const auto& c : r.cases)
    if (c.name == name) return c;
  ADD_FAILURE() << "no case " << name;
  return r.cases.front();
}

TEST(StripRobustness, DefectsOfASpiralUnderGravity) {
  const BSplineCurve2 c = test::spiral();
  StripDesignOptions o;
  o.gravity.enabled = true;
  const StripDesign d = design_strip(c, o);
  ASSERT_TRUE(d.feasible) << d.reason;
  const StripRobustness r = strip_robustness_study(c, d, o);
  for (const auto& cs : r.cases)
    std::printf("[ spiral, gravity ] %-24s deviation %.3g (%.2f mm)%s\n", cs.name.c_str(), cs.deviation,
                1e3 * cs.max_distance, cs.converged ? "" : (" NOT CONVERGED: " + cs.message).c_str());
  ASSERT_EQ(r.cases.size(), 9u);
  for (const auto& cs : r.cases) EXPECT_EQ(cs.nodes.size(), 801u) << cs.name;  // 800 edges
  EXPECT_LT(find(r, "baseline").deviation, 1e-5);
  for (const auto& cs : r.cases) {
    EXPECT_TRUE(cs.converged) << cs.name << ": " << cs.message;
    if (cs.name != "baseline") EXPECT_GT(cs.deviation, 1e-3) << cs.name;
  }
  EXPECT_GT(find(r, "plastic_top_50%").deviation, find(r, "plastic_top_25%").deviation);
  // Smaller defects, smaller deviations.
  StripRobustnessOptions half;
  half.stiffness_change = 0.25;
  half.gravity_change = 0.25;
  half.angle_change = 5 * M_PI / 180;
  half.plastic_fractions = {};
  const StripRobustness h = strip_robustness_study(c, d, o, half);
  EXPECT_LT(find(h, "stiffness_range+25%").deviation, find(r, "stiffness_range+50%").deviation);
  EXPECT_LT(find(h, "gravity-25%").deviation, find(r, "gravity-50%").deviation);
  EXPECT_LT(find(h, "end_angles_opened_5deg").deviation, find(r, "end_angles_opened_10deg").deviation);
}

TEST(StripRobustness, WithoutGravityThereAreNoGravityCases) {
  const BSplineCurve2 c = test::two_inflections();
  const StripDesignOptions o;
  const StripDesign d = design_strip(c, o);
  ASSERT_TRUE(d.feasible);
  const StripRobustness r = strip_robustness_study(c, d, o);
  EXPECT_EQ(r.cases.size(), 7u);
  for (const auto& cs : r.cases) {
    EXPECT_EQ(cs.name.find("gravity"), std::string::npos);
    EXPECT_TRUE(cs.converged) << cs.name << ": " << cs.message;
    if (cs.name != "baseline") EXPECT_GT(cs.deviation, 1e-3) << cs.name;
    std::printf("[ two inflections ] %-24s deviation %.3g%s\n", cs.name.c_str(), cs.deviation,
                cs.converged ? "" : " NOT CONVERGED");
  }
}

}  // namespace
}  // namespace parafab
