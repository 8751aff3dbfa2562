// Quadrature rule containers and Gauss–Legendre rules on [0, 1] (thesis §6.3.1: "a standard
// Gauss–Legendre rule"; §6.3.2–6.3.3: tensor Gauss points; tensor rules for uncut cells).
#pragma once

#include <vector>

#include "xfem/cut_geometry.h"

namespace parafab::xfem {

/// Σ_j weights[j] g(points[j]) ≈ ∫ g.
struct QuadratureRule1 {
  std::vector<double> points;
  std::vector<double> weights;
};
struct QuadratureRule2 {
  std::vector<Vec2> points;
  std::vector<double> weights;
};
struct QuadratureRule3 {
  std::vector<Vec3> points;
  std::vector<double> weights;
};

/// Outcome of a rule construction (moment-fitted rules and their refinement).
enum class RuleStatus {
  Ok,
  /// Zero measure (degenerate bounding box, |measure| at round-off): empty rule.
  EmptyDomain,
  /// Measure < 0: loops clockwise or patch orientations reversed; the rule is returned.
  NegativeMeasure,
  /// Moment equations violated beyond tolerance (NNLS without an exact non-negative fit).
  ResidualAboveTolerance,
  /// Adaptive refinement stopped at max_depth above its tolerance; the rule is returned.
  NotConverged
};
const char* to_string(RuleStatus status);
/// The more serious of two statuses of non-empty rules (NegativeMeasure >
/// ResidualAboveTolerance > NotConverged > Ok); EmptyDomain ranks as Ok.
RuleStatus worse_status(RuleStatus a, RuleStatus b);

/// Largest supported number of Gauss–Legendre points.
constexpr int kMaxGaussPoints = 64;

/// n-point Gauss–Legendre rule on [0, 1] (ascending points, exact for degree 2n − 1).
/// All rules are computed once (Newton on P_n) at first use; thread-safe.
/// Throws parafab::Error unless 1 ≤ n ≤ kMaxGaussPoints.
const QuadratureRule1& gauss_legendre(int n);

/// Tensor Gauss rule with n points per direction on the box [lo, hi] (exact for
/// polynomials of degree ≤ 2n − 1 in each variable). Throws unless hi ≥ lo componentwise.
QuadratureRule2 tensor_gauss_rule(const Vec2& lo, const Vec2& hi, int n);
/// Same on a cell (uncut cells of the grid).
QuadratureRule3 tensor_gauss_rule(const Box3& box, int n);

}  // namespace parafab::xfem
