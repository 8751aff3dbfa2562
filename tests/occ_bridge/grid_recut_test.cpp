// Two-level (block) cutting and re-cutting only the blocks a parameter change touches
// (issue 4): both must give exactly the cut, the rules and the solution of one global split.
#include <gtest/gtest.h>

#include <BRepAlgoAPI_Cut.hxx>
#include <BRepGProp.hxx>
#include <BRepPrimAPI_MakeBox.hxx>
#include <BRepPrimAPI_MakeCylinder.hxx>
#include <GProp_GProps.hxx>
#include <gp_Ax2.hxx>

#include <algorithm>
#include <cstdio>
#include <limits>
#include <map>
#include <set>

#include "grid_model.h"
#include "occt_shape.h"
#include "part_reader.h"
#include "xfem/volume_rules.h"

namespace parafab::occ {
namespace {

std::string sample(const char* name) { return std::string(PARAFAB_SAMPLES_DIR) + "/parts/" + name; }

// A 100 × 60 × 12 plate with a through hole of radius r at (70, 30): the parameter change
// moves only the hole's face.
std::shared_ptr<const PartShape> plate_with_hole(double r) {
  const TopoDS_Shape box = BRepPrimAPI_MakeBox(gp_Pnt(0, 0, 0), 100, 60, 12).Shape();
  const TopoDS_Shape hole = BRepPrimAPI_MakeCylinder(gp_Ax2(gp_Pnt(70, 30, -5), gp::DZ()), r, 22).Shape();
  return make_part(BRepAlgoAPI_Cut(box, hole).Shape(), "plate with hole r=" + std::to_string(r));
}

double occt_volume(const PartShape& p) {
  GProp_GProps props;
  BRepGProp::VolumeProperties(p.shape, props);
  return props.Mass();
}

double model_volume(const GridModel& m) {
  double v = 0;
  for (const auto& e : m.elements)
    for (double w : e.rule.weights) v += w;
  return v;
}

// The cut as cell-level facts that do not depend on the order pieces were built in.
struct CutSummary {
  std::multiset<std::array<int, 3>> subvolume_cells, interior;
  std::multiset<std::array<int, 6>> connections, interior_connections;
};

CutSummary summary(const GridCut& g) {
  CutSummary s;
  std::vector<std::array<int, 3>> cell_of(g.subvolumes.size());
  for (const auto& c : g.cut_cells)
    for (int sv : c.subvolumes) cell_of[sv] = c.index, s.subvolume_cells.insert(c.index);
  for (const auto& c : g.interior_cells) s.interior.insert(c);
  for (const auto& [a, b] : g.connections) {
    auto p = cell_of[a], q = cell_of[b];
    if (q < p) std::swap(p, q);
    s.connections.insert({p[0], p[1], p[2], q[0], q[1], q[2]});
  }
  for (const auto& [a, c] : g.interior_connections) {
    const auto p = cell_of[a], q = g.interior_cells[c];
    s.interior_connections.insert({p[0], p[1], p[2], q[0], q[1], q[2]});
  }
  return s;
}

void expect_same_cut(const GridCut& a, const GridCut& b, const std::string& what) {
  const CutSummary x = summary(a), y = summary(b);
  EXPECT_EQ(x.subvolume_cells, y.subvolume_cells) << what;
  EXPECT_EQ(x.interior, y.interior) << what;
  EXPECT_EQ(x.connections, y.connections) << what;
  EXPECT_EQ(x.interior_connections, y.interior_connections) << what;
}

// Face 0 of a box-based part (x = 0) clamped, gravity along −z, steel.
xfem::LinearXfemResult solve_clamped(const GridModel& m) {
  xfem::ElasticMaterial mat{210000, 0.3, 7.85e-9};
  xfem::LinearXfemOptions fo;
  fo.gravity = xfem::Vec3(0, 0, -9810 * 1000);
  const auto r = xfem::solve_linear(m.elements, m.adjacent, mat, {xfem::DirichletCondition{0}}, {}, fo);
  EXPECT_TRUE(r.solved) << r.message;
  return r;
}

double max_displacement(const GridModel& m) {
  const auto r = solve_clamped(m);
  double u = 0;
  for (size_t e = 0; e < m.elements.size(); ++e)
    for (const auto& X : m.elements[e].rule.points) u = std::max(u, r.displacement(m.elements, static_cast<int>(e), X).norm());
  return u;
}

// The whole displacement field of two models of the same part on the same grid: every element
// of `a` is matched with the element of `b` in the same cell whose rule has the same points,
// and both solutions are compared at all rule points and cell corners of the element.
// Returns max |u_a − u_b| / max |u_a|; +inf if an element has no match.
double field_difference(const GridModel& a, const GridModel& b, int* compared = nullptr) {
  const auto ra = solve_clamped(a), rb = solve_clamped(b);
  std::map<std::array<int, 3>, std::vector<int>> by_cell;
  for (size_t e = 0; e < b.elements.size(); ++e) by_cell[b.elements[e].cell].push_back(static_cast<int>(e));
  double worst = 0, scale = 0;
  int n = 0;
  for (size_t e = 0; e < a.elements.size(); ++e) {
    const auto& ea = a.elements[e];
    const double tol = 1e-9 * ea.box.size().norm();
    int match = -1;
    for (int f : by_cell[ea.cell]) {
      const auto& pb = b.elements[f].rule.points;
      if (pb.size() != ea.rule.points.size()) continue;
      bool same = true;
      for (size_t j = 0; j < pb.size() && same; ++j) same = (pb[j] - ea.rule.points[j]).norm() < tol;
      if (same) match = f;
    }
    if (match < 0) return std::numeric_limits<double>::infinity();
    std::vector<xfem::Vec3> points = ea.rule.points;
    for (int k = 0; k < 8; ++k) points.push_back(xfem::corner(ea.box, k));
    for (const auto& X : points) {
      const xfem::Vec3 ua = ra.displacement(a.elements, static_cast<int>(e), X), ub = rb.displacement(b.elements, match, X);
      worst = std::max(worst, (ua - ub).norm());
      scale = std::max(scale, ua.norm());
      ++n;
    }
  }
  if (compared) *compared = n;
  return worst / scale;
}

// The geometry of the cut: per cut cell, the volume and centroid of each of its subvolumes
// (from the subvolume's own moment-fitted rule, exact for degree ≤ 4), sorted by volume.
struct Piece {
  double volume;
  xfem::Vec3 centroid;
};
std::map<std::array<int, 3>, std::vector<Piece>> pieces(const GridCut& g) {
  std::map<std::array<int, 3>, std::vector<Piece>> out;
  for (const auto& c : g.cut_cells) {
    auto& list = out[c.index];
    for (int sv : c.subvolumes) {
      const xfem::QuadratureRule3 rule = xfem::volume_rule(g.subvolumes[sv]).rule;
      Piece p{0, xfem::Vec3::Zero()};
      for (size_t j = 0; j < rule.points.size(); ++j) p.volume += rule.weights[j], p.centroid += rule.weights[j] * rule.points[j];
      p.centroid /= p.volume;
      list.push_back(p);
    }
    std::sort(list.begin(), list.end(), [](const Piece& a, const Piece& b) { return a.volume < b.volume; });
  }
  return out;
}

// Largest difference of piece volume (relative to the cell volume) and centroid (relative to
// the cell diagonal) between two cuts with the same cells; +inf if the cells or counts differ.
using Pieces = std::map<std::array<int, 3>, std::vector<Piece>>;
double geometry_difference(const GridCut& a, const Pieces& pa, const Pieces& pb) {
  if (pa.size() != pb.size()) return std::numeric_limits<double>::infinity();
  const double cell = a.cell_size.prod(), diag = a.cell_size.norm();
  double worst = 0;
  for (const auto& [ijk, list] : pa) {
    auto it = pb.find(ijk);
    if (it == pb.end() || it->second.size() != list.size()) return std::numeric_limits<double>::infinity();
    for (size_t k = 0; k < list.size(); ++k) {
      worst = std::max(worst, std::abs(list[k].volume - it->second[k].volume) / cell);
      if (list[k].volume > 1e-6 * cell)  // a sliver's centroid is ill-conditioned
        worst = std::max(worst, (list[k].centroid - it->second[k].centroid).norm() / diag);
    }
  }
  return worst;
}

// Cut cells that really cut the part (volume fraction between 1 % and 99 %).
int real_cut_cells(const GridCut& g, const Pieces& p) {
  int n = 0;
  for (const auto& [ijk, list] : p) {
    double v = 0;
    for (const auto& p : list) v += p.volume;
    n += v > 0.01 * g.cell_size.prod() && v < 0.99 * g.cell_size.prod();
  }
  return n;
}

// Blocks against one global split, on the sample parts as they are (faces on or near grid
// planes) and turned 13° about a skew axis with the grid shifted: the same cells, connections
// and subvolume counts, and the same geometry (each subvolume's volume and centroid).
TEST(GridBlocks, BlocksGiveTheCutOfOneGlobalSplit) {
  for (const char* name : {"l_bracket.step", "wrench.step", "ring.step", "housing.step", "wheel.step"}) {
    for (const bool turned : {false, true}) {
      auto part = read_part(sample(name));
      GridOptions global, blocks;
      global.cells_longest = blocks.cells_longest = 12;
      global.method = blocks.method = CutMethod::Splitter;  // the block route is the splitter's
      if (turned) {
        const PartInfo info = part_info(*part);
        part = rotated_part(*part, 0.5 * (info.bbox_min + info.bbox_max), xfem::Vec3(1, 0.5, 0.3), 13);
        const PartInfo turned_info = part_info(*part);
        global.anchored = blocks.anchored = true;
        const double h = (turned_info.bbox_max - turned_info.bbox_min).maxCoeff() / 12;
        global.origin = blocks.origin = turned_info.bbox_min + xfem::Vec3(0.31, 0.47, 0.23) * h;
      }
      const std::string what = std::string(name) + (turned ? " turned" : " aligned");
      global.block_cells = 0;
      blocks.block_cells = 3;  // many blocks, so many block faces to match
      const GridCut a = cut_by_grid(*part, global), b = cut_by_grid(*part, blocks);
      ASSERT_TRUE(a.done && b.done) << what << ": " << a.message << b.message;
      EXPECT_GT(b.blocks_cut, 1) << what;
      EXPECT_FALSE(b.block_faces.empty()) << what;
      const Pieces pa = pieces(a), pb = pieces(b);
      const int cut = real_cut_cells(a, pa);
      if (turned) EXPECT_GT(cut, 0) << what;
      expect_same_cut(a, b, what);
      const double d = geometry_difference(a, pa, pb);
      std::printf("%s: %zu cut cells (%d with fraction 1-99 %%), %zu subvolumes, largest geometry difference %.1e\n",
                  what.c_str(), a.cut_cells.size(), cut, a.subvolumes.size(), d);
      // Measured: ≤ 1e-10 aligned except the housing (6e-9); turned 2.5e-9 … 3.4e-8 (l_bracket):
      // the two splits trim the same faces along differently computed curves, and the rules
      // are accurate to about 1e-8 of a cell (resources/doc/simulation.md; worst 8.6e-9 in the
      // cut-cell benchmark). A piece in the wrong cell or a missing piece differs by O(1).
      EXPECT_LT(d, 5e-8) << what;
    }
  }
}

TEST(GridBlocks, RecutOfAChangedHoleEqualsAFullCut) {
  const auto before = plate_with_hole(8), after = plate_with_hole(9.5);
  GridModelOptions o;
  o.grid.method = CutMethod::Splitter;  // blocks: the splitter route
  o.grid.cells_longest = 20;
  o.grid.block_cells = 4;
  o.grid.perturbation = 0;  // identical planes for the old and the fresh cut of the new part
  const GridModel old_model = build_grid_model(*before, o);
  ASSERT_TRUE(old_model.done) << old_model.message;
  RecutReport report;
  const GridModel recut = rebuild_grid_model(*after, old_model, *before, o, &report);
  ASSERT_TRUE(recut.done) << recut.message;
  EXPECT_FALSE(report.full) << report.message;
  EXPECT_EQ(report.changed_faces, 2);  // the old and the new hole face
  EXPECT_EQ(report.changed_edges, 6);  // their two circles and seam each
  EXPECT_EQ(report.regions, 1);
  EXPECT_TRUE(report.verified);
  EXPECT_LT(report.blocks_recut, report.blocks / 3);
  EXPECT_GT(report.subvolumes_kept, 3 * report.subvolumes_new);

  const GridModel fresh = build_grid_model(*after, o);
  ASSERT_TRUE(fresh.done) << fresh.message;
  expect_same_cut(*fresh.cut, *recut.cut, "recut vs fresh");
  EXPECT_NEAR(model_volume(recut), occt_volume(*after), 1e-9 * occt_volume(*after));
  EXPECT_NEAR(model_volume(recut), model_volume(fresh), 1e-11 * model_volume(fresh));
  // The solution: the whole displacement field at every rule point and cell corner of every
  // element (matched by cell and rule points), not one scalar.
  int compared = 0;
  const double d = field_difference(fresh, recut, &compared);
  std::printf("recut vs fresh: %zu elements, field compared at %d points, max |du| / max |u| = %.1e\n",
              fresh.elements.size(), compared, d);
  EXPECT_GT(compared, 1000);
  EXPECT_LT(d, 1e-9);
  const double u_fresh = max_displacement(fresh);
  EXPECT_GT(std::abs(u_fresh - max_displacement(old_model)), 1e-6 * u_fresh);  // the change matters
}

// Two holes far apart that both grow: two changed regions, so the blocks between them are
// kept; the result still equals a fresh cut.
TEST(GridBlocks, SeparateChangesAreSeparateRegions) {
  auto plate = [](double r) {
    TopoDS_Shape s = BRepPrimAPI_MakeBox(gp_Pnt(0, 0, 0), 120, 40, 10).Shape();
    for (double x : {15.0, 105.0})
      s = BRepAlgoAPI_Cut(s, BRepPrimAPI_MakeCylinder(gp_Ax2(gp_Pnt(x, 20, -5), gp::DZ()), r, 20).Shape()).Shape();
    return make_part(s, "plate with two holes");
  };
  const auto before = plate(5), after = plate(6);
  GridModelOptions o;
  o.grid.method = CutMethod::Splitter;  // blocks: the splitter route
  o.grid.cells_longest = 24;
  o.grid.block_cells = 4;
  o.grid.perturbation = 0;
  const GridModel old_model = build_grid_model(*before, o);
  ASSERT_TRUE(old_model.done) << old_model.message;
  RecutReport report;
  const GridModel recut = rebuild_grid_model(*after, old_model, *before, o, &report);
  ASSERT_TRUE(recut.done) << recut.message;
  EXPECT_EQ(report.regions, 2);
  EXPECT_TRUE(report.verified) << report.message;
  EXPECT_FALSE(report.full);
  // 2 × 2 blocks around each hole; one box around both would take all 12 blocks.
  EXPECT_EQ(report.blocks, 12);
  EXPECT_LE(report.blocks_recut, 8);
  const GridModel fresh = build_grid_model(*after, o);
  expect_same_cut(*fresh.cut, *recut.cut, "two holes");
  EXPECT_LT(field_difference(fresh, recut), 1e-9);
}

// The safety net: when the old model does not belong to the given old part (here: cut from
// r = 8, but r = 9.5 passed as the old part, so no change is seen), the rules miss the new
// volume, and the part is cut again whole instead of returning the stale cells.
TEST(GridBlocks, AMissedChangeIsCaughtByTheVolumeCheck) {
  const auto r8 = plate_with_hole(8), r95 = plate_with_hole(9.5);
  GridModelOptions o;
  o.grid.method = CutMethod::Splitter;  // blocks: the splitter route
  o.grid.cells_longest = 12;
  o.grid.block_cells = 4;
  o.grid.perturbation = 0;
  const GridModel stale = build_grid_model(*r8, o);
  ASSERT_TRUE(stale.done) << stale.message;
  RecutReport report;
  const GridModel m = rebuild_grid_model(*r95, stale, *r95, o, &report);
  ASSERT_TRUE(m.done) << m.message;
  EXPECT_EQ(report.changed_faces + report.changed_edges, 0);
  EXPECT_FALSE(report.verified);
  EXPECT_TRUE(report.full);
  EXPECT_NE(report.message.find("missed the new volume"), std::string::npos) << report.message;
  EXPECT_NEAR(model_volume(m), occt_volume(*r95), 1e-9 * occt_volume(*r95));
}

TEST(GridBlocks, AnUnchangedPartIsNotCutAgain) {
  const auto part = plate_with_hole(8), same = plate_with_hole(8);
  GridOptions o;
  o.method = CutMethod::Splitter;  // blocks: the splitter route
  o.cells_longest = 10;
  o.block_cells = 4;
  const GridCut old = cut_by_grid(*part, o);
  RecutReport report;
  const GridCut again = recut_by_grid(*same, old, *part, o, &report);
  ASSERT_TRUE(again.done) << again.message;
  EXPECT_EQ(report.changed_faces, 0);
  EXPECT_EQ(report.changed_edges, 0);
  EXPECT_EQ(report.blocks_recut, 0);
  EXPECT_EQ(report.subvolumes_new, 0);
  expect_same_cut(old, again, "unchanged");
}

TEST(GridBlocks, APartThatLeavesTheGridIsCutAgainWhole) {
  const auto part = plate_with_hole(8);
  const TopoDS_Shape longer = BRepAlgoAPI_Cut(BRepPrimAPI_MakeBox(gp_Pnt(0, 0, 0), 130, 60, 12).Shape(),
                                              BRepPrimAPI_MakeCylinder(gp_Ax2(gp_Pnt(70, 30, -5), gp::DZ()), 8, 22).Shape())
                                  .Shape();
  const auto grown = make_part(longer, "longer plate");
  GridOptions o;
  o.method = CutMethod::Splitter;  // blocks: the splitter route
  o.cells_longest = 10;
  const GridCut old = cut_by_grid(*part, o);
  RecutReport report;
  const GridCut again = recut_by_grid(*grown, old, *part, o, &report);
  ASSERT_TRUE(again.done) << again.message;
  EXPECT_TRUE(report.full);
  EXPECT_NE(report.message.find("leaves the old grid"), std::string::npos) << report.message;
  EXPECT_DOUBLE_EQ(again.cell_size.x(), old.cell_size.x());
}

}  // namespace
}  // namespace parafab::occ
