// Framed equilibrium curves (thesis Prop. 10): the frame of a designed rod passes; a
// non-parallel curve with a twist-free frame fails while a helix with one passes; the
// returned complex yields sections in K that solve Eq. 5.11 for the prescribed twist.
#include <gtest/gtest.h>

#include <cmath>

#include "rod_test_curves.h"
#include "rods/framed_equilibrium.h"
#include "rods/rod_design.h"

namespace parafab {
namespace {

TEST(RodFramed, DesignedFramePassesAndGivesAdmissibleSections) {
  const SpaceCurve curve = rod_test::light_sculpture(0.2, 0, 4 * M_PI / 3);
  RodDesignOptions o;
  o.geometry.circularity_factor = 1.5;  // J = 4ψ(I) < 4ψ_max strictly
  const RodDesign d = design_rod(curve, 400, o);
  ASSERT_TRUE(d.ok());
  std::vector<double> tau;
  for (const auto& s : d.sections) tau.push_back(s.twist);
  const FramedEquilibriumResult r = check_framed_equilibrium(d.samples, tau, o.material);
  ASSERT_TRUE(r.feasible) << r.message;
  EXPECT_LT(r.max_torsion_fraction, 1.0);
  EXPECT_GT(r.max_torsion_fraction, 0.0);
  // From the returned complex: J = ⟨γ', h⟩/(μτ) > 0 and I on the family with 4ψ(I) = J
  // exists (J < 4⟨ωn, h⟩/(Eκ²)): check the bound pointwise with the exact numbers.
  const double E = o.material.youngs_modulus, mu = o.material.shear_modulus();
  for (size_t i = 0; i < d.samples.size(); ++i) {
    const Vec3 h = r.c.cross(d.samples[i].point) + r.c_bar;
    const double J = d.samples[i].tangent.dot(h) / (mu * tau[i]);
    EXPECT_GT(J, 0) << i;
    EXPECT_LT(J, 4 * d.samples[i].omega_n().dot(h) / (E * d.samples[i].kappa * d.samples[i].kappa)) << i;
  }
}

TEST(RodFramed, TwistFreeFrameOnlyForParallelCurves) {
  const RodMaterial m = RodMaterial::smooth_sil_960();
  const auto helix = sample_by_arc_length(rod_test::helix(0.1, 0.03, 3 * M_PI), 300);
  const FramedEquilibriumResult a = check_framed_equilibrium(helix, std::vector<double>(300, 0.0), m);
  EXPECT_TRUE(a.feasible) << a.message;
  EXPECT_EQ(a.zero_twist_samples, 300);
  const auto general = sample_by_arc_length(rod_test::light_sculpture(0.2, 0, 4 * M_PI / 3), 300);
  const FramedEquilibriumResult b = check_framed_equilibrium(general, std::vector<double>(300, 0.0), m);
  EXPECT_FALSE(b.feasible);
  EXPECT_EQ(b.lp_status, LpStatus::Infeasible);
}

}  // namespace
}  // namespace parafab
