// Space (3D) B-spline and NURBS curves for the rod entry points: a curve as FreeCAD gives it
// (Part.BSplineCurve, possibly rational) or the interpolant of points (chord-length
// parameters in R³, averaged knots; Piegl & Tiller §9.2.1), and the SpaceCurve over it.
// Evaluation reuses the plane BSplineCurve2: a NURBS coordinate depends only on its own pole
// coordinate and the shared weights, so (x, y) and (z, 0) curves with the same degree, knots
// and weights evaluate the space curve exactly.
#pragma once

#include <array>
#include <vector>

#include "common/bspline.h"
#include "rods/space_curve.h"

namespace parafab {

class BSplineCurve3 {
 public:
  /// Validates like BSplineCurve2 (errors name curve.bspline.<field>[i]).
  BSplineCurve3(int degree, std::vector<double> knots, std::vector<Vec3> poles,
                std::vector<double> weights = {});

  int degree() const { return xy_.degree(); }
  const std::vector<double>& knots() const { return xy_.knots(); }
  const std::vector<Vec3>& poles() const { return poles_; }
  const std::vector<double>& weights() const { return xy_.weights(); }
  bool rational() const { return xy_.rational(); }
  double first_parameter() const { return xy_.first_parameter(); }
  double last_parameter() const { return xy_.last_parameter(); }

  /// Position and derivatives d^k/du^k, k = 0..3 (zero beyond the degree).
  std::array<Vec3, 4> derivatives(double u) const;
  Vec3 point(double u) const { return derivatives(u)[0]; }

  /// The regular curve over [first, last] (throws parafab::Error at zero speed).
  SpaceCurve space_curve(int table_intervals = 1024) const;

 private:
  static std::vector<Vec2> split(const std::vector<Vec3>& p, bool xy);
  std::vector<Vec3> poles_;
  BSplineCurve2 xy_, z_;
};

/// Interpolates `points` (≥ 2, consecutive points distinct, finite) by a non-rational
/// B-spline of `degree` (lowered to points.size() − 1). Errors name curve.points[i].
BSplineCurve3 interpolate_points3(const std::vector<Vec3>& points, int degree = 3);

}  // namespace parafab
