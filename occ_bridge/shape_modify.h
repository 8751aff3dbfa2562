// Write-back of optimized shape parameters into the B-rep, topology unchanged (thesis §6.5.1:
// q = q(p⊥)): faces get the surfaces of their new parameters, edges and vertices are recomputed
// from the neighbouring surfaces (intersections; tangent edges from the relation's closed form)
// through OCCT's BRepTools_Modification mechanism (as BRepOffsetAPI_DraftAngle's
// Draft_Modification), then BRepCheck_Analyzer decides whether the result is a valid solid.
#pragma once

#include <Eigen/Core>
#include <memory>
#include <string>

#include "face_model.h"
#include "shape_parameters.h"

namespace parafab::occ {

struct PartShape;

struct ModifyResult {
  bool done = false;        ///< a valid solid with the same numbers of faces, edges and vertices
  std::string message;      ///< what failed (edge/vertex/face index), or "ok"
  std::shared_ptr<const PartShape> part;  ///< the modified part (null when not done)
  int modified_faces = 0;
  double seconds = 0;
};

/// The part with the faces of `parameters` set to p. `model` is the face model of `part`
/// (edge tangency, relations). Never throws for a geometric failure (done = false, message);
/// throws parafab::Error for a p of the wrong size.
ModifyResult modify_part(const PartShape& part, const FaceModel& model, const ShapeParameters& parameters,
                         const Eigen::VectorXd& p);

/// Writes the part as STEP (AP214, mm). Throws parafab::Error naming the path on failure.
void write_step(const PartShape& part, const std::string& path);

}  // namespace parafab::occ
