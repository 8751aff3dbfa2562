// Private helpers shared by the two grid-cutting routes (thesis §6.3): the OCCT surface as the
// quadrature's SurfaceMap and the sampling of curves into polynomial boundary segments.
// Only for occ_bridge/*.cpp.
#pragma once

#include <BRepBndLib.hxx>
#include <Bnd_Box.hxx>
#include <Geom2d_Curve.hxx>
#include <Geom_Surface.hxx>
#include <TopoDS_Shape.hxx>

#include <cmath>
#include <string>
#include <vector>

#include "grid_cut.h"

namespace parafab::occ::detail {

using xfem::Box3;
using xfem::Vec2;
using xfem::Vec3;

inline Box3 tight_box(const TopoDS_Shape& s) {
  Bnd_Box bb;
  BRepBndLib::AddOptimal(s, bb, /*useTriangulation=*/false, /*useShapeTolerance=*/false);
  double x0, y0, z0, x1, y1, z1;
  bb.Get(x0, y0, z0, x1, y1, z1);
  Box3 b;
  b.min = Vec3(x0, y0, z0);
  b.max = Vec3(x1, y1, z1);
  return b;
}

/// The surface of a face (location applied) as the quadrature's SurfaceMap.
class OcctSurfaceMap : public xfem::SurfaceMap {
 public:
  explicit OcctSurfaceMap(Handle(Geom_Surface) s) : surface_(std::move(s)) {}
  void evaluate(double u, double v, Vec3& X, Vec3& Xu, Vec3& Xv) const override {
    gp_Pnt p;
    gp_Vec du, dv;
    surface_->D1(u, v, p, du, dv);
    X = Vec3(p.X(), p.Y(), p.Z());
    Xu = Vec3(du.X(), du.Y(), du.Z());
    Xv = Vec3(dv.X(), dv.Y(), dv.Z());
  }
  const Handle(Geom_Surface)& surface() const { return surface_; }

 private:
  Handle(Geom_Surface) surface_;
};

inline Vec2 eval2(const Handle(Geom2d_Curve)& c, double t) {
  const gp_Pnt2d p = c->Value(t);
  return Vec2(p.X(), p.Y());
}

// Appends the curve `at(t)` from t0 to t1 (t1 < t0 for a reversed edge) as `order`
// polynomial segments (without the first point, which the caller already holds), refined by
// doubling until the interpolant deviates less than `tol` from the curve at interior test
// points. Returns the number of segments. `param`, if given, receives t of every point added.
template <class Vec, class Eval>
int append_curve(const Eval& at, double t0, double t1, bool straight, const GridOptions& o,
                 double tol, std::vector<Vec>& out, std::vector<double>* param = nullptr) {
  int n = 1;
  const int order = o.segment_order;
  auto t_at = [&](int k, int n_seg, double frac) { return t0 + (t1 - t0) * (k + frac) / n_seg; };
  auto point_at = [&](int k, int n_seg, double frac) { return at(t_at(k, n_seg, frac)); };
  while (!straight && n < o.max_segments_per_edge) {
    double err = 0;
    for (int k = 0; k < n && err <= tol; ++k) {
      const Vec p0 = point_at(k, n, 0), p1 = point_at(k, n, 1);
      if (order == 1) {
        for (double f : {0.25, 0.5, 0.75})
          err = std::max(err, (point_at(k, n, f) - ((1 - f) * p0 + f * p1)).norm());
      } else {
        const Vec pm = point_at(k, n, 0.5);
        for (double f : {0.25, 0.75}) {  // Lagrange parabola through t = 0, 1/2, 1
          const Vec q = 2 * (f - 0.5) * (f - 1) * p0 - 4 * f * (f - 1) * pm + 2 * f * (f - 0.5) * p1;
          err = std::max(err, (point_at(k, n, f) - q).norm());
        }
      }
    }
    if (err <= tol) break;
    n *= 2;
  }
  for (int k = 0; k < n; ++k) {
    if (order == 2) {
      out.push_back(point_at(k, n, 0.5));
      if (param) param->push_back(t_at(k, n, 0.5));
    }
    out.push_back(point_at(k, n, 1.0));
    if (param) param->push_back(t_at(k, n, 1.0));
  }
  return n;
}

/// The (u, v) of 3D point P on surface S, by Gauss–Newton from `uv0` (e.g. a pcurve's value,
/// which approximates the exact section curve only to the edge tolerance). Keeps `uv0` if the
/// step grows beyond `max_move` (near a pole or apex, where u is ill-conditioned).
inline Vec2 refine_uv(const Handle(Geom_Surface)& S, const Vec2& uv0, const gp_Pnt& P, double max_move) {
  Vec2 uv = uv0;
  for (int it = 0; it < 4; ++it) {
    gp_Pnt X;
    gp_Vec du, dv;
    S->D1(uv.x(), uv.y(), X, du, dv);
    const gp_Vec r(X, P);
    const double a = du.Dot(du), b = du.Dot(dv), c = dv.Dot(dv), det = a * c - b * b;
    if (!(det > 1e-30 * (a * c + 1e-300))) break;
    const double ru = du.Dot(r), rv = dv.Dot(r);
    const Vec2 d((c * ru - b * rv) / det, (a * rv - b * ru) / det);
    uv += d;
    if (d.norm() < 1e-15 * (1 + uv.norm())) break;
  }
  return (uv - uv0).norm() <= max_move ? uv : uv0;
}

/// Re-cutting on the face route (recut_by_grid): only the `dirty` cells are cut again; every
/// other cell keeps its state (`status`: 0 outside, 1 interior, 2 cut) and its old pieces,
/// which the caller holds in `g`. Cell index = i + n0·(j + n1·k).
struct FaceRecut {
  std::vector<char> dirty;
  std::vector<signed char> status;
  int cells_cut = 0;  ///< out: dirty cells that came out cut
  int faces_cut = 0;  ///< out: B-rep faces cut again (those meeting a dirty cell)
};

/// The plane area and centroid of a grid-face patch (axis a at coordinate q) from its sampled
/// loops (points as polygon): how pieces of kept and re-cut cells are matched across a cell face.
inline void grid_patch_area_centroid(const xfem::CutPatch& p, int a, double q, double& area, Vec3& centroid) {
  double A = 0, cx = 0, cy = 0;
  for (const auto& l : p.loops)
    for (size_t i = 0; i + 1 < l.points.size(); ++i) {
      const Vec2& u = l.points[i];
      const Vec2& v = l.points[i + 1];
      const double c = u.x() * v.y() - v.x() * u.y();
      A += c, cx += (u.x() + v.x()) * c, cy += (u.y() + v.y()) * c;
    }
  area = std::abs(0.5 * A);
  centroid[a] = q;
  centroid[(a + 1) % 3] = A != 0 ? cx / (3 * A) : 0;
  centroid[(a + 2) % 3] = A != 0 ? cy / (3 * A) : 0;
}

/// The face route (face_cut.cpp): fills the cut cells, subvolumes, connections and curves of
/// `g`, whose grid (box, cells, planes) is set. False with `g.message` = the reason when the
/// part has faces it does not handle or its consistency check fails. With `recut`, only the
/// dirty cells are cut (appended to what `g` holds), g.interior_cells lists all interior
/// cells, and the grid-face patches between a re-cut and a kept cut cell become
/// g.block_faces (owner: the new subvolume) for the caller to match.
bool cut_by_faces(const PartShape& part, const GridOptions& options, GridCut& g, FaceRecut* recut = nullptr);

}  // namespace parafab::occ::detail
