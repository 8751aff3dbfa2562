// Face lookup for boundary conditions: the B-rep face nearest to a point (users name faces by
// index from `parafab inspect`, or by a point on them), and face areas (force → traction).
#pragma once

#include "xfem/cut_geometry.h"

namespace parafab::occ {

struct PartShape;

/// Index of the face within `tolerance` of X (nearest one). Throws parafab::Error naming the
/// point and the distance to the nearest face if none is that close.
int face_at_point(const PartShape& part, const xfem::Vec3& X, double tolerance);

/// Area of face `index`; throws parafab::Error for an index out of range.
double face_area(const PartShape& part, int index);

}  // namespace parafab::occ
