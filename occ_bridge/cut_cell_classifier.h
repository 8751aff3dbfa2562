// In/out of points inside cut grid cells from the cell's own boundary patches (thesis §6.3: the
// face cut knows ∂Ω ∩ cell as trimmed patches of B-rep faces): the segment from a reference point
// of the cell (a corner, or an inner point when the corners lie on the part's surfaces) whose
// state OCCT gave once to the point crosses ∂Ω ∩ cell an even number of times exactly when both
// have the same state. The crossings are closed forms (line ∩ plane, cylinder, sphere) and
// a winding-number test of the hit's (u, v) in the patch loops. Anything not decided beyond
// doubt (another surface type, a hit near a loop, an end point or a grazing hit) goes to OCCT's
// classifier, whose verdict is the reference (tests/occ_bridge/cut_cell_classifier_test.cpp
// compares both on 56,000 points of cut cells of six parts, as they are and turned).
#pragma once

#include <array>
#include <memory>
#include <unordered_map>
#include <vector>

#include "face_lookup.h"
#include "xfem/cut_geometry.h"

namespace parafab::occ {

struct GridCut;
struct PartShape;

class CutCellClassifier {
 public:
  /// `cut` must outlive the classifier; `tolerance` as PointClassifier's (ON counts as in).
  CutCellClassifier(const PartShape& part, const GridCut& cut, double tolerance);
  ~CutCellClassifier();
  /// X in the (closed) box of cut cell `cell`: in the material (inside or on the boundary)?
  /// Cells that are not cut, and undecided points, are classified by OCCT.
  bool in_material(const std::array<int, 3>& cell, const xfem::Vec3& X) const;

  struct Counts {
    long by_crossings = 0;  ///< decided by the crossing parity
    long by_occt = 0;       ///< sent to OCCT (reference corners included)
  };
  const Counts& counts() const { return counts_; }

 private:
  struct Cell;
  const Cell& cell_data(const std::array<int, 3>& cell) const;
  const GridCut& cut_;
  double tolerance_;
  PointClassifier occt_;
  std::unordered_map<long long, int> cut_cell_of_;  ///< linear cell index → index in cut.cut_cells
  mutable std::unordered_map<long long, std::unique_ptr<Cell>> cells_;
  mutable Counts counts_;
};

/// Is X inside `subvolume` (the piece of a cut cell bounded by its patches)? OnBoundary when X
/// lies within `near` of a patch, inside its loops; else the parity of the crossings of a ray
/// from X with the patches: closed forms for planes, cylinders, spheres and grid faces, the
/// hit's (u, v) tested in the patch loops. Undecided when a patch lies on another surface, X
/// lies within `near` of a patch's loop, or three rays each graze a patch or pass within `near`
/// of a loop. Which piece of a cell holds a probe or a surface vertex (ElementLocator).
enum class SubvolumeTest { Inside, Outside, OnBoundary, Undecided };
SubvolumeTest point_in_subvolume(const xfem::Subvolume& subvolume, const xfem::Vec3& X, double near);

}  // namespace parafab::occ
