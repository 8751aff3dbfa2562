// A triangulation of a part's B-rep faces (OCCT's BRepMesh), for showing results on the exact
// boundary: the simulator evaluates displacement and stress at its vertices (surface.vtu).
#pragma once

#include <array>
#include <vector>

#include "xfem/cut_geometry.h"

namespace parafab::occ {

struct PartShape;

struct SurfaceMesh {
  std::vector<xfem::Vec3> points;
  std::vector<std::array<int, 3>> triangles;  ///< counter-clockwise seen from outside
  std::vector<int> triangle_face;             ///< B-rep face index of every triangle
};

/// Triangulates every face with chordal deflection `deflection` (model units) and an angular
/// deflection of 0.3 rad; vertices are not shared between faces. With `max_edge` > 0, every
/// triangle longer than that is split uniformly into k² triangles (k from its longest edge),
/// so fields evaluated at the vertices are resolved on large flat faces too (neighbouring
/// triangles may then meet with hanging vertices: a display mesh). Throws parafab::Error if
/// a face cannot be triangulated. `parallel`: OCCT meshes the faces in parallel (the same
/// triangulation either way).
SurfaceMesh triangulate_part(const PartShape& part, double deflection, double max_edge = 0, bool parallel = true);

}  // namespace parafab::occ
