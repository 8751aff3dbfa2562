// Plane (2D) B-spline and NURBS curves: evaluation with derivatives up to order 3, and
// interpolation of points (chord-length parameters, averaged knots; Piegl & Tiller §9.2.1).
#pragma once

#include <Eigen/Core>
#include <array>
#include <vector>

namespace parafab {

using Vec2 = Eigen::Vector2d;

/// A (possibly rational) B-spline curve in the plane. Knots are the full (clamped or not)
/// knot vector with repeated entries; weights are empty for a non-rational curve.
class BSplineCurve2 {
 public:
  /// Validates the data (sizes, monotone knots, finite values, positive weights) and
  /// throws parafab::Error naming the offending entry.
  BSplineCurve2(int degree, std::vector<double> knots, std::vector<Vec2> poles,
                std::vector<double> weights = {});

  int degree() const { return degree_; }
  const std::vector<double>& knots() const { return knots_; }
  const std::vector<Vec2>& poles() const { return poles_; }
  const std::vector<double>& weights() const { return weights_; }
  bool rational() const { return !weights_.empty(); }

  double first_parameter() const { return knots_[degree_]; }
  double last_parameter() const { return knots_[knots_.size() - degree_ - 1]; }
  /// Distinct knot values inside [first, last] (span boundaries, where the curve may lose
  /// smoothness).
  std::vector<double> breakpoints() const;

  /// Position and derivatives d^k/du^k for k = 0..3 (zero beyond the degree).
  std::array<Vec2, 4> derivatives(double u) const { return derivatives(u, 3); }
  /// The same up to order `order` ≤ 3 only (entries beyond it are not meaningful): cheaper.
  std::array<Vec2, 4> derivatives(double u, int order) const;
  Vec2 point(double u) const { return derivatives(u, 0)[0]; }

 private:
  int find_span(double u) const;
  int degree_;
  std::vector<double> knots_;
  std::vector<Vec2> poles_;
  std::vector<double> weights_;
};

/// Interpolation of points of any dimension (one per row of `points`, at least 2, consecutive
/// points distinct) by a non-rational B-spline of the given degree (lowered to rows − 1 if
/// needed): chord-length parameters, averaged knots, a banded collocation solve (Piegl &
/// Tiller §9.2.1). Throws parafab::Error naming the offending point index (as
/// "curve.points[i]") for NaN/inf or repeated points.
struct InterpolatedBSpline {
  int degree = 0;
  std::vector<double> knots;
  Eigen::MatrixXd poles;  ///< one pole per row
};
InterpolatedBSpline interpolate_rows(const Eigen::MatrixXd& points, int degree);

/// interpolate_rows for plane points.
BSplineCurve2 interpolate_points(const std::vector<Vec2>& points, int degree);

}  // namespace parafab
