// Cut-cell quadrature on real B-reps against OpenCASCADE's own mass properties (whole part
// by BRepGProp, and per cell by a Boolean common of the cell box with the part).
#include <gtest/gtest.h>

#include <cstdio>

#include "occt_mass_properties.h"
#include "part_integration.h"
#include "part_reader.h"

namespace parafab::occ {
namespace {

std::string sample(const char* name) { return std::string(PARAFAB_SAMPLES_DIR) + "/parts/" + name; }

void expect_matches_occt(const char* name, int cells, double tol) {
  const auto part = read_part(sample(name));
  IntegrationOptions o;
  o.grid.cells_longest = cells;
  const IntegrationResult r = integrate_part(*part, o);
  ASSERT_TRUE(r.done) << r.message;
  std::printf("%-16s cells %d: cut %zu cells / %zu subvolumes, interior %zu; errors V %.2e c %.2e I %.2e; "
              "residual %.1e closure %.1e; cut %.3f s rules %.3f s occt %.3f s\n",
              name, cells, r.cut.cut_cells.size(), r.cut.subvolumes.size(), r.cut.interior_cells.size(),
              r.errors.volume, r.errors.center, r.errors.inertia, r.max_moment_residual,
              r.max_closure_defect, r.cut_seconds, r.rule_seconds, r.occt_seconds);
  EXPECT_LT(r.errors.volume, tol) << name;
  EXPECT_LT(r.errors.center, tol) << name;
  EXPECT_LT(r.errors.inertia, tol) << name;
  EXPECT_EQ(r.rules_not_ok, 0) << name;
}

TEST(PartIntegration, BoxIsExact) { expect_matches_occt("box.step", 4, 1e-12); }
TEST(PartIntegration, CylinderMatchesOcct) { expect_matches_occt("cylinder.step", 6, 1e-8); }
TEST(PartIntegration, FilletedBracketMatchesOcct) { expect_matches_occt("l_bracket.step", 6, 1e-7); }
TEST(PartIntegration, RingMatchesOcct) { expect_matches_occt("ring.step", 6, 1e-7); }
TEST(PartIntegration, HalfTorusMatchesOcct) { expect_matches_occt("half_torus.step", 6, 1e-7); }

TEST(PartIntegration, EveryCutCellMatchesItsBoolean) {
  const auto part = read_part(sample("l_bracket.step"));
  IntegrationOptions o;
  o.grid.cells_longest = 4;
  o.occt_reference = false;
  const IntegrationResult r = integrate_part(*part, o);
  ASSERT_TRUE(r.done) << r.message;
  double worst = 0;
  for (const auto& cell : r.cut.cut_cells) {
    xfem::MassAccumulator acc;
    for (int s : cell.subvolumes) acc.add(r.rules[s].rule.points, r.rules[s].rule.weights);
    const xfem::Box3 box = r.cut.cell_box(cell.index);
    const CellBooleanResult ref = occt_cell_properties(*part, box);
    ASSERT_TRUE(ref.done);
    EXPECT_EQ(static_cast<int>(cell.subvolumes.size()), ref.solids);
    const double err = std::abs(acc.result().volume - ref.properties.volume) / box.volume();
    worst = std::max(worst, err);
  }
  std::printf("worst per-cell volume error / cell volume: %.2e over %zu cut cells\n", worst, r.cut.cut_cells.size());
  EXPECT_LT(worst, 1e-6);
}

}  // namespace
}  // namespace parafab::occ
