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

enum class Kind { Plane, Cylinder, Sphere };

// One B-rep patch of the cell on an elementary surface: C + R, axis a (plane: normal).
struct Patch {
  Kind kind = Kind::Plane;
  gp_Pln plane;
  gp_Cylinder cylinder;
  gp_Sphere sphere;
  Vec3 C{0, 0, 0}, a{0, 0, 1};
  double R = 0;
  const std::vector<xfem::BoundaryLoop>* loops = nullptr;
  double umin = 0, umax = 0;  ///< u range of the loops
};

Vec3 vec(const gp_XYZ& p) { return Vec3(p.X(), p.Y(), p.Z()); }

// |distance| of X to the patch's whole surface.
double surface_distance(const Patch& p, const Vec3& X) {
  const Vec3 w = X - p.C;
  switch (p.kind) {
    case Kind::Plane:
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
  if (p.kind == Kind::Plane) {
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
  if (p.kind == Kind::Plane) return p.a;
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
      const auto* map = dynamic_cast<const detail::OcctSurfaceMap*>(cp.surface.get());
      if (!map) {
        usable = false;
        break;
      }
      Patch p;
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
        usable = false;
        break;
      }
      p.loops = &cp.loops;
      p.umin = 1e300, p.umax = -1e300;
      for (const auto& loop : cp.loops)
        for (const Vec2& q : loop.points) p.umin = std::min(p.umin, q.x()), p.umax = std::max(p.umax, q.x());
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
  const double length = D.norm();
  const double near = 100 * tolerance_;  // closer than this to a surface: OCCT decides (its ON band is `tolerance`)
  if (length <= near) return by_occt();
  int crossings = 0;
  for (const Patch& p : cell.patches) {
    if (surface_distance(p, X) <= near) return by_occt();
    double roots[2];
    int count = 0;
    if (!line_hits(p, cell.reference, D, roots, count)) return by_occt();
    for (int r = 0; r < count; ++r) {
      const double t = roots[r];
      if (t <= 0 || t >= 1) continue;  // both ends are farther than `near` from the surface
      const Vec3 P = cell.reference + t * D;
      if (std::abs(normal_at(p, P).dot(D) / length) < 1e-3) return by_occt();  // grazing
      double u = 0, v = 0;
      const gp_Pnt G(P.x(), P.y(), P.z());
      double su = 1, sv = 1;  // (u, v) → lengths
      switch (p.kind) {
        case Kind::Plane:
          ElSLib::Parameters(p.plane, G, u, v);
          break;
        case Kind::Cylinder:
          ElSLib::Parameters(p.cylinder, G, u, v);
          su = p.R;
          break;
        case Kind::Sphere:
          ElSLib::Parameters(p.sphere, G, u, v);
          su = p.R * std::cos(v), sv = p.R;
          if (std::abs(std::cos(v)) < 1e-3) return by_occt();  // near a pole
          break;
      }
      const bool periodic = p.kind != Kind::Plane;
      const double m = (near + 1e-12) / std::max(std::abs(su), 1e-300);  // the near band, in u
      bool inside = false;
      for (int shift = periodic ? -2 : 0; shift <= (periodic ? 2 : 0); ++shift) {
        const double us = u + 2 * M_PI * shift;
        if (us < p.umin - m || us > p.umax + m) continue;
        const Where w = in_loops(*p.loops, Vec2(us, v), std::abs(su), sv, near);
        if (w == Where::Near) return by_occt();
        inside |= w == Where::Inside;
      }
      crossings += inside;
    }
  }
  ++counts_.by_crossings;
  return cell.reference_in != (crossings % 2 == 1);
}

}  // namespace parafab::occ
