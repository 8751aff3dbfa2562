// Write-back of optimized shape parameters into the B-rep, topology unchanged (thesis §6.5.1:
// q = q(p⊥)): faces get the surfaces of their new parameters, edges and vertices are recomputed
// from the neighbouring surfaces (intersections; tangent edges from the relation's closed form)
// through OCCT's BRepTools_Modification mechanism (as BRepOffsetAPI_DraftAngle's
// Draft_Modification), then BRepCheck_Analyzer and a self-interference test decide whether the
// result is a valid solid.
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

struct ModifyOptions {
  /// Also reject a solid two of whose faces with no vertex in common cross or touch: a blind hole
  /// deepened through the far wall, a pocket grown into another. BRepCheck_Analyzer checks each
  /// face's own wires only. Only face pairs whose boxes overlap are measured (the exact distance);
  /// where one cannot be, the full test below runs. See bench_write_back for its cost.
  bool check_self_interference = true;
  /// The self-interference test on every pair of sub-shapes instead (BOPAlgo_ArgumentAnalyzer,
  /// the test before 2026-12-01: 1.9–2.6 times the write-back's own time on the samples and the
  /// 646-face bridge, against 1.0–1.3 for the face-pair test); a test that cannot finish rejects
  /// the part.
  bool full_self_interference = false;
};

/// The part with the faces of `parameters` set to p. `model` is the face model of `part`
/// (edge tangency, relations). Never throws for a geometric failure (done = false, message);
/// throws parafab::Error for a p of the wrong size.
ModifyResult modify_part(const PartShape& part, const FaceModel& model, const ShapeParameters& parameters,
                         const Eigen::VectorXd& p, const ModifyOptions& options = {});

/// Writes the part as STEP (AP214, mm). Throws parafab::Error naming the path on failure.
void write_step(const PartShape& part, const std::string& path);

}  // namespace parafab::occ
