// Point-in-material by crossing parity inside cut cells (cut_cell_classifier.h) against OCCT's
// solid classifier (BRepClass3d_SolidClassifier) on the sample parts as they are and turned off
// the grid: the same verdict for every point (cell corners, quadrature points of the cut
// subvolumes' rules, random points of the cells), and most of them decided without OCCT.
#include <gtest/gtest.h>

#include <cstdio>
#include <random>

#include "cut_cell_classifier.h"
#include "face_lookup.h"
#include "grid_model.h"
#include "occt_shape.h"
#include "part_reader.h"

namespace parafab::occ {
namespace {

std::string sample(const char* name) { return std::string(PARAFAB_SAMPLES_DIR) + "/parts/" + name; }

TEST(CutCellClassifier, AgreesWithOcctOnEveryPointAndMostlyWithoutIt) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> unit(0, 1);
  // Face route on six parts as they are and turned 13° about a skew axis; the splitter route on two.
  struct Case {
    const char* name;
    bool turned;
    CutMethod method;
  };
  std::vector<Case> cases;
  for (const char* name : {"l_bracket.step", "wrench.step", "ring.step", "wheel.step", "flange.step", "housing.step"})
    for (const bool turned : {false, true}) cases.push_back({name, turned, CutMethod::FaceCut});
  for (const char* name : {"l_bracket.step", "wheel.step"}) cases.push_back({name, true, CutMethod::Splitter});
  for (const auto& [name, turned, method] : cases) {
    auto part = read_part(sample(name));
    if (turned) {
      const PartInfo info = part_info(*part);
      part = rotated_part(*part, 0.5 * (info.bbox_min + info.bbox_max), xfem::Vec3(1, 0.5, 0.3), 13);
    }
    const PartInfo info = part_info(*part);
    const double tol = 1e-7 * (info.bbox_max - info.bbox_min).norm();
    GridModelOptions o;
    o.grid.cells_longest = 10;
    o.grid.method = method;
    const GridModel m = build_grid_model(*part, o);
    ASSERT_TRUE(m.done) << name << ": " << m.message;
    ASSERT_EQ(m.cut->method, method) << name << ": " << m.cut->retry_reason;
    CutCellClassifier fast(*part, *m.cut, tol);
    PointClassifier occt(*part, tol);
    long points = 0, mismatches = 0, inside = 0, interior = 0, interior_by_crossings = 0;
    for (const auto& el : m.elements) {
      if (!el.subvolume) continue;
      std::vector<xfem::Vec3> X;
      for (int k = 0; k < 8; ++k)
        X.emplace_back((k & 1) ? el.box.max.x() : el.box.min.x(), (k & 2) ? el.box.max.y() : el.box.min.y(),
                       (k & 4) ? el.box.max.z() : el.box.min.z());
      const size_t stride = std::max<size_t>(1, el.rule.points.size() / 6);
      for (size_t i = 0; i < el.rule.points.size(); i += stride) X.push_back(el.rule.points[i]);
      for (int k = 0; k < 6; ++k)
        X.push_back(el.box.min + xfem::Vec3(unit(rng), unit(rng), unit(rng)).cwiseProduct(el.box.size()));
      for (size_t i = 0; i < X.size(); ++i) {
        const bool reference = occt.in_material(X[i]);
        const long before = fast.counts().by_crossings;
        mismatches += fast.in_material(el.cell, X[i]) != reference;
        if (i >= 8) interior += 1, interior_by_crossings += fast.counts().by_crossings - before;
        inside += reference;
        ++points;
      }
    }
    const auto& c = fast.counts();
    const double share = double(interior_by_crossings) / interior;
    std::printf("%-9s %-14s %-7s %6ld points (%ld in material): %ld by crossings, of the %ld inside the cells %.1f %%; "
                "%ld OCCT calls, %ld mismatches\n",
                m.cut->method == CutMethod::FaceCut ? "face" : "splitter", name, turned ? "turned" : "as is", points,
                inside, c.by_crossings, interior, 100 * share, c.by_occt, mismatches);
    EXPECT_EQ(mismatches, 0) << name << (turned ? " turned" : "");
    EXPECT_GT(inside, points / 10) << name;
    EXPECT_LT(inside, points * 9 / 10) << name;
    // Points inside the cells (rule points, random points) mostly without OCCT (cells of the
    // housing's torus and points near a surface go to OCCT); corners lie on
    // the cell faces that carry the patches' loops, and often go to OCCT.
    EXPECT_GT(share, 0.9) << name << (turned ? " turned" : "");  // measured 94.1-100 %
  }
}

}  // namespace
}  // namespace parafab::occ
