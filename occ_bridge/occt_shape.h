// The OpenCASCADE side of PartShape (thesis §6.2.1, the CAD model): the solid and its stable
// face/edge numbering. Private to occ_bridge/*.cpp; public headers only see `struct PartShape;`.
#pragma once

#include <TopTools_IndexedMapOfShape.hxx>
#include <TopoDS.hxx>
#include <TopoDS_Edge.hxx>
#include <TopoDS_Face.hxx>
#include <TopoDS_Shape.hxx>
#include <memory>
#include <string>
#include <vector>

#include "part_reader.h"

namespace parafab::occ {

/// One valid, closed, manifold solid. Face, edge and vertex indices are 0-based positions in
/// TopExp::MapShapes(solid, ...) order: ParaFab index i is map index i + 1. Everyone (face
/// model, grid cutting, JSON) uses these indices.
struct PartShape {
  TopoDS_Shape shape;  ///< a TopoDS_Solid
  TopTools_IndexedMapOfShape faces, edges, vertices;
  std::string source;   ///< file path, or "BRep string"
  std::string name;     ///< the solid's name in the file (STEP product or entity), may be ""
  int solid_index = 0;  ///< position among the solids of the file
  int solid_count = 1;  ///< solids in the file

  int face_count() const { return faces.Extent(); }
  int edge_count() const { return edges.Extent(); }
  const TopoDS_Face& face(int i) const { return TopoDS::Face(faces(i + 1)); }
  const TopoDS_Edge& edge(int i) const { return TopoDS::Edge(edges(i + 1)); }
  int face_index(const TopoDS_Shape& f) const { return faces.FindIndex(f) - 1; }  ///< −1 if absent
  int edge_index(const TopoDS_Shape& e) const { return edges.FindIndex(e) - 1; }  ///< −1 if absent
};

/// Selects one solid of `shape` (per `options`), validates it (closed, manifold,
/// BRepCheck_Analyzer) and numbers its faces and edges. `source` names the input in errors;
/// `names` gives solids' names (same length as the solids of `shape` in TopExp order, or
/// empty). Throws parafab::Error naming the problem, the source and the face/edge index.
std::shared_ptr<const PartShape> make_part(const TopoDS_Shape& shape, const std::string& source,
                                           const ReadOptions& options = {},
                                           const std::vector<std::string>& names = {});

}  // namespace parafab::occ
