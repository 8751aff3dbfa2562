// Cut-cell quadrature on real B-reps against OpenCASCADE's own mass properties (whole part
// by BRepGProp, and per cell by a Boolean common of the cell box with the part).
#include <gtest/gtest.h>

#include <BRepBuilderAPI_Transform.hxx>
#include <gp_Ax1.hxx>
#include <gp_Trsf.hxx>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "occt_shape.h"

#include "occt_mass_properties.h"
#include "part_integration.h"
#include "face_model.h"
#include "nurbs_surface.h"
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

TEST(GridCut, IntersectionCurvesLieOnTheirPlanesInsideTheirCells) {
  const auto part = read_part(sample("l_bracket.step"));
  GridOptions o;
  o.cells_longest = 5;
  const GridCut g = cut_by_grid(*part, o);
  ASSERT_TRUE(g.done) << g.message;
  int face_plane = 0, face_face = 0;
  for (const CutCurve& c : g.curves) {
    const xfem::Box3& cell = g.subvolumes[c.subvolume].cell;
    const double tol = 1e-7 * cell.size().maxCoeff();
    for (const auto& p : c.points)
      EXPECT_TRUE(((p - cell.min).array() >= -tol).all() && ((cell.max - p).array() >= -tol).all());
    if (c.kind == CutCurve::FaceFace) {
      ++face_face;
      EXPECT_GE(c.sources[0], 0);
      EXPECT_GE(c.sources[1], 0);
      continue;
    }
    ++face_plane;
    const int axis = -1 - std::min(c.sources[0], c.sources[1]);
    ASSERT_GE(axis, 0);
    ASSERT_LT(axis, 3);
    for (const auto& p : c.points) {
      double d = 1e300;
      for (double x : g.planes[axis]) d = std::min(d, std::abs(p[axis] - x));
      EXPECT_LT(d, 1e-9);
    }
  }
  EXPECT_GT(face_plane, 0);
  EXPECT_GT(face_face, 0);  // fillet–plane and plate edges inside cells
}

TEST(GridCut, NurbsPatchesAreThePiecesOfTheFaceModelsNurbs) {
  // With GridOptions::nurbs, every B-rep patch evaluates like its face-model NURBS at the same
  // (u, v): the data later shape derivatives with respect to control points need.
  const auto part = read_part(sample("l_bracket.step"));
  const FaceModel model = build_face_model(*part);
  IntegrationOptions o;
  o.grid.cells_longest = 5;
  o.grid.nurbs = true;
  const IntegrationResult r = integrate_part(*part, o);
  ASSERT_TRUE(r.done) << r.message;
  // Rational reparameterized fillets make the area factor less smooth: ~1e-9 instead of 1e-12.
  EXPECT_LT(r.errors.volume, 1e-8);
  EXPECT_LT(r.errors.inertia, 1e-8);
  int checked = 0;
  for (const auto& sv : r.cut.subvolumes)
    for (const auto& patch : sv.patches) {
      if (patch.source_face < 0) continue;
      for (const auto& loop : patch.loops)
        for (size_t k = 0; k < loop.points.size(); k += 7) {
          const xfem::Vec2 uv = loop.points[k];
          xfem::Vec3 X, Xu, Xv, Y, Yu, Yv;
          patch.surface->evaluate(uv.x(), uv.y(), X, Xu, Xv);
          evaluate(model.faces[patch.source_face].nurbs, uv.x(), uv.y(), Y, Yu, Yv);
          EXPECT_LT((X - Y).norm(), 1e-9 * 100);
          EXPECT_LT((Xu - Yu).norm(), 1e-7 * (1 + Xu.norm()));
          ++checked;
        }
    }
  EXPECT_GT(checked, 100);
}

TEST(GridCut, NurbsPatchesOnTheFaceRouteAreThePiecesOfTheFaceModelsNurbs) {
  // The face route with GridOptions::nurbs cuts the converted faces (traced level curves on
  // B-splines): its patches evaluate like the face model's NURBS too, on the bracket turned
  // against the grid, and its rules hold the volume as the splitter route's do.
  const auto read = read_part(sample("l_bracket.step"));
  gp_Trsf rot;
  rot.SetRotation(gp_Ax1(gp_Pnt(10, 20, 5), gp_Dir(1, 2, 3)), 17 * M_PI / 180);
  const auto part = make_part(BRepBuilderAPI_Transform(read->shape, rot, true).Shape(), "turned bracket");
  const FaceModel model = build_face_model(*part);
  IntegrationOptions o;
  o.grid.cells_longest = 5;
  o.grid.nurbs = true;
  o.grid.method = CutMethod::FaceCut;
  const IntegrationResult r = integrate_part(*part, o);
  ASSERT_TRUE(r.done) << r.message;
  ASSERT_EQ(r.cut.method, CutMethod::FaceCut) << r.cut.retry_reason;
  std::printf("face route on NURBS: volume error %.1e, inertia %.1e\n", r.errors.volume, r.errors.inertia);
  EXPECT_LT(r.errors.volume, 3e-9);  // measured 2.4e-9 (rational fillets, as on the splitter route)
  EXPECT_LT(r.errors.inertia, 4e-9);  // measured 3.3e-9
  int checked = 0;
  double worst = 0;
  for (const auto& sv : r.cut.subvolumes)
    for (const auto& patch : sv.patches) {
      if (patch.source_face < 0) continue;
      for (const auto& loop : patch.loops)
        for (size_t k = 0; k < loop.points.size(); k += 7) {
          const xfem::Vec2 uv = loop.points[k];
          xfem::Vec3 X, Xu, Xv, Y, Yu, Yv;
          patch.surface->evaluate(uv.x(), uv.y(), X, Xu, Xv);
          evaluate(model.faces[patch.source_face].nurbs, uv.x(), uv.y(), Y, Yu, Yv);
          worst = std::max(worst, (X - Y).norm());
          ++checked;
        }
    }
  std::printf("  %d points, worst distance to the face model's NURBS %.1e\n", checked, worst);
  EXPECT_LT(worst, 1e-11);  // measured 1.4e-12
  EXPECT_GT(checked, 100);
}

TEST(GridCut, NurbsOnTheFaceRouteForTheCurvedSamples) {
  // NURBS-converted tori and cylinders on the face route hold OCCT's volume like the splitter
  // route (rational surfaces: 2.1e-8 half torus, 5.0e-9 wheel, 1.9e-8 wrench, 9.1e-10 housing
  // (splitter 9.0e-10), measured). The housing failed the closure check (cut curves ending at
  // cell-face corners on the grid's box) until the corner snap of the face route.
  for (const auto& [name, tol] : std::vector<std::pair<std::string, double>>{{"half_torus", 2.5e-8}, {"wheel", 6e-9}, {"wrench", 2.5e-8}, {"housing", 2e-9}}) {
    const auto part = read_part(sample((name + ".step").c_str()));
    IntegrationOptions o;
    o.grid.cells_longest = 6;
    o.grid.nurbs = true;
    o.grid.method = CutMethod::FaceCut;
    const IntegrationResult r = integrate_part(*part, o);
    ASSERT_TRUE(r.done) << name << ": " << r.message;
    std::printf("%-10s %s, volume error %.1e %s\n", name.c_str(), r.cut.method == CutMethod::FaceCut ? "face" : "splitter",
                r.errors.volume, r.cut.retry_reason.c_str());
    EXPECT_EQ(r.cut.method, CutMethod::FaceCut) << name << ": " << r.cut.retry_reason;
    EXPECT_LT(r.errors.volume, tol) << name;
  }
}

TEST(PartIntegration, EveryCutCellMatchesItsBoolean) {
  const auto part = read_part(sample("l_bracket.step"));
  IntegrationOptions o;
  o.grid.cells_longest = 4;
  o.occt_reference = false;
  const IntegrationResult r = integrate_part(*part, o);
  ASSERT_TRUE(r.done) << r.message;
  double worst = 0;
  for (const auto& cell : r.cut.cut_cells) {
    const xfem::Box3 box = r.cut.cell_box(cell.index);
    const CellBooleanResult ref = occt_cell_properties(*part, box);
    ASSERT_TRUE(ref.done);
    EXPECT_EQ(static_cast<int>(cell.subvolumes.size()), ref.solids);
    const double err = std::abs(cut_cell_properties(r, cell).volume - ref.properties.volume) / box.volume();
    worst = std::max(worst, err);
  }
  std::printf("worst per-cell volume error / cell volume: %.2e over %zu cut cells\n", worst, r.cut.cut_cells.size());
  // The per-cell Boolean route sums to the whole part too (cut cells + interior cells).
  double total = 0;
  for (const auto& cell : r.cut.cut_cells) total += occt_cell_properties(*part, r.cut.cell_box(cell.index)).properties.volume;
  for (const auto& ijk : r.cut.interior_cells) total += r.cut.cell_box(ijk).volume();
  EXPECT_NEAR(total, occt_mass_properties(*part).volume, 1e-9 * total);
  EXPECT_LT(worst, 1e-6);
}

}  // namespace
}  // namespace parafab::occ
