// Stability verdict of designed Kirchhoff rods (thesis §4.5.1 eigenvalue condition on the
// discrete elastic rod): against the forward simulation (an energy-decreasing Newton with
// Hessian shifts, which leaves an unstable equilibrium) for the twist-free helix at several
// section factors t/t*, and the light-sculpture segments under dead load.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "common/error.h"
#include "rod_test_curves.h"
#include "rods/rod_design.h"
#include "rods/rod_stability.h"

namespace parafab {
namespace {

TEST(RodStability, HelixVerdictMatchesTheForwardSimulationForEachSectionFactor) {
  const SpaceCurve curve = rod_test::helix(0.1, 0.03, 3 * M_PI);
  int stable = 0, unstable = 0;
  // Not 1.5: there the Hessian at the target is barely positive (min/max 9e-10) yet the
  // simulation leaves (0.42 L): near the bifurcation the target's residual decides; the
  // verdict is a second-order test at the target, not at the discrete equilibrium.
  for (double factor : {1.0, 2.0, 4.0}) {
    RodDesignOptions o;
    o.max_radius = 0.004;
    o.geometry.circularity_factor = factor;
    const RodDesign d = design_rod(curve, 400, o);
    ASSERT_TRUE(d.ok());
    const DiscreteRodModel m = discrete_rod_model(d, curve, 100, o.material, o.loads, false);
    const RodStability st = rod_stability(m);
    const DiscreteRodResult r = simulate_discrete_rod(m);
    const double dev = max_node_distance(r.nodes, m.nodes) / curve.length();
    std::printf("[rod stability] helix t = %.1f t*: %s, %d negative eigenvalue(s), min/max diag %.2e, "
                "simulated deviation/L %.2e, %.1f ms\n",
                factor, st.stable ? "stable" : "UNSTABLE", st.negative, st.min_relative, dev, 1e3 * st.seconds);
    EXPECT_EQ(st.zero, 0);
    if (st.stable) {
      ++stable;
      EXPECT_TRUE(r.ok()) << r.message;
      EXPECT_LT(dev, 1e-4);  // floor: extension of the simulated rod
    } else {
      ++unstable;
      EXPECT_GT(dev, 0.01);
    }
  }
  EXPECT_GE(stable, 1);
  EXPECT_GE(unstable, 1);
}

// The verdict at the discrete equilibrium (rod_stability_at_equilibrium) on the same helix,
// now including t = 1.5 t*, where the target's Hessian is barely positive yet the rod leaves.
// Independent check of a "stable" verdict: the equilibrium perturbed by a smooth bump of
// 1 % of the length (nodes only) and released returns to it; of "unstable": the rod leaves.
TEST(RodStability, VerdictAtTheDiscreteEquilibriumCatchesTheNearBifurcationCase) {
  const SpaceCurve curve = rod_test::helix(0.1, 0.03, 3 * M_PI);
  const double L = curve.length();
  for (double factor : {1.0, 1.5, 2.0, 4.0}) {
    RodDesignOptions o;
    o.max_radius = 0.004;
    o.geometry.circularity_factor = factor;
    const RodDesign d = design_rod(curve, 400, o);
    ASSERT_TRUE(d.ok());
    const DiscreteRodModel m = discrete_rod_model(d, curve, 100, o.material, o.loads, false);
    const RodStability at_target = rod_stability(m);
    const RodStability st = rod_stability_at_equilibrium(m);
    std::printf("[rod stability] helix t = %.1f t*: at the target %s (min/max %.2e), at the equilibrium %s "
                "(distance/L %.2e, %d negative, min/max %.2e), %.1f ms\n",
                factor, at_target.stable ? "stable" : "UNSTABLE", at_target.min_relative,
                st.stable ? "stable" : "UNSTABLE", st.equilibrium_distance, st.negative, st.min_relative,
                1e3 * st.seconds);
    EXPECT_EQ(st.method, "hessian_at_equilibrium");
    EXPECT_TRUE(std::isfinite(st.equilibrium_distance));
    // With the simulation given (as the JSON entry reuses its validation run): the same verdict.
    const RodStability reused = rod_stability_at_equilibrium(m, simulate_discrete_rod(m));
    EXPECT_EQ(reused.stable, st.stable);
    EXPECT_EQ(reused.negative, st.negative);
    EXPECT_EQ(reused.equilibrium_distance, st.equilibrium_distance);
    EXPECT_EQ(st.verdict, factor < 2 ? "unstable" : "stable") << "factor " << factor;
    EXPECT_EQ(st.moved_away, factor < 2) << "factor " << factor;
    if (factor == 1.5) {
      EXPECT_TRUE(at_target.stable);  // the known blind spot of the target verdict
      EXPECT_FALSE(st.stable);
      EXPECT_GT(st.equilibrium_distance, 0.1);  // measured 0.42
      continue;
    }
    EXPECT_EQ(st.stable, at_target.stable) << "factor " << factor;
    if (!st.stable) continue;
    EXPECT_LT(st.equilibrium_distance, 1e-4);
    const DiscreteRodResult eq = simulate_discrete_rod(m);
    DiscreteRodModel bumped = m;
    const int N = static_cast<int>(m.nodes.size()) - 1;
    for (int i = 2; i <= N - 2; ++i)
      bumped.nodes[i] = eq.nodes[i] + 0.01 * L * std::sin(M_PI * i / N) * Vec3(0.6, 0.0, 0.8);
    bumped.material_normal = eq.material_normal;
    const DiscreteRodResult back = simulate_discrete_rod(bumped);
    ASSERT_TRUE(back.ok()) << back.message;
    EXPECT_LT(max_node_distance(back.nodes, eq.nodes) / L, 1e-6) << "factor " << factor;
  }
}

TEST(RodStability, InvalidModelThrows) {
  DiscreteRodModel m;
  m.nodes.assign(3, Vec3::Zero());
  EXPECT_THROW(rod_stability(m), Error);
}

}  // namespace
}  // namespace parafab
