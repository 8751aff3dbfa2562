// How close the material pieces of a grid cell are to joining (thesis §6.4.4, Fig. 6.10): when
// a shape change makes two subvolumes of one cell join, their enriched copies of the cell's
// nodes become one DOF and the simulation jumps. Eq. 6.24 smooths this with a penalty
// b(d)‖x¹ − x²‖² whose weight grows as a distance d goes to zero at the join. This file gives
// that d for every pair of pieces of a cell, the exact Euclidean gap between the two pieces
// (OCCT: the solid's common with the cell box, BRepExtrema between its solids), and its shape
// derivative from the normal velocity of the faces at the closest points. The penalty itself
// is not applied yet.
#pragma once

#include <Eigen/Core>
#include <array>
#include <string>
#include <vector>

#include "xfem/cut_geometry.h"

namespace parafab::occ {

struct PartShape;
struct GridModel;
struct ShapeParameters;

struct PieceGapOptions {
  /// Report pairs whose gap is below this (model units); ≤ 0: every pair of pieces of a cell.
  double critical_distance = 0;
  /// A closest point lies on a face of the part when within this × the cell's smallest side.
  double face_tolerance = 1e-6;
};

/// Where a closest point lies: on one face of the part (face ≥ 0, with the solid's outward
/// normal there), on the cell's box only (face −1: it does not move with the shape), or on an
/// edge or vertex between faces of the part (face −2: no derivative here).
struct GapEnd {
  xfem::Vec3 point{0, 0, 0};
  int face = -1;
  xfem::Vec3 normal{0, 0, 0};  ///< outward normal of the solid at point (face ≥ 0)
};

struct PieceGap {
  std::array<int, 3> cell{0, 0, 0};
  int element_a = -1, element_b = -1;  ///< indices into GridModel::elements, a < b
  double distance = 0;
  GapEnd a, b;  ///< closest points on piece a and on piece b
  /// OCCT's common of the solid and the cell has both elements in one solid: the pieces touch
  /// (distance 0) where the cut still separates them (at the join, within OCCT's tolerance).
  bool joined = false;
};

struct PieceGapResult {
  bool done = false;
  std::string message;  ///< why not done (a failed Boolean names its cell)
  std::vector<PieceGap> gaps;
  int cells_checked = 0;           ///< cells with two or more pieces
  double max_centroid_mismatch = 0;  ///< largest distance between an element's rule centroid and its OCCT piece's
  double seconds = 0;
};

/// The gaps between the pieces of every cut cell of `grid` (the model of `part`) with two or
/// more pieces.
PieceGapResult piece_gaps(const PartShape& part, const GridModel& grid, const PieceGapOptions& options = {});

/// ∂d/∂p of each gap (rows) for the parameter vector p of `parameters` (columns): a closest
/// point on face f moves with the face's normal velocity Vₙ = ∂X/∂p·n, and along the gap
/// direction t = (b − a)/d by Vₙ/(n·t) (t ∥ n inside a face; on the section of a face with the
/// cell's box, t lies in the box face and the section moves by Vₙ/|n projected|), so
/// d' = −Vₙ,a/(n_a·t) − Vₙ,b/(n_b·(−t)). `complete[i]` is 0 where row i misses a term: an end
/// on an edge between faces of the part, on a B-spline face, a joined pair, or a zero gap.
Eigen::MatrixXd piece_gap_gradient(const std::vector<PieceGap>& gaps, const ShapeParameters& parameters,
                                   const Eigen::VectorXd& p, std::vector<char>* complete = nullptr);

}  // namespace parafab::occ
