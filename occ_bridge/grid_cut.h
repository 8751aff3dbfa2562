// Grid cutting for X-CAD (thesis §6.2.2, §6.3, Fig. 6.3/6.5, 6.12): an axis-aligned grid over
// the part's bounding box, giving for every cut cell its connected subvolumes, each bounded by
// trimmed B-rep face pieces and planar regions on the cell's faces, all as plain data
// (xfem::Subvolume) for the quadrature. Two routes: OCCT's Boolean splitter on the whole solid
// (reference), or the face route (§6.3, Fig. 6.12): every face's trimming loops are split in
// its (u, v) by the curves where the grid planes meet its surface (closed forms for planes
// and cylinders, traced level curves for any other surface), the cells' grid
// faces are built from those curves, and every intersection point keeps its class and its
// (u, v) on each surface it lies on (for the shape derivatives of §6.5.3).
#pragma once

#include <array>
#include <string>
#include <vector>

#include "xfem/cut_geometry.h"

namespace parafab::occ {

struct PartShape;  // occ_bridge/occt_shape.h

/// How the part is cut. FaceCut (every entry's route): per face, plane ∩ surface curves in
/// (u, v) (closed forms for planes and cylinders, traced for any other surface). Splitter:
/// OCCT's Boolean splitter on the solid, kept only as the tests' and benchmarks' reference.
enum class CutMethod { Splitter, FaceCut };

struct GridOptions {
  CutMethod method = CutMethod::FaceCut;
  /// Face route: check that every subvolume's boundary closes (each boundary curve is run
  /// through once in each direction by the subvolume's outward-oriented patches); the cut fails
  /// if not. build_grid_model also checks the rules' volume against OCCT's.
  bool verify = true;
  /// Face route: when the cut fails (a grid vertex on a surface, crossings that do not
  /// alternate, an open boundary) or build_grid_model's volume check fails, the grid is shifted
  /// and cut again (GridCut::retry_reason, grid_shift): the first retry along the failing
  /// plane's axis a only by s_a cells, s = (0.118, 0.141, 0.173), where one plane is at fault
  /// (the others stay, e.g. on a clamped face); retry k = 2 … shift_retries (and a first retry
  /// without a plane at fault) by k·s along all axes. 0: the grid must not move (re-cuts on a
  /// kept grid).
  int shift_retries = 2;
  /// Face route: run the per-face work in parallel (oneTBB).
  bool face_parallel = true;
  int cells_longest = 8;    ///< cells along the longest side of the bounding box
  double cell_size = 0;     ///< if > 0, overrides cells_longest [model units]
  /// Grid anchor: by default the grid is centred on the bounding box; with `anchored`, grid
  /// planes pass through `origin` + k·cell size (e.g. to keep one grid while a part changes).
  bool anchored = false;
  xfem::Vec3 origin{0, 0, 0};
  /// Grid planes within this distance (× cell size) of a vertex, or of a face's extreme
  /// coordinate (tangent or coincident face), or forming with a plane of another axis a grid
  /// line on a cylinder parallel to a grid axis (a ruling), are shifted deterministically by
  /// the same amount until clear (the thesis perturbs grid planes to avoid these corner cases).
  /// 0 turns the shift off (planes may then pass through vertices or along faces).
  double perturbation = 1e-4;
  /// Re-cuts (rebuild_grid_model), when > 0 (and `perturbation` is): the old grid's planes stay
  /// where they are, and a plane moves (by 1.5 × this × cell) only off a vertex or face extreme
  /// of the new part closer than this × cell, instead of off everything within `perturbation`
  /// as a fresh cut of the new part would: the model then changes with the part continuously
  /// also where a face's extreme crosses a plane (a slot's end: the fresh cut's shifts jumped
  /// the plane over it, 1.5e-4 of a cell each way). Shape optimization sets it
  /// (occ::compliance_at: 1e-8). 0: the planes a fresh cut of the new part picks.
  double recut_clearance = 0;
  /// Boundary loops: parabolic (2) or linear (1) segments, refined until the deviation from
  /// the exact pcurve is below `segment_tolerance` × the face's uv extent.
  int segment_order = 2;
  double segment_tolerance = 1e-8;
  int max_segments_per_edge = 4096;
  /// Splitter route: the (u, v) of boundary points are the pcurve's refined onto the edge's 3D
  /// curve (the splitter's pcurves approximate exact section curves to the edge tolerance).
  bool project_pcurves = true;
  bool parallel = false;    ///< let OCCT's splitter use threads
  /// Two-level cutting: the part is first split into blocks of `block_cells`³ cells by every
  /// block_cells-th plane, then every block piece by its own planes; subvolumes meeting across
  /// block faces are matched by their common face (cell face, area, centroid). OCCT's splitter
  /// costs grow faster than linearly with the pieces it builds, so blocks of 8 cells cut the
  /// 32-cell L-bracket about 2× faster than one global split; blocks also let a changed part
  /// be re-cut block by block (recut_by_grid). 0: one global split.
  int block_cells = 8;
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

/// One sample of an intersection curve of the face route (thesis Fig. 6.12): its class and its
/// parameters on every surface it lies on, for the shape derivatives of §6.5.3.
struct CutSample {
  enum Kind {
    FacePlane,       ///< inside a face, on one grid plane
    EdgePlane,       ///< a B-rep edge crosses a grid plane (on two faces and the plane)
    FacePlanePlane,  ///< inside a face, on a cell edge (two grid planes)
    OnEdge,          ///< inside a B-rep edge, inside the cell (on two faces)
    Vertex,          ///< a B-rep vertex
    /// (a plane tangent to a face; not produced: grid planes are shifted off face extremes)
    Tangent
  } kind = FacePlane;
  struct On {
    int source = -1;     ///< B-rep face index ≥ 0, or −1 − axis for a grid plane
    xfem::Vec2 uv{0, 0};  ///< face: its surface's (u, v); grid plane axis a: (X_{a+1}, X_{a+2})
  };
  std::vector<On> on;
  int edge = -1;           ///< EdgePlane, OnEdge: the B-rep edge; Vertex: the vertex index
  double edge_param = 0;   ///< the edge's curve parameter
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
  /// Face route only: one sample per point (empty from the splitter).
  std::vector<CutSample> samples;
};

/// A grid-plane face of a subvolume or interior cell on a block face: how pieces cut in
/// different blocks are matched.
struct BlockFace {
  int owner = -1;                       ///< subvolume index ≥ 0, or −1 − interior cell index
  std::array<int, 4> cell_face{0, 0, 0, 0};  ///< axis, plane index (1..cells−1), other two cell indices
  bool upper = false;                   ///< the owner lies above the plane (cell index = plane index)
  xfem::Vec3 centroid{0, 0, 0};
  double area = 0;
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
  std::vector<BlockFace> block_faces;             ///< faces on block faces (for re-cutting)
  int block_cells = 0;                            ///< cells per block edge (0: one block)
  int patches = 0, segments = 0;
  double split_seconds = 0, extract_seconds = 0;
  int blocks_cut = 0;                             ///< blocks split at the second level
  CutMethod method = CutMethod::FaceCut;          ///< the route that produced this cut
  xfem::Vec3 origin{0, 0, 0};                     ///< the unshifted grid's lowest planes (cell corner)
  /// Why the face route failed on the requested grid, when it then cut a shifted one (empty:
  /// cut as requested); grid_shift is that shift [model units].
  std::string retry_reason;
  xfem::Vec3 grid_shift{0, 0, 0};
  int failed_axis = -1;  ///< face route, not done: the axis of the grid plane at fault (−1: none)
  double verify_seconds = 0;                      ///< face route: the closure check
  int verify_open_edges = 0;                      ///< face route: unmatched boundary curves (check failed)

  xfem::Box3 cell_box(const std::array<int, 3>& ijk) const;
};

/// Cuts the part by the grid. Never throws for geometry a route cannot handle: that is
/// `done == false` with a message (on the face route after the grid shifts of shift_retries). Throws parafab::Error for invalid options.
GridCut cut_by_grid(const PartShape& part, const GridOptions& options = {});

/// The options of the k-th shifted retry of a face-route cut that failed (`failed` carries the
/// grid's origin, cell size and failed_axis): anchored at origin + k·h·s, s = (0.118, 0.141,
/// 0.173), along failed_axis only for k = 1 (all axes when it is −1 or k > 1); no further retries.
GridOptions shifted_grid(const GridCut& failed, const GridOptions& options, int k);

struct RecutReport {
  bool full = false;           ///< the whole part was cut again (reason in `message`)
  std::string message;
  int changed_faces = 0;       ///< faces on a surface no face of the other part lies on (both ways)
  int changed_edges = 0;       ///< edges without an identical edge in the other part (both ways)
  int regions = 0;             ///< changed regions (boxes of overlapping changes, merged)
  int blocks = 0, blocks_recut = 0;
  /// Face route: grid cells; old cut cells cut again (a changed face or edge, old or new, meets
  /// them); cells that came out cut among all re-cut cells (those plus uncut cells in a change
  /// region, whose state is tested again); B-rep faces cut again (those meeting a re-cut cell).
  /// A full cut counts all old cut cells as cut again (cells_recut = old_cut_cells).
  int cells = 0, cells_recut = 0, cut_cells_recut = 0, faces_recut = 0;
  int old_cut_cells = 0;       ///< cut cells of the old cut
  /// Face route: grid planes moved because a fresh cut of the new part would shift them off a
  /// new vertex or face extreme (GridOptions::perturbation); the cells on both sides are re-cut.
  int planes_moved = 0;
  bool verified = true;        ///< rebuild_grid_model: the rules' volume matched OCCT's (else cut again whole)
  /// rebuild_grid_model: OCCT's volume of the new part (adaptive precision 1e-9), measured for
  /// that check (0 when the cut failed first); callers checking the same part reuse it.
  double occt_volume = 0;
  int subvolumes_kept = 0, subvolumes_new = 0;
  std::vector<int> kept_from;  ///< for every subvolume of the new cut: its old index, or −1
};

/// Re-cuts `new_part` on the grid of `old` (cut from `old_part` with block_cells > 0): blocks
/// that no change touches keep their subvolumes, connections and block faces; only the blocks
/// inside the boxes around the changes are split again. Changes are faces whose surface moved
/// (old and new) and edges that moved (a face on the same surface changes only between its
/// old and new trimming edges); overlapping change boxes merge into one region each. Falls back
/// to a full cut on the same grid planes when the new part leaves the grid.
/// Face route (old cut and `options` both FaceCut): the same by cells instead of blocks: the
/// cells whose boxes meet a changed region are cut again by the face route, all others keep
/// their subvolumes, curves and connections; pieces meeting across a kept/re-cut cell face are
/// matched by that face (area, centroid). Grid planes that a fresh cut of the new part would
/// shift (a new vertex or face extreme on them) are moved the same way and the cells on both
/// sides re-cut, so the result is that fresh cut. If that fails, a full cut with the reason.
GridCut recut_by_grid(const PartShape& new_part, const GridCut& old, const PartShape& old_part,
                      const GridOptions& options, RecutReport* report = nullptr);

}  // namespace parafab::occ
