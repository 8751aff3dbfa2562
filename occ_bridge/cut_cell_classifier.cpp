// Point-in-material by crossing parity inside one cut cell (see cut_cell_classifier.h).
#include "cut_cell_classifier.h"

#include <ElSLib.hxx>
#include <Geom_CylindricalSurface.hxx>
#include <Geom_Plane.hxx>
#include <Geom_SphericalSurface.hxx>
#include <cmath>

#include "common/error.h"
#include "grid_cut.h"
#include "grid_cut_detail.h"
#include "occt_shape.h"

namespace parafab::occ {

namespace {

using xfem::Vec2;
using xfem::Vec3;

enum class Kind { Plane, Cylinder, Sphere, GridPlane };

// One patch on an elementary surface: C + R, axis a (plane: normal). GridPlane: a grid face of
// the face route (X_axis = C[axis], (u, v) = (X_{axis+1}, X_{axis+2})).
struct Patch {
  Kind kind = Kind::Plane;
  gp_Pln plane;
  gp_Cylinder cylinder;
  gp_Sphere sphere;
  Vec3 C{0, 0, 0}, a{0, 0, 1};
  double R = 0;
  const std::vector<xfem::BoundaryLoop>* loops = nullptr;
  double umin = 0, umax = 0;  ///< u range of the loops
  int axis = -1;              ///< GridPlane
};

Vec3 vec(const gp_XYZ& p) { return Vec3(p.X(), p.Y(), p.Z()); }

// |distance| of X to the patch's whole surface.
double surface_distance(const Patch& p, const Vec3& X) {
  const Vec3 w = X - p.C;
  switch (p.kind) {
    case Kind::Plane:
    case Kind::GridPlane:
      return std::abs(w.dot(p.a));
    case Kind::Cylinder:
      return std::abs((w - w.dot(p.a) * p.a).norm() - p.R);
    case Kind::Sphere:
      return std::abs(w.norm() - p.R);
  }
  return 0;
}

// Roots t of the line Y + t D with the surface (none, one or two); false: a double root
// (tangent line), undecidable here.
bool line_hits(const Patch& p, const Vec3& Y, const Vec3& D, double roots[2], int& count) {
  count = 0;
  const Vec3 w = Y - p.C;
  double A, B, Cq;
  if (p.kind == Kind::Plane || p.kind == Kind::GridPlane) {
    const double dn = D.dot(p.a);
    if (dn == 0) return true;  // parallel: no crossing (a point on the plane was sent to OCCT before)
    roots[count++] = -w.dot(p.a) / dn;
    return true;
  }
  if (p.kind == Kind::Cylinder) {
    const Vec3 wp = w - w.dot(p.a) * p.a, Dp = D - D.dot(p.a) * p.a;
    A = Dp.squaredNorm(), B = 2 * wp.dot(Dp), Cq = wp.squaredNorm() - p.R * p.R;
  } else {
    A = D.squaredNorm(), B = 2 * w.dot(D), Cq = w.squaredNorm() - p.R * p.R;
  }
  if (A == 0) return true;  // along the cylinder's axis: never crosses it
  const double disc = B * B - 4 * A * Cq;
  if (disc < 0) return true;
  if (disc <= 1e-10 * B * B + 1e-300) return false;
  const double s = std::sqrt(disc), q = -0.5 * (B + (B >= 0 ? s : -s));
  roots[count++] = q / A;
  if (q != 0) roots[count++] = Cq / q;
  return true;
}

// Unit normal of the surface at a point P on it.
Vec3 normal_at(const Patch& p, const Vec3& P) {
  const Vec3 w = P - p.C;
  if (p.kind == Kind::Plane || p.kind == Kind::GridPlane) return p.a;
  if (p.kind == Kind::Cylinder) return (w - w.dot(p.a) * p.a).normalized();
  return w.normalized();
}

enum class Where { Inside, Outside, Near };

// Is (u, v) inside the patch's loops (winding number of the polylines through the loop
// points, holes clockwise)? Near: within the polyline's deviation from the loop's parabolas
// plus `margin` (lengths: u scaled by su, v by sv).
Where in_loops(const std::vector<xfem::BoundaryLoop>& loops, const Vec2& q, double su, double sv, double margin) {
  int winding = 0;
  auto scaled = [&](const Vec2& p) { return Vec2(p.x() * su, p.y() * sv); };
  const Vec2 Q = scaled(q);
  for (const auto& loop : loops) {
    const auto& pts = loop.points;
    for (size_t k = 0; k + 1 < pts.size(); ++k) {
      const Vec2 a = scaled(pts[k]), b = scaled(pts[k + 1]);
      // The parabola through points 2j, 2j+1, 2j+2 leaves the polyline by at most |p0 − 2pm + p1|/8.
      double bulge = 0;
      if (loop.order == 2) {
        const size_t j = k - k % 2;
        if (j + 2 < pts.size()) bulge = (scaled(pts[j]) - 2 * scaled(pts[j + 1]) + scaled(pts[j + 2])).norm() / 8;
      }
      const Vec2 ab = b - a;
      const double len2 = ab.squaredNorm();
      const double t = len2 > 0 ? std::clamp((Q - a).dot(ab) / len2, 0.0, 1.0) : 0.0;
      if ((a + t * ab - Q).norm() <= bulge + margin) return Where::Near;
      // Winding number (Sunday's crossing test).
      if (a.y() <= Q.y()) {
        if (b.y() > Q.y() && (ab.x() * (Q.y() - a.y()) - (Q.x() - a.x()) * ab.y()) > 0) ++winding;
      } else if (b.y() <= Q.y() && (ab.x() * (Q.y() - a.y()) - (Q.x() - a.x()) * ab.y()) < 0) {
        --winding;
      }
    }
  }
  return winding != 0 ? Where::Inside : Where::Outside;
}

// `cp` as a Patch; false when its surface is not a plane, cylinder or sphere.
bool elementary_patch(const xfem::CutPatch& cp, Patch& p) {
  const auto* map = dynamic_cast<const detail::OcctSurfaceMap*>(cp.surface.get());
  if (!map) {
    if (cp.grid_axis < 0) return false;
    // A grid face of the face route: (u, v) = (X_{a+1}, X_{a+2}) on X_a = const.
    Vec3 X, Xu, Xv;
    cp.surface->evaluate(0, 0, X, Xu, Xv);
    p.kind = Kind::GridPlane, p.axis = cp.grid_axis;
    p.C = X, p.a = Vec3::Unit(cp.grid_axis);
  } else {
    const Handle(Geom_Surface)& s = map->surface();
    if (auto pl = Handle(Geom_Plane)::DownCast(s)) {
      p.kind = Kind::Plane, p.plane = pl->Pln();
      p.C = vec(p.plane.Location().XYZ()), p.a = vec(p.plane.Axis().Direction().XYZ());
    } else if (auto cy = Handle(Geom_CylindricalSurface)::DownCast(s)) {
      p.kind = Kind::Cylinder, p.cylinder = cy->Cylinder();
      p.C = vec(p.cylinder.Location().XYZ()), p.a = vec(p.cylinder.Axis().Direction().XYZ()), p.R = p.cylinder.Radius();
    } else if (auto sp = Handle(Geom_SphericalSurface)::DownCast(s)) {
      p.kind = Kind::Sphere, p.sphere = sp->Sphere();
      p.C = vec(p.sphere.Location().XYZ()), p.R = p.sphere.Radius();
    } else {
      return false;
    }
  }
  p.loops = &cp.loops;
  p.umin = 1e300, p.umax = -1e300;
  for (const auto& loop : cp.loops)
    for (const Vec2& q : loop.points) p.umin = std::min(p.umin, q.x()), p.umax = std::max(p.umax, q.x());
  return true;
}

// Where the point P of the patch's surface lies in its loops (Near also close to a sphere's pole,
// where (u, v) degenerate).
Where where_on_patch(const Patch& p, const Vec3& P, double near) {
  double u = 0, v = 0;
  const gp_Pnt G(P.x(), P.y(), P.z());
  double su = 1, sv = 1;  // (u, v) → lengths
  switch (p.kind) {
    case Kind::Plane:
      ElSLib::Parameters(p.plane, G, u, v);
      break;
    case Kind::GridPlane:
      u = P[(p.axis + 1) % 3], v = P[(p.axis + 2) % 3];
      break;
    case Kind::Cylinder:
      ElSLib::Parameters(p.cylinder, G, u, v);
      su = p.R;
      break;
    case Kind::Sphere:
      ElSLib::Parameters(p.sphere, G, u, v);
      su = p.R * std::cos(v), sv = p.R;
      if (std::abs(std::cos(v)) < 1e-3) return Where::Near;
      break;
  }
  const bool periodic = p.kind == Kind::Cylinder || p.kind == Kind::Sphere;
  const double m = (near + 1e-12) / std::max(std::abs(su), 1e-300);  // the near band, in u
  bool inside = false;
  for (int shift = periodic ? -2 : 0; shift <= (periodic ? 2 : 0); ++shift) {
    const double us = u + 2 * M_PI * shift;
    if (us < p.umin - m || us > p.umax + m) continue;
    const Where w = in_loops(*p.loops, Vec2(us, v), std::abs(su), sv, near);
    if (w == Where::Near) return Where::Near;
    inside |= w == Where::Inside;
  }
  return inside ? Where::Inside : Where::Outside;
}

// How often the segment Y → Y + D crosses the patches (inside their loops). −1: undecided (the
// end X = Y + D within `near` of a patch surface, a tangent line, a grazing hit, a hit near a
// loop or near a sphere's pole). Y must be farther than `near` from every patch surface.
// `touching`: patches whose surface passes within `near` of X but whose loops do not hold X:
// they do not make the count undecided, and their hits at X are not crossings.
int crossings(const std::vector<Patch>& patches, const Vec3& Y, const Vec3& D, double near,
              const std::vector<bool>* touching = nullptr) {
  const Vec3 X = Y + D;
  const double length = D.norm();
  int count_in = 0;
  for (size_t k = 0; k < patches.size(); ++k) {
    const Patch& p = patches[k];
    const bool touches = touching && (*touching)[k];
    if (!touches && surface_distance(p, X) <= near) return -1;
    double roots[2];
    int count = 0;
    if (!line_hits(p, Y, D, roots, count)) return -1;
    for (int r = 0; r < count; ++r) {
      const double t = roots[r];
      if (t <= 0 || t >= 1) continue;  // both ends are farther than `near` from the surface
      if (touches && (1 - t) * length <= 2 * near) continue;  // the hit at X, outside the loops
      const Vec3 P = Y + t * D;
      if (std::abs(normal_at(p, P).dot(D) / length) < 1e-3) return -1;  // grazing
      const Where w = where_on_patch(p, P, near);
      if (w == Where::Near) return -1;
      count_in += w == Where::Inside;
    }
  }
  return count_in;
}

}  // namespace

struct CutCellClassifier::Cell {
  bool usable = false;  ///< every B-rep patch on a plane, cylinder or sphere, and a reference corner
  std::vector<Patch> patches;
  Vec3 reference{0, 0, 0};
  bool reference_in = false;
};

CutCellClassifier::CutCellClassifier(const PartShape& part, const GridCut& cut, double tolerance)
    : cut_(cut), tolerance_(tolerance), occt_(part, tolerance) {
  for (size_t i = 0; i < cut.cut_cells.size(); ++i) {
    const auto& c = cut.cut_cells[i].index;
    cut_cell_of_[(static_cast<long long>(c[0]) * cut.cells[1] + c[1]) * cut.cells[2] + c[2]] = static_cast<int>(i);
  }
}

CutCellClassifier::~CutCellClassifier() = default;

const CutCellClassifier::Cell& CutCellClassifier::cell_data(const std::array<int, 3>& ijk) const {
  const long long key = (static_cast<long long>(ijk[0]) * cut_.cells[1] + ijk[1]) * cut_.cells[2] + ijk[2];
  auto found = cells_.find(key);
  if (found != cells_.end()) return *found->second;
  auto cell = std::make_unique<Cell>();
  const auto cc = cut_cell_of_.find(key);
  bool usable = cc != cut_cell_of_.end();
  for (size_t s = 0; usable && s < cut_.cut_cells[cc->second].subvolumes.size(); ++s) {
    for (const xfem::CutPatch& cp : cut_.subvolumes[cut_.cut_cells[cc->second].subvolumes[s]].patches) {
      if (cp.source_face < 0) continue;  // a grid face: not the part's boundary
      Patch p;
      if (!elementary_patch(cp, p)) {
        usable = false;
        break;
      }
      cell->patches.push_back(p);
    }
  }
  if (usable) {
    // A reference point clear of every patch surface, classified by OCCT once: a corner, else
    // a point inside the cell (a face of the part may lie on a grid plane through the corners).
    const xfem::Box3 box = cut_.cell_box(ijk);
    static const double fractions[][3] = {{0.5, 0.5, 0.5}, {0.3, 0.6, 0.45}, {0.7, 0.35, 0.6}, {0.4, 0.25, 0.8}};
    for (int k = 0; k < 12 && !cell->usable; ++k) {
      const Vec3 Y = k < 8 ? Vec3((k & 1) ? box.max.x() : box.min.x(), (k & 2) ? box.max.y() : box.min.y(),
                                  (k & 4) ? box.max.z() : box.min.z())
                           : box.min + Vec3(fractions[k - 8][0], fractions[k - 8][1], fractions[k - 8][2]).cwiseProduct(box.size());
      bool clear = true;
      for (const Patch& p : cell->patches) clear &= surface_distance(p, Y) > 100 * tolerance_;
      if (!clear) continue;
      const PointClassifier::State st = occt_.state(Y);
      ++counts_.by_occt;
      if (st == PointClassifier::State::On) continue;
      cell->usable = true, cell->reference = Y, cell->reference_in = st == PointClassifier::State::In;
    }
  }
  return *cells_.emplace(key, std::move(cell)).first->second;
}

bool CutCellClassifier::in_material(const std::array<int, 3>& ijk, const Vec3& X) const {
  const Cell& cell = cell_data(ijk);
  auto by_occt = [&] {
    ++counts_.by_occt;
    return occt_.in_material(X);
  };
  if (!cell.usable) return by_occt();
  const Vec3 D = X - cell.reference;
  const double near = 100 * tolerance_;  // closer than this to a surface: OCCT decides (its ON band is `tolerance`)
  if (D.norm() <= near) return by_occt();
  const int crossed = crossings(cell.patches, cell.reference, D, near);
  if (crossed < 0) return by_occt();
  ++counts_.by_crossings;
  return cell.reference_in != (crossed % 2 == 1);
}

SubvolumeTest point_in_subvolume(const xfem::Subvolume& subvolume, const Vec3& X, double near) {
  std::vector<Patch> patches(subvolume.patches.size());
  for (size_t k = 0; k < patches.size(); ++k)
    if (!elementary_patch(subvolume.patches[k], patches[k])) return SubvolumeTest::Undecided;
  // X on a patch (a surface vertex of the part, a point on a cell face): on the boundary.
  std::vector<bool> touching(patches.size(), false);
  for (size_t k = 0; k < patches.size(); ++k) {
    if (surface_distance(patches[k], X) > near) continue;
    const Where w = where_on_patch(patches[k], X, near);  // (u, v) of X's projection
    if (w == Where::Inside) return SubvolumeTest::OnBoundary;
    if (w == Where::Near) return SubvolumeTest::Undecided;  // on a loop: an edge of the piece, or just off it
    touching[k] = true;
  }
  // Rays from X that leave the cell (twice its diagonal long); another direction when one grazes
  // a patch or passes near a loop.
  static const double directions[][3] = {{0.5377, 0.3127, 0.7834}, {-0.4121, 0.8219, -0.3931}, {0.6913, -0.5546, -0.4632}};
  const double length = 2 * subvolume.cell.size().norm();
  for (const auto& d : directions) {
    const Vec3 D = length * Vec3(d[0], d[1], d[2]).normalized();
    // The segment runs from its far end (clear of the cell) back to X.
    const int crossed = crossings(patches, X + D, -D, near, &touching);
    if (crossed >= 0) return crossed % 2 == 1 ? SubvolumeTest::Inside : SubvolumeTest::Outside;
  }
  return SubvolumeTest::Undecided;
}

}  // namespace parafab::occ
