// Where cut-cell integration is known to struggle (thesis §6.3, Fig. 6.4): tiny cut fractions,
// grid planes through vertices and along faces, walls thinner than a cell, holes smaller than a
// cell, several holes in one cell, fillets whose tangent faces meet inside a cell. Each case
// shows what the user gets, against OCCT's mass properties and closed forms.
#include <gtest/gtest.h>

#include <BRepAlgoAPI_Cut.hxx>
#include <BRepPrimAPI_MakeBox.hxx>
#include <BRepPrimAPI_MakeCylinder.hxx>
#include <gp_Ax2.hxx>

#include <cmath>
#include <cstdio>

#include "occt_mass_properties.h"
#include "occt_shape.h"
#include "part_integration.h"

namespace parafab::occ {
namespace {

std::shared_ptr<const PartShape> part_of(const TopoDS_Shape& s) { return make_part(s, "test shape"); }

TopoDS_Shape box(double x0, double y0, double z0, double x1, double y1, double z1) {
  return BRepPrimAPI_MakeBox(gp_Pnt(x0, y0, z0), gp_Pnt(x1, y1, z1)).Shape();
}

TopoDS_Shape z_cylinder(double x, double y, double z0, double r, double h) {
  return BRepPrimAPI_MakeCylinder(gp_Ax2(gp_Pnt(x, y, z0), gp_Dir(0, 0, 1)), r, h).Shape();
}

IntegrationResult integrate(const PartShape& part, double h, double perturbation = 1e-4) {
  IntegrationOptions o;
  o.grid.cell_size = h;
  o.grid.anchored = true;
  o.grid.perturbation = perturbation;
  return integrate_part(part, o);
}

TEST(GridFailureModes, TinyCutFractionsStayBoundedAndAccurate) {
  // A cylinder (R = 10) whose side pokes a depth δ through the grid plane x = 10 − δ: the cap
  // in the outer cell column has area ≈ (4/3)√(2R) δ^1.5, a volume fraction down to ~1e-9.
  const double R = 10, H = 5, h = 5;
  for (double delta : {1e-2, 1e-4, 2.6e-6}) {
    const auto part = part_of(z_cylinder(0, 0, 0, R, H));
    IntegrationOptions o;
    o.grid.cell_size = h;
    o.grid.anchored = true;
    o.grid.origin = xfem::Vec3(10 - delta, 0.37, 0.21);  // a grid plane at x = R − δ (y, z planes off the seam)
    o.grid.perturbation = 0;                       // keep the sliver on purpose
    o.grid.shift_retries = 0;                      // and this grid
    const IntegrationResult r = integrate_part(*part, o);
    ASSERT_TRUE(r.done) << r.message;
    // The sliver: subvolumes whose cell starts at x = R − δ.
    double sliver = 0, largest_weight = 0;
    for (size_t s = 0; s < r.cut.subvolumes.size(); ++s)
      if (std::abs(r.cut.subvolumes[s].cell.min.x() - (R - delta)) < 1e-9) {
        for (double w : r.rules[s].rule.weights) {
          ASSERT_TRUE(std::isfinite(w));
          largest_weight = std::max(largest_weight, std::abs(w));
          sliver += w;
        }
      }
    const double theta = std::acos((R - delta) / R);
    const double exact = H * (R * R * (theta - std::sin(theta) * std::cos(theta)));  // segment area × H
    const double fraction = exact / (h * h * h);
    std::printf("delta %.1e: sliver volume fraction %.2e per column, relative error %.2e, "
                "largest |weight| / cell volume %.2e, whole-part volume error %.2e\n",
                delta, fraction, std::abs(sliver - exact) / exact, largest_weight / (h * h * h), r.errors.volume);
    EXPECT_LT(std::abs(sliver - exact), 1e-9 * h * h * h);  // error relative to the cell, not the sliver
    EXPECT_LT(largest_weight, 10 * h * h * h);               // no blow-up of weights
    EXPECT_LT(r.errors.volume, 1e-9);
  }
}

TEST(GridFailureModes, GridPlanesThroughVerticesAndAlongFacesAreShifted) {
  // An L-shaped block with vertices and faces on x = 5 and y = 5, exactly on grid planes.
  BRepAlgoAPI_Cut cut(box(0, 0, 0, 10, 10, 10), box(5, 5, -1, 11, 11, 11));
  const auto part = part_of(cut.Shape());
  const IntegrationResult r = integrate(*part, 2.5);
  ASSERT_TRUE(r.done) << r.message;
  EXPECT_GT(r.cut.shifted_planes, 0);
  EXPECT_NEAR(r.by_rules.volume, 750.0, 1e-9);
  EXPECT_LT(r.errors.inertia, 1e-12);
  // Without the plane shift the face route fails on planes through vertices; the grid is then
  // moved as a whole (first along the failing plane's axis, then along all three: the y = 5
  // planes still pass through vertices after the x shift) and the volume is exact again.
  const IntegrationResult unshifted = integrate(*part, 2.5, 0.0);
  ASSERT_TRUE(unshifted.done) << unshifted.message;
  EXPECT_EQ(unshifted.cut.shifted_planes, 0);
  EXPECT_FALSE(unshifted.cut.retry_reason.empty());
  std::printf("no plane shift: %s; grid moved by (%g, %g, %g)\n", unshifted.cut.retry_reason.c_str(),
              unshifted.cut.grid_shift.x(), unshifted.cut.grid_shift.y(), unshifted.cut.grid_shift.z());
  EXPECT_NEAR(unshifted.by_rules.volume, 750.0, 1e-9);
}

TEST(GridFailureModes, WallThinnerThanACell) {
  const auto part = part_of(box(0, 0, 0, 40, 40, 0.5));
  const IntegrationResult r = integrate(*part, 5);
  ASSERT_TRUE(r.done) << r.message;
  EXPECT_EQ(r.cut.cut_cells.size(), 64u);  // one layer of 8 × 8 cut cells
  EXPECT_EQ(r.cut.connections.size(), 2u * 8 * 7);
  EXPECT_NEAR(r.by_rules.volume, 800.0, 1e-10);
  EXPECT_LT(r.errors.inertia, 1e-12);
}

TEST(GridFailureModes, HolesSmallerThanACellSeveralInOneCell) {
  // Block 20³ with three holes of radius 0.4 inside the cell column [5, 10]², and one of
  // radius 1 in another column; h = 5.
  TopoDS_Shape s = box(0, 0, 0, 20, 20, 20);
  for (const auto& [x, y, r] : std::vector<std::array<double, 3>>{{6.2, 6.5, 0.4}, {8.1, 7.0, 0.4}, {7.0, 8.6, 0.4}, {13, 16, 1}})
    s = BRepAlgoAPI_Cut(s, z_cylinder(x, y, -1, r, 22)).Shape();
  const auto part = part_of(s);
  const IntegrationResult r = integrate(*part, 5);
  ASSERT_TRUE(r.done) << r.message;
  const double exact = 8000 - 20 * M_PI * (3 * 0.16 + 1);
  std::printf("holes: volume error %.2e, inertia error %.2e, %zu cut cells\n",
              std::abs(r.by_rules.volume - exact) / exact, r.errors.inertia, r.cut.cut_cells.size());
  EXPECT_LT(std::abs(r.by_rules.volume - exact) / exact, 1e-10);
  EXPECT_LT(r.errors.inertia, 1e-9);
  for (const auto& cell : r.cut.cut_cells) EXPECT_EQ(cell.subvolumes.size(), 1u);  // holes do not split cells
}

TEST(GridFailureModes, FilletTangenciesInsideCoarseCells) {
  // The filleted L-bracket on a 2-cell grid: fillet faces meet their planes tangentially
  // inside cells. Every cell against its own OCCT Boolean.
  const auto part = read_part(std::string(PARAFAB_SAMPLES_DIR) + "/parts/l_bracket.step");
  IntegrationOptions o;
  o.grid.cells_longest = 2;
  const IntegrationResult r = integrate_part(*part, o);
  ASSERT_TRUE(r.done) << r.message;
  EXPECT_LT(r.errors.volume, 1e-10);
  for (const auto& cell : r.cut.cut_cells) {
    const xfem::Box3 b = r.cut.cell_box(cell.index);
    const CellBooleanResult ref = occt_cell_properties(*part, b);
    ASSERT_TRUE(ref.done);
    EXPECT_LT(std::abs(cut_cell_properties(r, cell).volume - ref.properties.volume) / b.volume(), 1e-10);
  }
}

}  // namespace
}  // namespace parafab::occ
