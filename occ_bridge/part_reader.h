// Reads a CAD part (STEP, BREP file, or a BRep string from FreeCAD's exportBrepToString)
// into one validated solid, the B-rep input of X-CAD (thesis §6.2.1). No OCCT types here.
#pragma once

#include <Eigen/Core>
#include <memory>
#include <string>
#include <vector>

namespace parafab::occ {

/// Opaque handle: one valid closed solid with stable face/edge indices (occt_shape.h).
struct PartShape;

struct ReadOptions {
  /// Which solid to take when the file holds several: 0-based, in file (TopExp) order.
  /// −1: none chosen, then the file must hold exactly one solid (or `solid_name` chooses).
  int solid_index = -1;
  /// Or choose by name: the STEP product name (FreeCAD: the object's label) or the
  /// solid entity's name. Empty: none chosen.
  std::string solid_name;
  /// Accept a file without solids (faces, shells: a surface to take sections of). The part
  /// then holds all faces and is not checked for closedness; solids are still preferred.
  bool surfaces_allowed = false;
  /// Also refuse a solid whose faces intersect each other or themselves (OCCT's Boolean
  /// checker, BRepAlgoAPI_Check: BRepCheck does not see a bow-tie face that STEP healing made
  /// well-formed). Costs up to ~1 s on a part of hundreds of faces: `parafab inspect` runs it.
  bool check_self_intersection = false;
};

/// Reads a STEP (.step/.stp) or BREP (.brep/.brp) file; the format comes from the content
/// (ISO-10303-21 header, or "CASCADE Topology"). Throws parafab::Error naming the file and the
/// problem: missing, empty, not STEP/BREP, unreadable, no solid, several solids and none
/// chosen, open shell, non-manifold edge, or a failed BRepCheck (with the face/edge index).
std::shared_ptr<const PartShape> read_part(const std::string& path, const ReadOptions& options = {});

/// Same for the text of a BREP file, e.g. FreeCAD's `Shape.exportBrepToString()`.
std::shared_ptr<const PartShape> read_part_from_brep_string(const std::string& brep,
                                                            const ReadOptions& options = {});

/// The part rotated by `degrees` about the axis through `center` with direction `axis` (for
/// studies of a part at several orientations inside a fixed grid). Faces keep their indices.
std::shared_ptr<const PartShape> rotated_part(const PartShape& part, const Eigen::Vector3d& center,
                                              const Eigen::Vector3d& axis, double degrees);

/// The part moved by `offset` (every point X goes to X + offset), geometry copied (not a
/// TopLoc_Location); faces, edges and vertices keep their indices. Entries compute on a part
/// far from the origin in a frame near its box (local_frame.h): coordinates of 1e7 leave ~1e-9
/// absolute resolution, above the quadrature's tolerances.
std::shared_ptr<const PartShape> translated_part(const PartShape& part, const Eigen::Vector3d& offset);

/// Global facts about a part (units: those of the file, mm for STEP).
struct PartInfo {
  std::string source, name;
  int solid_index = 0, solid_count = 1;
  int face_count = 0, edge_count = 0, vertex_count = 0;
  Eigen::Vector3d bbox_min = Eigen::Vector3d::Zero(), bbox_max = Eigen::Vector3d::Zero();
  double volume = 0, area = 0;
};

PartInfo part_info(const PartShape& part);

/// What an estimate needs, cheaper than part_info (~2 ms against ~12 ms on the L-bracket): the
/// tight bounding box (BRepBndLib::AddOptimal, as in PartInfo) and the surface area and volume by
/// OCCT's fixed Gauss rules (no adaptive error control: ~1e-5 relative on B-spline faces).
struct PartBoxArea {
  Eigen::Vector3d min = Eigen::Vector3d::Zero(), max = Eigen::Vector3d::Zero();
  double area = 0;
  double volume = 0;
};
PartBoxArea part_box_and_area(const PartShape& part);

/// The tight bounding box alone (PartInfo's bbox_min / bbox_max, without its adaptive volume and
/// area integrals: those cost ~0.4 s on the 646-face bridge sample, and five callers that need
/// only the part's size called part_info once per run each).
struct PartBox {
  Eigen::Vector3d min = Eigen::Vector3d::Zero(), max = Eigen::Vector3d::Zero();
  double diagonal() const { return (max - min).norm(); }
};
PartBox part_box(const PartShape& part);

/// What BRepCheck_Analyzer finds wrong with the part, naming the first failing face, edge,
/// vertex, wire or shell ("BRepCheck_SelfIntersectingWire on face 3"); "" when it is valid.
std::string check_failure_description(const PartShape& part);

}  // namespace parafab::occ
