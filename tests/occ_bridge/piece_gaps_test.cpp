// Gaps between the pieces of a cut cell (thesis §6.4.4, the d of Eq. 6.24) against a closed form.
#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include <BRepAlgoAPI_Cut.hxx>
#include <BRepAlgoAPI_Fuse.hxx>
#include <BRepBuilderAPI_Transform.hxx>
#include <BRepPrimAPI_MakeBox.hxx>
#include <BRepPrimAPI_MakeCylinder.hxx>
#include <cmath>
#include <cstdio>

#include "face_lookup.h"
#include "face_model.h"
#include "grid_model.h"
#include "occt_shape.h"
#include "part_reader.h"
#include "piece_gaps.h"
#include "shape_parameters.h"

namespace parafab::occ {
namespace {

// A 60 × 40 × 20 block with a through slot along x from the end x = 0, 2r wide, ending in a
// half-cylinder (axis z at x = x0, y = 20), turned `degrees` about the x axis through the block's
// centre: the slot's walls and end cut the grid's cells obliquely, while the grid planes
// x = const still meet the end cylinder square to its axis. On such a plane x = c with
// x0 < c < x0 + r the slot's section is a band of width 2·sqrt(r² − (c − x0)²).
std::shared_ptr<const PartShape> slotted_block(double x0, double r, double degrees) {
  const TopoDS_Shape block = BRepPrimAPI_MakeBox(gp_Pnt(0, 0, 0), gp_Pnt(60, 40, 20)).Shape();
  const TopoDS_Shape slot = BRepAlgoAPI_Fuse(BRepPrimAPI_MakeBox(gp_Pnt(-1, 20 - r, -1), gp_Pnt(x0, 20 + r, 21)).Shape(),
                                             BRepPrimAPI_MakeCylinder(gp_Ax2(gp_Pnt(x0, 20, -1), gp::DZ()), r, 22).Shape())
                                .Shape();
  gp_Trsf turn;
  turn.SetRotation(gp_Ax1(gp_Pnt(30, 20, 10), gp::DX()), degrees * M_PI / 180);
  const TopoDS_Shape cut = BRepAlgoAPI_Cut(block, slot).Shape();
  return make_part(BRepBuilderAPI_Transform(cut, turn, true).Shape(), "slotted block");
}

GridModel model_of(const PartShape& part) {
  GridModelOptions options;
  options.grid.cell_size = 5;
  options.grid.anchored = true;
  options.grid.origin = xfem::Vec3(2, 0.3, 0.7);  // planes x = 27, 32, 37: one inside the slot's end
  return build_grid_model(part, options);
}

// Cells x ∈ [27, 32] the slot splits: the gap between their pieces is the band's width on the
// plane x = 32 (c − x0 = 1), where both pieces' closest points lie on the end cylinder's section
// lines; its derivatives by the end cylinder's axis point x and radius against the closed form
// and against differences of rebuilt parts.
TEST(PieceGaps, SlotEndGapMatchesTheClosedFormAndItsDerivatives) {
  const double x0 = 31, r = 2, c = 32, degrees = 20;
  const auto part = slotted_block(x0, r, degrees);
  const GridModel grid = model_of(*part);
  ASSERT_TRUE(grid.done) << grid.message;
  const PieceGapResult gaps = piece_gaps(*part, grid);
  ASSERT_TRUE(gaps.done) << gaps.message;
  std::printf("%d cells with 2+ pieces, %zu pairs, %.3f s, centroid mismatch %.2e\n", gaps.cells_checked, gaps.gaps.size(),
              gaps.seconds, gaps.max_centroid_mismatch);
  EXPECT_LT(gaps.max_centroid_mismatch, 1e-6);
  const double closed = 2 * std::sqrt(r * r - (c - x0) * (c - x0));
  const double d_x0 = 2 * (c - x0) / std::sqrt(r * r - (c - x0) * (c - x0));  // ∂/∂x0
  const double d_r = 2 * r / std::sqrt(r * r - (c - x0) * (c - x0));           // ∂/∂r
  const FaceModel model = build_face_model(*part);
  const ShapeParameters sp = build_shape_parameters(model);
  // The end cylinder: the face through the slot's tip (x0 + r, 20, 10) turned.
  const Eigen::Vector3d tip = Eigen::AngleAxisd(degrees * M_PI / 180, Eigen::Vector3d::UnitX()) *
                                  (Eigen::Vector3d(x0 + r, 20, 10) - Eigen::Vector3d(30, 20, 10)) +
                              Eigen::Vector3d(30, 20, 10);
  // OCCT splits the end cylinder into two half faces at its seam, each with its own parameter
  // block (the face model ties them as one surface): moving the cylinder moves both blocks.
  const int end = face_at_point(*part, tip, 1e-6);
  std::vector<int> halves;
  for (int f = 0; f < part->face_count(); ++f)
    if (model.faces[f].primitive.type == model.faces[end].primitive.type && sp.block(f) &&
        (sp.initial.segment(sp.block(f)->offset, 7) - sp.initial.segment(sp.block(end)->offset, 7)).norm() < 1e-9)
      halves.push_back(f);
  ASSERT_EQ(halves.size(), 2u);
  auto along = [&](const Eigen::MatrixXd& g, size_t i, const char* name) {  // both halves moved
    double sum = 0;
    for (int f : halves) sum += g(i, parameter_index(sp, f, name));
    return sum;
  };
  std::vector<char> complete;
  const Eigen::MatrixXd g = piece_gap_gradient(gaps.gaps, sp, sp.initial, &complete);
  int checked = 0;
  for (size_t i = 0; i < gaps.gaps.size(); ++i) {
    const PieceGap& gap = gaps.gaps[i];
    const xfem::Box3& box = grid.elements[gap.element_a].box;
    if (std::abs(box.max.x() - c) > 1e-9 || gap.cell_b != gap.cell) continue;
    const double fa = xfem::volume_fraction(grid.elements[gap.element_a]);
    const double fb = xfem::volume_fraction(grid.elements[gap.element_b]);
    std::printf("cell (%d, %d, %d): fractions %.3f %.3f, gap %.12g (closed form %.12g), ends on faces %d %d, "
                "d/dx0 %.12g (%.12g), d/dr %.12g (%.12g); off by %.1e, %.1e, %.1e\n",
                gap.cell[0], gap.cell[1], gap.cell[2], fa, fb, gap.distance, closed, gap.a.faces.size() == 1 ? gap.a.faces[0] : -1, gap.b.faces.size() == 1 ? gap.b.faces[0] : -1,
                along(g, i, "axis point x"), d_x0, along(g, i, "radius"), d_r, std::abs(gap.distance - closed),
                std::abs(along(g, i, "axis point x") - d_x0), std::abs(along(g, i, "radius") - d_r));
    ++checked;
    EXPECT_FALSE(gap.joined);
    EXPECT_NEAR(gap.distance, closed, 1e-12);  // measured 2e-14 … 1e-13
    ASSERT_EQ(gap.a.faces.size(), 1u);
    ASSERT_EQ(gap.b.faces.size(), 1u);
    EXPECT_TRUE(gap.a.faces[0] == halves[0] || gap.a.faces[0] == halves[1]) << gap.a.faces[0];
    EXPECT_TRUE(gap.b.faces[0] == halves[0] || gap.b.faces[0] == halves[1]) << gap.b.faces[0];
    ASSERT_TRUE(complete[i]);
    EXPECT_NEAR(along(g, i, "axis point x"), d_x0, 1e-12);  // measured ≤ 6e-14
    EXPECT_NEAR(along(g, i, "radius"), d_r, 1e-12);
  }
  EXPECT_EQ(checked, 3);
  // Differences of rebuilt parts (the same cells, the part made again by OCCT).
  auto gap_at = [&](double x, double radius, std::array<int, 3> cell) {
    const auto moved = slotted_block(x, radius, degrees);
    const GridModel m = model_of(*moved);
    EXPECT_TRUE(m.done) << m.message;
    const PieceGapResult gr = piece_gaps(*moved, m);
    for (const PieceGap& q : gr.gaps)
      if (q.cell == cell) return q.distance;
    ADD_FAILURE() << "no gap in that cell";
    return 0.0;
  };
  for (size_t i = 0; i < gaps.gaps.size(); ++i) {
    const PieceGap& gap = gaps.gaps[i];
    if (std::abs(grid.elements[gap.element_a].box.max.x() - c) > 1e-9 || gap.cell_b != gap.cell) continue;
    const double h = 1e-4;
    const double fd_x0 = (gap_at(x0 + h, r, gap.cell) - gap_at(x0 - h, r, gap.cell)) / (2 * h);
    const double fd_r = (gap_at(x0, r + h, gap.cell) - gap_at(x0, r - h, gap.cell)) / (2 * h);
    std::printf("differences of rebuilt parts: d/dx0 %.10g, d/dr %.10g; off by %.1e, %.1e\n", fd_x0, fd_r,
                std::abs(fd_x0 - along(g, i, "axis point x")), std::abs(fd_r - along(g, i, "radius")));
    EXPECT_NEAR(fd_x0, along(g, i, "axis point x"), 1e-8);  // measured 2.4e-9 (step 1e-4)
    EXPECT_NEAR(fd_r, along(g, i, "radius"), 1e-8);  // measured 9.9e-10
    break;  // one cell is enough: the parts are rebuilt and cut four times
  }
}

}  // namespace
}  // namespace parafab::occ

namespace parafab::occ {
namespace {
TEST(PieceGapsScratch, Cost) {
  for (const char* name : {"plate_holes", "wrench", "wheel", "housing", "l_bracket"}) {
    const auto part = read_part(std::string(PARAFAB_SAMPLES_DIR) + "/parts/" + name + ".step");
    for (int cells : {10, 16, 32}) {
      GridModelOptions o;
      o.grid.cells_longest = cells;
      const GridModel m = build_grid_model(*part, o);
      const PieceGapResult g = piece_gaps(*part, m);
      int close = 0;
      double h = m.elements[0].box.size().minCoeff();
      for (const auto& q : g.gaps) {
        close += q.distance < 0.25 * h;
        if (q.distance < 0.25 * h && std::string(name) == "plate_holes" && close < 6)
          std::printf("  (%d %d %d)-(%d %d %d) fractions %.3g %.3g: %.3g joined %d faces %d %d at %.3f %.3f %.3f\n", q.cell[0], q.cell[1], q.cell[2],
                      q.cell_b[0], q.cell_b[1], q.cell_b[2], xfem::volume_fraction(m.elements[q.element_a]),
                      xfem::volume_fraction(m.elements[q.element_b]), q.distance, q.joined, int(q.a.faces.size()), int(q.b.faces.size()), q.a.point.x(), q.a.point.y(), q.a.point.z());
      }
      const ShapeParameters sp = build_shape_parameters(build_face_model(*part));
      std::vector<char> complete;
      piece_gap_gradient(g.gaps, sp, sp.initial, &complete);
      int whole = 0;
      for (char c : complete) whole += c;
      std::printf("%s %d cells: cut %.2f s rules %.2f s; %d cells with 2+ pieces, %zu pairs, %d closer than h/4, %d with derivatives; gaps %.2f s\n", name, cells,
                  m.cut_seconds, m.rule_seconds, g.cells_checked, g.gaps.size(), close, whole, g.seconds);
    }
  }
}
}  // namespace
}  // namespace parafab::occ
