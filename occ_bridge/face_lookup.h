// Face lookup for boundary conditions: the B-rep face nearest to a point (users name faces by
// index from `parafab inspect`, or by a point on them), and face areas (force → traction).
#pragma once

#include <memory>

#include "xfem/cut_geometry.h"

namespace parafab::occ {

struct PartShape;

/// Index of the face within `tolerance` of X (nearest one; of equally near faces the lowest
/// index). Throws parafab::Error naming the point and the distance to the nearest face if none
/// is that close. One query; for many on one part, FaceLocator.
int face_at_point(const PartShape& part, const xfem::Vec3& X, double tolerance);

/// face_at_point for many queries on one part (a job naming hundreds of faces by points: the
/// 160-hole bridge names 800). Each face's bounding box is built once; a query measures the
/// exact distance (BRepExtrema) only to faces whose box is no farther than the nearest face
/// found so far, nearest box first, so it measures a few faces instead of all. Same answer as
/// face_at_point. `part` must outlive the locator.
class FaceLocator {
 public:
  explicit FaceLocator(const PartShape& part);
  ~FaceLocator();
  FaceLocator(const FaceLocator&) = delete;
  FaceLocator& operator=(const FaceLocator&) = delete;
  int face_at(const xfem::Vec3& X, double tolerance) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

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
