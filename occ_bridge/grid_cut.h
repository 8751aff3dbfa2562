// Grid cutting for X-CAD (thesis §6.2.2, §6.3, Fig. 6.3/6.5): an axis-aligned grid over the
// part's bounding box; every B-rep face is split by the grid planes with OCCT's Boolean
// splitter (built on its surface–surface intersectors), giving for every cut cell its
// connected subvolumes, each bounded by trimmed B-rep face pieces and planar regions on the
// cell's faces, all as plain data (xfem::Subvolume) for the quadrature.
#pragma once

#include <array>
#include <string>
#include <vector>

#include "xfem/cut_geometry.h"

namespace parafab::occ {

struct PartShape;  // occ_bridge/occt_shape.h

struct GridOptions {
  int cells_longest = 8;    ///< cells along the longest side of the bounding box
  double cell_size = 0;     ///< if > 0, overrides cells_longest [model units]
  /// Grid anchor: by default the grid is centred on the bounding box; with `anchored`, grid
  /// planes pass through `origin` + k·cell size (e.g. to keep one grid while a part changes).
  bool anchored = false;
  xfem::Vec3 origin{0, 0, 0};
  /// Grid planes within this distance (× cell size) of a vertex, or of a face's extreme
  /// coordinate (tangent or coincident face), are shifted deterministically by the same
  /// amount until clear (the thesis perturbs grid planes to avoid these corner cases).
  /// 0 turns the shift off (planes may then pass through vertices or along faces).
  double perturbation = 1e-4;
  /// Boundary loops: parabolic (2) or linear (1) segments, refined until the deviation from
  /// the exact pcurve is below `segment_tolerance` × the face's uv extent.
  int segment_order = 2;
  double segment_tolerance = 1e-8;
  int max_segments_per_edge = 4096;
  bool parallel = false;    ///< let OCCT's splitter use threads
  /// Convert every face to NURBS (BRepBuilderAPI_NurbsConvert, as the face model does) before
  /// cutting: patches of B-rep faces are then pieces of exactly the face model's NURBS, in
  /// its (u, v), which shape derivatives with respect to control points need (§6.5.3).
  bool nurbs = false;
};

/// One grid cell that the boundary cuts.
struct CutCell {
  std::array<int, 3> index{0, 0, 0};
  std::vector<int> subvolumes;  ///< indices into GridCut::subvolumes
};

/// An intersection curve inside a cut cell (an edge of a subvolume's boundary that is not a
/// straight cell edge), sampled as polynomial segments like the boundary loops, in 3D.
struct CutCurve {
  enum Kind { FacePlane, FaceFace } kind = FacePlane;
  int subvolume = -1;
  /// The two faces meeting along it: B-rep face index ≥ 0, or −1 − axis for a grid plane.
  std::array<int, 2> sources{-1, -1};
  int order = 2;                  ///< segment order, as BoundaryLoop::order
  std::vector<xfem::Vec3> points;
};

struct GridCut {
  bool done = false;
  std::string message;                     ///< why not done
  xfem::Box3 grid;                         ///< the grid's box (covers the part)
  std::array<int, 3> cells{0, 0, 0};       ///< cells per axis
  xfem::Vec3 cell_size{0, 0, 0};
  std::array<std::vector<double>, 3> planes;  ///< interior grid planes per axis (after shifts)
  int shifted_planes = 0;                  ///< planes moved off vertices / tangencies
  std::vector<std::array<int, 3>> interior_cells;  ///< uncut cells fully inside the part
  std::vector<CutCell> cut_cells;
  std::vector<xfem::Subvolume> subvolumes;        ///< of cut cells only
  std::vector<std::array<int, 2>> connections;    ///< subvolume pairs sharing a grid face
  std::vector<std::array<int, 2>> interior_connections;  ///< (subvolume, interior cell) pairs
  std::vector<CutCurve> curves;                   ///< intersection curves of the subvolumes
  int patches = 0, segments = 0;
  double split_seconds = 0, extract_seconds = 0;

  xfem::Box3 cell_box(const std::array<int, 3>& ijk) const;
};

/// Cuts the part by the grid. Never throws for geometry the splitter cannot handle: that is
/// `done == false` with a message. Throws parafab::Error for invalid options.
GridCut cut_by_grid(const PartShape& part, const GridOptions& options = {});

}  // namespace parafab::occ
