// Plane (2D) B-spline and NURBS curves: evaluation with derivatives up to order 3 (from
// per-span Taylor forms), and interpolation of points (chord-length parameters, averaged
// knots; Piegl & Tiller §9.2.1).
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

  /// Position and derivatives d^k/du^k for k = 0..3 (zero beyond the degree). Summed from the
  /// span's Taylor form (below): equal to the textbook recursion's to ~3e-14 of each
  /// derivative's size (BSplineCurve2.TaylorFormsMatchTheTextbookRecursionForEveryDegree).
  std::array<Vec2, 4> derivatives(double u) const { return derivatives(u, 3); }
  /// The same up to order `order` ≤ 3 only (entries beyond it are not meaningful): cheaper.
  std::array<Vec2, 4> derivatives(double u, int order) const;
  Vec2 point(double u) const { return derivatives(u, 0)[0]; }

  // ---- Control points as variables (thesis §4.5.4, App. A.4).
  int pole_count() const { return static_cast<int>(poles_.size()); }
  /// Replaces the poles (same count, finite; throws parafab::Error naming the entry).
  void set_poles(std::vector<Vec2> poles);
  /// Basis functions at u: N[k][j] = d^k/du^k N_{first + j}(u) for j = 0..degree, k = 0..3.
  /// For a non-rational curve C^(k)(u) = Σ_j N[k][j] · poles[first + j], so ∂C^(k)/∂P_i is
  /// N[k][i − first] times the identity (zero for poles outside first..first + degree).
  struct Basis {
    int first = 0;
    std::array<std::array<double, 8>, 4> N{};
  };
  Basis basis(double u) const;

 private:
  int find_span(double u) const;
  /// Every span's polynomial (the numerator Σ N w P and the denominator Σ N w of a rational
  /// curve) as its derivatives at the span's midpoint, from Cox–de Boor (Piegl & Tiller A2.3)
  /// once per span: an evaluation is then a Horner sum instead of the basis recursion and its
  /// divisions (the strip solvers evaluate a curve ~30,000 times per design).
  struct SpanTaylor {
    double center = 0;
    std::array<Vec2, 8> A{};       ///< d^k/du^k of Σ N w P (of C for a non-rational curve)
    std::array<double, 8> W{};     ///< d^k/du^k of Σ N w (rational curves only)
  };
  void build_taylor_forms();
  /// find_span's index: span_of_bucket_[b] is the span holding the start of bucket b of
  /// [first, last] cut into equal buckets (two per span on average), so a lookup is a
  /// multiply and a short scan instead of a binary search over the knots.
  void build_span_index();
  int degree_;
  std::vector<double> knots_;
  std::vector<Vec2> poles_;
  std::vector<double> weights_;
  std::vector<SpanTaylor> taylor_;  ///< index span − degree (empty spans left zero)
  std::vector<int> span_of_bucket_;
  double bucket_scale_ = 0;         ///< buckets per unit of u
  int first_span_ = 0, last_span_ = 0;  ///< the first and last non-empty spans
};

/// A point of a non-rational plane B-spline and the exact derivatives of its geometry with
/// respect to the poles it depends on (poles first .. first + degree): index j in the
/// arrays is pole first + j; a gradient entry is the 2-vector (∂/∂P.x, ∂/∂P.y). Thesis App.
/// A.4 uses these for the inflection constraint and §4.6.2 for dR/dP.
struct PoleJet {
  double u = 0;
  BSplineCurve2::Basis basis;
  std::array<Vec2, 4> d;    ///< C, C', C'', C''' (parameter derivatives)
  double speed = 0;         ///< |C'|
  Vec2 tangent{1, 0};       ///< C'/|C'|
  double kappa = 0;         ///< det(C', C'') / |C'|³
  double dkappa_du = 0;     ///< dκ/du
  double dkappa_ds = 0;     ///< dκ/ds = κ_u / |C'|
  int count = 0;            ///< degree + 1
  std::array<Eigen::Matrix2d, 8> dtangent;  ///< ∂t/∂P_j: column c is ∂t/∂P_j[c]
  std::array<Vec2, 8> dspeed;               ///< ∂|C'|/∂P_j
  std::array<Vec2, 8> dkappa;               ///< ∂κ/∂P_j
  std::array<Vec2, 8> ddkappa_ds;           ///< ∂(dκ/ds)/∂P_j
  /// ∂C/∂P_j = N[0][j]·I (the point is linear in the poles).
  double dpoint(int j) const { return basis.N[0][j]; }
};
/// Throws parafab::Error for a rational curve (weights make C non-linear in the poles) or a
/// zero speed at u.
PoleJet pole_jet(const BSplineCurve2& curve, double u);

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
