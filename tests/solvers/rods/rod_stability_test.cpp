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

TEST(RodStability, InvalidModelThrows) {
  DiscreteRodModel m;
  m.nodes.assign(3, Vec3::Zero());
  EXPECT_THROW(rod_stability(m), Error);
}

}  // namespace
}  // namespace parafab
