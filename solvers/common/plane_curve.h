// Arc-length geometry of a plane B-spline curve (thesis §3.1.1): arc length, its inverse,
// signed curvature κ = det(γ', γ'') / |γ'|³ and dκ/ds on the continuous curve.
#pragma once

#include <vector>

#include "common/bspline.h"

namespace parafab {

/// Everything the strip solvers need to know about the curve at one parameter.
struct CurvePoint {
  double u = 0;          ///< curve parameter
  double s = 0;          ///< arc length from the start
  Vec2 point{0, 0};      ///< γ(s)
  Vec2 tangent{1, 0};    ///< unit tangent γ'(s)
  double kappa = 0;      ///< signed curvature κ(s)
  double dkappa_ds = 0;  ///< κ'(s)
};

/// A plane curve with an arc-length table. The table uses Gauss–Legendre quadrature on
/// sub-intervals of every knot span, so s(u) is exact to round-off for polynomial speeds
/// and to ~1e-14 relative for smooth rational ones.
class PlaneCurve {
 public:
  /// Throws parafab::Error if the parametrization is singular (zero speed) somewhere.
  explicit PlaneCurve(BSplineCurve2 curve);

  const BSplineCurve2& bspline() const { return curve_; }
  double length() const { return table_s_.back(); }
  double first_parameter() const { return curve_.first_parameter(); }
  double last_parameter() const { return curve_.last_parameter(); }

  double arc_length_at(double u) const;
  /// Arc length at every breakpoint of the B-spline (from the table, no integration).
  const std::vector<double>& breakpoint_arc_lengths() const { return breakpoint_s_; }
  /// Parameter u with arc_length_at(u) == s (safeguarded Newton), s clamped to [0, length].
  double parameter_at(double s) const;
  CurvePoint at_parameter(double u) const;
  /// at_parameter without the arc length (s = NaN): point, tangent, κ, κ′ only (cheaper).
  CurvePoint geometry_at(double u) const;
  CurvePoint at_arc_length(double s) const;
  double curvature_at(double u) const;

 private:
  double speed(double u) const;
  double integrate_speed(double u0, double u1) const;
  BSplineCurve2 curve_;
  std::vector<double> table_u_, table_s_, table_v_;  // table_v_: speed |γ'(u)| at the nodes
  std::vector<double> breakpoint_s_;
};

}  // namespace parafab
