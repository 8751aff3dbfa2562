#include "surface_mesh.h"

#include <BRepMesh_IncrementalMesh.hxx>
#include <BRepTools.hxx>
#include <BRep_Tool.hxx>
#include <Poly_Triangulation.hxx>
#include <TopLoc_Location.hxx>

#include <algorithm>
#include <cmath>

#include "common/error.h"
#include "occt_shape.h"

namespace parafab::occ {

SurfaceMesh triangulate_part(const PartShape& part, double deflection, double max_edge, bool parallel) {
  PARAFAB_VERIFY(deflection > 0, "surface mesh: deflection must be positive, got " << deflection);
  // Work on a copy so the caller's shape keeps no triangulation (and no shared state changes).
  TopoDS_Shape shape = part.shape;
  BRepTools::Clean(shape);
  BRepMesh_IncrementalMesh mesher(shape, deflection, /*isRelative=*/false, /*angle=*/0.3, parallel);
  SurfaceMesh m;
  for (int i = 0; i < part.face_count(); ++i) {
    const TopoDS_Face& face = part.face(i);
    TopLoc_Location loc;
    const Handle(Poly_Triangulation) tri = BRep_Tool::Triangulation(face, loc);
    PARAFAB_VERIFY(!tri.IsNull(), "surface mesh: face " << i << " of " << part.source << " could not be triangulated");
    const gp_Trsf& T = loc.Transformation();
    const int base = static_cast<int>(m.points.size());
    for (int k = 1; k <= tri->NbNodes(); ++k) {
      const gp_Pnt p = tri->Node(k).Transformed(T);
      m.points.emplace_back(p.X(), p.Y(), p.Z());
    }
    const bool reversed = face.Orientation() == TopAbs_REVERSED;
    for (int t = 1; t <= tri->NbTriangles(); ++t) {
      int a, b, c;
      tri->Triangle(t).Get(a, b, c);
      if (reversed) std::swap(b, c);
      const std::array<int, 3> t3{base + a - 1, base + b - 1, base + c - 1};
      const xfem::Vec3 P[3] = {m.points[t3[0]], m.points[t3[1]], m.points[t3[2]]};
      const double longest = std::max({(P[1] - P[0]).norm(), (P[2] - P[1]).norm(), (P[0] - P[2]).norm()});
      const int k = max_edge > 0 ? std::max(1, static_cast<int>(std::ceil(longest / max_edge))) : 1;
      if (k == 1) {
        m.triangles.push_back(t3);
        m.triangle_face.push_back(i);
        continue;
      }
      // Barycentric lattice (r, q) with r + q ≤ k; corners keep their original vertices.
      std::vector<int> id((k + 1) * (k + 1), -1);
      auto node = [&](int r, int q) {
        int& v = id[r * (k + 1) + q];
        if (v >= 0) return v;
        if (r == 0 && q == 0) return v = t3[0];
        if (r == k) return v = t3[1];
        if (q == k) return v = t3[2];
        m.points.push_back(P[0] + (P[1] - P[0]) * (double(r) / k) + (P[2] - P[0]) * (double(q) / k));
        return v = static_cast<int>(m.points.size()) - 1;
      };
      for (int r = 0; r < k; ++r)
        for (int q = 0; r + q < k; ++q) {
          m.triangles.push_back({node(r, q), node(r + 1, q), node(r, q + 1)});
          m.triangle_face.push_back(i);
          if (r + q + 2 <= k) {
            m.triangles.push_back({node(r + 1, q), node(r + 1, q + 1), node(r, q + 1)});
            m.triangle_face.push_back(i);
          }
        }
    }
  }
  BRepTools::Clean(shape);
  return m;
}

}  // namespace parafab::occ
