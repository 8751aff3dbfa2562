// How close the material pieces of a grid cell are to joining (thesis §6.4.4, Fig. 6.10): when
// a shape change makes two subvolumes of one cell join, their enriched copies of the cell's
// nodes become one DOF and the simulation jumps. Eq. 6.24 smooths this with a penalty
// b(d)‖x¹ − x²‖² whose weight grows as a distance d goes to zero at the join. This file gives
// that d for every pair of pieces of a cell, the exact Euclidean gap between the two pieces
// (OCCT: the solid's common with the cell box, BRepExtrema between its solids), and its shape
// derivative from the normal velocity of the faces at the closest points; piece_ties turns the
// gaps into the penalty's weights (xfem::PieceTie).
#pragma once

#include <Eigen/Core>
#include <array>
#include <string>
#include <vector>

#include "xfem/cut_geometry.h"
#include "xfem/linear_xfem.h"

namespace parafab::occ {

struct PartShape;
struct GridModel;
struct ShapeParameters;

struct PieceGapOptions {
  /// Report pairs whose gap is below this (model units); ≤ 0: every pair of pieces of a cell.
  double critical_distance = 0;
  /// A closest point lies on a face of the part when within this × the cell's smallest side.
  double face_tolerance = 1e-6;
  /// Also pairs of pieces of face-neighbour cells that share no part of that face (not in
  /// GridModel::adjacent): when they come to touch, their copies of the face's nodes become one.
  bool neighbour_cells = true;
  /// OCCT's solid of a cell against the volume of the cut's elements matched to it, as a
  /// fraction of the cell: a larger difference fails (the pieces do not correspond). The rules
  /// match OCCT to ~1e-8 of a cell (PieceGaps.MergePenaltyAtASlotTipCrossingAGridPlane); the
  /// margin is for OCCT's common, which dropped a piece 1.6e-7 mm before the bracket's join.
  double match_tolerance = 2e-3;
};

/// A closest point and the faces of the part it lies on (none: on the cell's box only, it does
/// not move with the shape), each with the solid's outward normal there.
struct GapEnd {
  xfem::Vec3 point{0, 0, 0};
  std::vector<int> faces;
  std::vector<xfem::Vec3> normals;
  std::vector<int> box_axes;  ///< the cell box's planes it lies on (their axes): it moves within them
};

struct PieceGap {
  std::array<int, 3> cell{0, 0, 0};    ///< element a's cell
  std::array<int, 3> cell_b{0, 0, 0};  ///< element b's: the same, or a face neighbour
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
  int cells_checked = 0;  ///< cells whose pieces OCCT made (a cell with two or more, or a neighbour's)
  double max_centroid_mismatch = 0;  ///< largest distance between an element's rule centroid and its OCCT piece's
  double seconds = 0;
};

/// The gaps between the pieces of every cut cell of `grid` (the model of `part`) with two or
/// more pieces, and (options.neighbour_cells) between pieces of face-neighbour cut cells that
/// are not adjacent.
PieceGapResult piece_gaps(const PartShape& part, const GridModel& grid, const PieceGapOptions& options = {});

/// ∂d/∂p of each gap (rows) for the parameter vector p of `parameters` (columns): a closest
/// point on face f with outward normal n moves with the face's normal velocity Vₙ = ∂X/∂p·n
/// within the cell box's planes it lies on (P: the projector onto their common directions, I
/// inside the box), by Vₙ·Pn/(nᵀPn), so with t = (b − a)/d the unit gap direction
/// d' = −Vₙ,a (Pn_a·t)/(n_aᵀPn_a) − Vₙ,b (Pn_b·(−t))/(n_bᵀPn_b) (inside a face n = t: −Vₙ; on a
/// face's section with a box plane: −Vₙ/|n projected| when t lies in that plane). Faces at an
/// end with n ⟂ t (|n·t| < 1e-9: the gap runs along them) do not move it, nor does a box
/// corner. `complete[i]` is 0 where row i misses a term: an end on two faces not along t (an
/// edge or vertex of the part), on a B-spline face, a joined pair, or a zero gap. Where the
/// closest points are not unique (OCCT's first solution is used) the gap may not be
/// differentiable.
Eigen::MatrixXd piece_gap_gradient(const std::vector<PieceGap>& gaps, const ShapeParameters& parameters,
                                   const Eigen::VectorXd& p, std::vector<char>* complete = nullptr);

/// Eq. 6.24's penalty: weight E·h·b(d) on each pair of tied DOF nodes, h the cell's smallest
/// side, b capped at `cap` (the thesis cuts b off "at a high value" for the conditioning). b and
/// b' vanish at d = d_crit: a pair enters and leaves smoothly.
/// - Log2 (the thesis's b(d) = log²(min{1, d/d_crit})): grows so slowly that near the join the
///   tie is still soft: on the slotted block 1e-9 mm past a join C is 4.1e-7 off the joined
///   model's against 4.1e-8 with InverseSquare (of a 4.8e-2 jump without ties;
///   PieceGaps.MergePenaltyAtASlotTipCrossingAGridPlane).
/// - InverseSquare (ParaFab's default): b(d) = (d_crit/d − 1)², so b ∝ 1/d²: where d ∝ √δ (δ the
///   shape change left to the join, a tip crossing a grid plane) the tie's softness, hence C's
///   remaining step, is O(δ).
struct MergePenaltyOptions {
  bool enabled = false;
  enum class Law { Log2, InverseSquare };
  Law law = Law::InverseSquare;
  double critical_fraction = 0.05;  ///< d_crit / h
  double cap = 0;                   ///< largest b; 0: 1e3 for Log2, 1e4 for InverseSquare (1e8 cost the bracket's join 1e-7 of C in round-off)
};

/// b(d) (and b'(d) in `derivative`: 0 beyond d_crit and on the cap).
double merge_penalty_b(double d, double critical, const MergePenaltyOptions& options, double* derivative = nullptr);

/// The ties of the gaps closer than d_crit (a joined pair: d = 0, the cap), weight E·h·b(d).
std::vector<xfem::PieceTie> piece_ties(const std::vector<PieceGap>& gaps, const GridModel& grid, double youngs_modulus,
                                       const MergePenaltyOptions& options);

}  // namespace parafab::occ
