// Face lookup for boundary conditions: the B-rep face nearest to a point (users name faces by
// index from `parafab inspect`, or by a point on them), and face areas (force → traction).
#pragma once

#include <memory>

#include "xfem/cut_geometry.h"

namespace parafab::occ {

struct PartShape;

/// Index of the face within `tolerance` of X (nearest one). Throws parafab::Error naming the
/// point and the distance to the nearest face if none is that close.
int face_at_point(const PartShape& part, const xfem::Vec3& X, double tolerance);

/// Area of face `index`; throws parafab::Error for an index out of range.
double face_area(const PartShape& part, int index);

/// Which points belong to the material: inside the solid or on its boundary within
/// `tolerance` (OCCT's BRepClass3d_SolidClassifier, loaded once). Results reported from points
/// (largest displacement and stress) use it to skip quadrature points of cut cells that lie in
/// the fitting box but outside the part.
class PointClassifier {
 public:
  PointClassifier(const PartShape& part, double tolerance);
  ~PointClassifier();
  bool in_material(const xfem::Vec3& X) const;
  enum class State { In, Out, On };
  State state(const xfem::Vec3& X) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace parafab::occ
