// Plain geometry of cut cells, as the OpenCASCADE bridge delivers it to the quadrature
// (thesis §6.3, Fig. 6.5): every subvolume of a grid cell is bounded by patches, each a
// trimmed region of a parametric surface (a piece of a B-rep face, or a planar region on a
// cell face), given by its surface map and its boundary loops in parameter space.
// No OpenCASCADE types: the bridge implements SurfaceMap over Geom_Surface.
#pragma once

#include <Eigen/Core>
#include <memory>
#include <vector>

namespace parafab::xfem {

using Vec2 = Eigen::Vector2d;
using Vec3 = Eigen::Vector3d;

struct Box3 {
  Vec3 min{0, 0, 0}, max{0, 0, 0};
  Vec3 size() const { return max - min; }
  double volume() const { return size().prod(); }
};

/// A parametric surface σ(u, v) ∈ R³ with first derivatives.
class SurfaceMap {
 public:
  virtual ~SurfaceMap() = default;
  virtual void evaluate(double u, double v, Vec3& X, Vec3& Xu, Vec3& Xv) const = 0;
};

/// A closed loop in the (u, v) plane made of polynomial segments through `points`:
/// order 1: segment k joins points[k] and points[k+1];
/// order 2: segment k is the parabola through points[2k], points[2k+1], points[2k+2]
///          (interpolating at t = 0, 1/2, 1).
/// The last point repeats the first. Loops run so that the region lies on their left
/// (outer loops counter-clockwise, holes clockwise) in (u, v).
struct BoundaryLoop {
  std::vector<Vec2> points;
  int order = 2;
};

/// One boundary patch of a subvolume.
struct CutPatch {
  std::shared_ptr<const SurfaceMap> surface;
  std::vector<BoundaryLoop> loops;
  /// +1 when σ_u × σ_v points out of the subvolume, −1 when it points in.
  int orientation = 1;
  int source_face = -1;  ///< B-rep face index (face model numbering), −1 on a grid face
  int grid_axis = -1;    ///< 0, 1, 2 on a grid face (x, y, z = const), −1 otherwise
};

/// A connected piece of the solid inside one grid cell.
struct Subvolume {
  Box3 cell;                     ///< the grid cell
  std::vector<CutPatch> patches; ///< its closed boundary
};

}  // namespace parafab::xfem
