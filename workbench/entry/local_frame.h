// The frame integrate and simulate compute in (issue 56): a part far from the origin is moved
// near it once, after reading, and user points and reported positions are shifted at the
// entry's boundary. Coordinates of 1e7 mm leave doubles ~2e-9 mm of resolution, of the order of
// the quadrature's tolerances on a 1 mm cell (the flux refinement of volume_rule then never
// converged and ran to its depth cap on every patch), and ∫XXᵀ − V c cᵀ loses the inertia.
#pragma once

#include <Eigen/Core>
#include <cmath>

namespace parafab::entry {

/// Where the local frame's origin lies in the part's own frame: the box centre rounded to a
/// multiple of the power of two s ≥ the box diagonal. Local coordinates then stay within about
/// 1.5 diagonals of 0; X − origin is exact in floating point (both are multiples of X's ulp and
/// the difference is below 2 s), so the local part is the file's geometry exactly, and the same
/// part moved by any multiple of s has bit-identical local geometry. Along an axis where the box
/// centre lies within s / 2 of 0 the origin coordinate is 0: the samples, drawn at the origin,
/// are not moved at all and compute exactly as before.
inline Eigen::Vector3d local_frame_origin(const Eigen::Vector3d& box_min, const Eigen::Vector3d& box_max) {
  const double diagonal = (box_max - box_min).norm();
  if (!(diagonal > 0) || !std::isfinite(diagonal)) return Eigen::Vector3d::Zero();
  const double step = std::exp2(std::ceil(std::log2(diagonal)));
  Eigen::Vector3d origin;
  for (int a = 0; a < 3; ++a) origin[a] = step * std::nearbyint(0.5 * (box_min[a] + box_max[a]) / step);
  return origin;
}

}  // namespace parafab::entry
