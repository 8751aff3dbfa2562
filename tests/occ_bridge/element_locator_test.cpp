// occ::ElementLocator (grid_model.h): the element holding a probe or a surface vertex, found
// through the grid. Checked against a search of every element with the same rule (the grid
// lookup), its piece test (point_in_subvolume) against OCCT's point classifier, and in cells
// that hold two pieces of material (the two sides of a slot, told apart by their wall patches).
#include <gtest/gtest.h>

#include <BRepAlgoAPI_Cut.hxx>
#include <BRepClass3d_SolidClassifier.hxx>
#include <BRepPrimAPI_MakeBox.hxx>

#include <cmath>
#include <cstdint>
#include <cstdio>

#include <Eigen/Geometry>

#include "cut_cell_classifier.h"
#include "grid_model.h"
#include "occt_shape.h"
#include "part_reader.h"
#include "surface_mesh.h"

namespace parafab::occ {
namespace {

using xfem::Vec3;

// The rule of ElementLocator::find applied to every element of the grid (what the locator
// replaces): of the elements whose box holds X (slack 1e-6 of the box) those that hold X (an
// uncut cell, a subvolume by point_in_subvolume), else those undecided, else all of them; the
// nearest rule point.
int find_by_search(const GridModel& grid, const Vec3& X, double* distance = nullptr) {
  const double near = 1e-6 * grid.cut->cell_size.norm();
  int best[3] = {-1, -1, -1};  // among the elements that hold X, that may hold it, all
  double best_d[3] = {1e300, 1e300, 1e300};
  for (size_t e = 0; e < grid.elements.size(); ++e) {
    const auto& el = grid.elements[e];
    const Vec3 slack = 1e-6 * el.box.size();
    if (((X - el.box.min + slack).array() < 0).any() || ((el.box.max + slack - X).array() < 0).any()) continue;
    const SubvolumeTest test = el.subvolume ? point_in_subvolume(*el.subvolume, X, near) : SubvolumeTest::Inside;
    const int tier = test == SubvolumeTest::Inside || test == SubvolumeTest::OnBoundary ? 0 : test == SubvolumeTest::Undecided ? 1 : 2;
    for (const Vec3& P : el.rule.points)
      for (int k = tier; k < 3; ++k)
        if ((P - X).norm() < best_d[k]) best_d[k] = (P - X).norm(), best[k] = static_cast<int>(e);
  }
  const int k = best[0] >= 0 ? 0 : best[1] >= 0 ? 1 : 2;
  if (distance) *distance = best_d[k];
  return best[k];
}

// The element that the nearest rule point alone picks (the locator's rule until 2026-11-28).
int by_nearest_rule_point(const GridModel& grid, const Vec3& X) {
  int best = -1;
  double best_d = 1e300;
  for (size_t e = 0; e < grid.elements.size(); ++e) {
    const auto& el = grid.elements[e];
    const Vec3 slack = 1e-6 * el.box.size();
    if (((X - el.box.min + slack).array() < 0).any() || ((el.box.max + slack - X).array() < 0).any()) continue;
    for (const Vec3& P : el.rule.points)
      if ((P - X).norm() < best_d) best_d = (P - X).norm(), best = static_cast<int>(e);
  }
  return best;
}

double nearest_rule_point(const GridModel& grid, int e, const Vec3& X) {
  double d = 1e300;
  for (const Vec3& P : grid.elements[e].rule.points) d = std::min(d, (P - X).norm());
  return d;
}

// Deterministic points in a box (a 64-bit LCG, the same sequence on every machine).
struct Points {
  uint64_t state = 12345;
  double next() {
    state = state * 6364136223846793005ULL + 1442695040888963407ULL;
    return static_cast<double>(state >> 11) / 9007199254740992.0;
  }
  Vec3 in(const xfem::Box3& b) { return {b.min.x() + next() * (b.max.x() - b.min.x()), b.min.y() + next() * (b.max.y() - b.min.y()), b.min.z() + next() * (b.max.z() - b.min.z())}; }
};

TEST(ElementLocator, FindsWhatASearchOfEveryElementFindsOnTheTurnedBracket) {
  const auto bracket = read_part(std::string(PARAFAB_SAMPLES_DIR) + "/parts/l_bracket.step");
  const auto part = rotated_part(*bracket, Vec3(40, 20, 20), Vec3(0.3, 0.5, 1.0), 17.0);
  GridModelOptions o;
  o.grid.cells_longest = 12;
  const GridModel grid = build_grid_model(*part, o);
  ASSERT_TRUE(grid.done) << grid.message;
  ASSERT_GT(grid.cut->cut_cells.size(), 100u);
  const ElementLocator locator(grid);

  // Points: random in the grid's box, and the vertices of the part's surface mesh.
  std::vector<Vec3> points;
  Points rnd;
  for (int i = 0; i < 8000; ++i) points.push_back(rnd.in(grid.cut->grid));
  const SurfaceMesh mesh = triangulate_part(*part, 0.2, 4.0);
  points.insert(points.end(), mesh.points.begin(), mesh.points.end());

  BRepClass3d_SolidClassifier classifier(part->shape);
  int same = 0, ties = 0, inside = 0, surface_found = 0, pieces_inside = 0, pieces_outside = 0, undecided = 0;
  for (size_t i = 0; i < points.size(); ++i) {
    const Vec3& X = points[i];
    double d_search = 0;
    const int e_search = find_by_search(grid, X, &d_search);
    const int e = locator.find(X);
    if (e == e_search) {
      ++same;
    } else {
      // Only a tie in distance may pick another element.
      ASSERT_GE(e, 0) << "point " << i << " (" << X.transpose() << "): the search finds element " << e_search;
      ASSERT_EQ(nearest_rule_point(grid, e, X), d_search) << "point " << i << " (" << X.transpose() << ")";
      ++ties;
    }
    if (i >= 8000) {  // a surface vertex: always in some element
      EXPECT_GE(e, 0) << "surface vertex " << X.transpose();
      surface_found += e >= 0;
      continue;
    }
    // The piece test against OCCT's classifier. OCCT says X is inside: the locator finds an
    // element whose box holds X, and if it is a cut piece, the piece test does not say Outside.
    // OCCT says X is outside: no piece whose box holds X says it holds X.
    classifier.Perform(gp_Pnt(X.x(), X.y(), X.z()), 1e-7);
    const double near = 1e-6 * grid.cut->cell_size.norm();
    if (classifier.State() == TopAbs_OUT) {
      for (size_t k = 0; k < grid.elements.size(); ++k) {
        const auto& el = grid.elements[k];
        const Vec3 slack = 1e-6 * el.box.size();
        if (!el.subvolume || ((X - el.box.min + slack).array() < 0).any() || ((el.box.max + slack - X).array() < 0).any())
          continue;
        const SubvolumeTest t = point_in_subvolume(*el.subvolume, X, near);
        EXPECT_TRUE(t == SubvolumeTest::Outside || t == SubvolumeTest::Undecided) << "outside point " << X.transpose();
        ++pieces_outside;
        undecided += t == SubvolumeTest::Undecided;
      }
      continue;
    }
    if (classifier.State() != TopAbs_IN) continue;
    ++inside;
    ASSERT_GE(e, 0) << "point " << X.transpose() << " is inside the part";
    const auto& box = grid.elements[e].box;
    const Vec3 slack = 1e-6 * box.size();
    EXPECT_TRUE(((X - box.min + slack).array() >= 0).all() && ((box.max + slack - X).array() >= 0).all());
    if (const xfem::Subvolume* sv = grid.elements[e].subvolume) {
      const SubvolumeTest t = point_in_subvolume(*sv, X, near);
      EXPECT_NE(t, SubvolumeTest::Outside) << "inside point " << X.transpose();
      ++pieces_inside;
      undecided += t == SubvolumeTest::Undecided;
    }
  }
  std::printf("%zu points (%zu surface vertices), %d inside by OCCT: %d same element as the search, %d ties; "
              "piece test against OCCT on %d inside and %d outside (point, piece) pairs, %d undecided\n",
              points.size(), mesh.points.size(), inside, same, ties, pieces_inside, pieces_outside, undecided);
  EXPECT_EQ(same + ties, static_cast<int>(points.size()));
  EXPECT_GT(inside, 800);
  EXPECT_GT(pieces_inside, 100);
  EXPECT_GT(pieces_outside, 100);
  EXPECT_EQ(surface_found, static_cast<int>(mesh.points.size()));
}

// Points of the slotted cube below turned by `degrees` about `axis` through its centre.
struct Turn {
  Eigen::Matrix3d R;
  Vec3 c{5, 5, 5};
  Turn(const Vec3& axis, double degrees) : R(Eigen::AngleAxisd(degrees * M_PI / 180, axis.normalized())) {}
  Vec3 to(const Vec3& X) const { return c + R * (X - c); }      ///< cube frame → turned
  Vec3 back(const Vec3& Y) const { return c + R.transpose() * (Y - c); }
};

TEST(ElementLocator, PicksThePieceOfACellThatHoldsThePoint) {
  // A 10 mm cube with a slot x ∈ [4.6, 5.4] (0.8 mm) or [4.99, 5.01] (0.02 mm) from z = 3 up,
  // aligned with the grid and turned. Cells of h = 2.5 that the slot crosses hold material on
  // both sides, two subvolumes. Points near either wall (down to 1e-3 mm from it) and the
  // surface vertices of both walls must get the element of their own side: the piece whose
  // boundary holds that wall and not the other. Points are taken at z ≥ 7.6 (cube frame),
  // clear of the cells that hold the slot's floor z = 3 (U-shaped single pieces) at any turn.
  const struct {
    double half_width;
    Vec3 axis;
    double degrees;
  } cases[] = {{0.4, {0, 0, 1}, 0}, {0.01, {0, 0, 1}, 0}, {0.4, {0, 0, 1}, 30}, {0.4, {0.2, 1, 0.1}, 23},
               {0.01, {0, 0, 1}, 30}};
  for (const auto& cs : cases) {
    const double x0 = 5 - cs.half_width, x1 = 5 + cs.half_width;
    const TopoDS_Shape cube = BRepPrimAPI_MakeBox(gp_Pnt(0, 0, 0), gp_Pnt(10, 10, 10)).Shape();
    const TopoDS_Shape slot = BRepPrimAPI_MakeBox(gp_Pnt(x0, -1, 3), gp_Pnt(x1, 11, 11)).Shape();
    const auto slotted = make_part(BRepAlgoAPI_Cut(cube, slot).Shape(), "slotted cube");
    const Turn turn(cs.axis, cs.degrees);
    const auto part = cs.degrees == 0 ? slotted : rotated_part(*slotted, turn.c, cs.axis, cs.degrees);
    GridModelOptions o;
    o.grid.cell_size = 2.5;
    o.grid.anchored = true;
    o.grid.origin = Vec3(1.3, 0.37, 0.21);
    const GridModel grid = build_grid_model(*part, o);
    ASSERT_TRUE(grid.done) << grid.message;
    const ElementLocator locator(grid);

    // Which wall of the slot an element's piece lies on: −1 / +1 when its boundary holds a patch
    // of the left / right wall only (a patch whose boundary points all lie on x = x0 or x1 in the
    // cube's frame), 0 otherwise.
    auto side = [&](int e) {
      bool on[2] = {false, false};
      if (const xfem::Subvolume* sv = grid.elements[e].subvolume)
        for (const xfem::CutPatch& cp : sv->patches) {
          if (cp.source_face < 0) continue;
          double lo = 1e300, hi = -1e300;
          for (const auto& loop : cp.loops)
            for (const xfem::Vec2& q : loop.points) {
              Vec3 P, Pu, Pv;
              cp.surface->evaluate(q.x(), q.y(), P, Pu, Pv);
              lo = std::min(lo, turn.back(P).x()), hi = std::max(hi, turn.back(P).x());
            }
          for (int k : {0, 1})
            if (std::abs(lo - (k ? x1 : x0)) < 1e-7 && std::abs(hi - (k ? x1 : x0)) < 1e-7) on[k] = true;
        }
      return on[0] == on[1] ? 0 : on[0] ? -1 : 1;
    };
    int checked = 0, wrong = 0, wrong_by_nearest = 0;
    for (double eps : {1e-3, 0.01, 0.05})
      for (double y : {0.5, 2.0, 4.44, 7.9, 9.5})
        for (double z : {7.6, 8.3, 9.0, 9.9})
          for (int s : {-1, 1}) {
            const Vec3 X = turn.to(Vec3(s < 0 ? x0 - eps : x1 + eps, y, z));
            const int e = locator.find(X);
            ASSERT_GE(e, 0) << X.transpose();
            EXPECT_EQ(side(e), s) << "point " << X.transpose() << " (" << eps << " from the wall)";
            wrong += side(e) != s;
            wrong_by_nearest += side(by_nearest_rule_point(grid, X)) != s;
            ++checked;
          }
    // The surface vertices on the two walls.
    const SurfaceMesh mesh = triangulate_part(*part, 0.1, 0.5);
    int wall_vertices = 0;
    for (const Vec3& Y : mesh.points) {
      const Vec3 X = turn.back(Y);
      const bool left = std::abs(X.x() - x0) < 1e-9, right = std::abs(X.x() - x1) < 1e-9;
      if (!(left || right) || X.z() < 7.6) continue;
      const Vec3 outward = turn.R * Vec3(left ? 1 : -1, 0, 0);  // into the slot
      const int e = locator.find_on_surface(Y, outward);
      ASSERT_GE(e, 0) << Y.transpose();
      EXPECT_EQ(side(e), left ? -1 : 1) << "wall vertex " << X.transpose();
      wrong += side(e) != (left ? -1 : 1);
      wrong_by_nearest += side(by_nearest_rule_point(grid, Y)) != (left ? -1 : 1);
      ++wall_vertices;
    }
    std::printf("slot %.2f mm, turned %2g deg: %3zu cut cells; %d points near the walls and %d wall vertices: %d on "
                "the wrong side (%ld located with no piece known to hold them); the nearest rule point alone "
                "(the rule until 2026-11-28): %d wrong\n",
                2 * cs.half_width, cs.degrees, grid.cut->cut_cells.size(), checked, wall_vertices, wrong,
                locator.nearest_rule_point_fallbacks(), wrong_by_nearest);
    EXPECT_GT(wall_vertices, 50);
    // The case is one where the nearest rule point alone fails (341 of 680 on 2026-11-28).
    if (cs.half_width < 0.1 && cs.degrees > 0) EXPECT_GT(wrong_by_nearest, 100);
  }
}

}  // namespace
}  // namespace parafab::occ
