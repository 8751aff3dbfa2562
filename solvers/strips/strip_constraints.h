// Control points of a plane B-spline as optimization variables on the manifold of equilibrium
// curves: EnforceConstraints of thesis Appendix A.4 (inflections on a fixed line L, end points
// and end tangents fixed, arc length fixed) by an underdetermined (minimum-norm) Newton
// iteration, the tangent space T_qM of §4.5.4, the p-norm approximation of R = sup K / inf K
// (§4.5.4 "Remarks", p > 20) and ProjectStep of Algorithm 4.2 line 10.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "common/bspline.h"

namespace parafab {

struct StripConstraintOptions {
  bool fix_end_points = true;     ///< γ(0) = γ₀, γ(l) = γ_l (4 linear rows)
  bool fix_end_tangents = true;   ///< ⟨γ'(0), n₀⟩ = 0 = ⟨γ'(l), n_l⟩ (2 linear rows)
  bool fix_length = true;         ///< l(q) = l₀ (Gauss–Legendre quadrature of |γ'|, 1 row)
  bool inflections_on_line = true;  ///< a + ⟨b, γ(t₀(q))⟩ = 0 per tracked inflection
  /// Newton stops when max |G| ≤ tolerance · l₀ (every row is in length units).
  double tolerance = 1e-13;
  int max_iterations = 25;
  /// Gauss–Legendre 8-point sub-intervals per knot span for the length row.
  int length_intervals_per_span = 2;
};

struct EnforceResult {
  bool converged = false;
  int iterations = 0;
  double residual = 0;   ///< max |G| after the last iteration [length units]
  double move = 0;       ///< |q − q₀| (Euclidean over all pole coordinates)
  std::string message;
};

/// The inflections of a non-rational plane B-spline: parameters where det(γ', γ'') changes
/// sign, found by a scan (`scan_per_span` points per knot span) and Newton/bisection.
std::vector<double> inflection_parameters(const BSplineCurve2& curve, int scan_per_span = 32);

/// Constraints G(q) = 0 of App. A.4 recorded from a reference curve (end points, end normals,
/// length) and the line L: a + ⟨b, x⟩ = 0 ((a, b) are rescaled to |b| = 1).
class StripConstraints {
 public:
  StripConstraints(const BSplineCurve2& reference, double a, const Vec2& b,
                   std::vector<double> inflection_u, const StripConstraintOptions& options = {});

  int rows() const;
  double a() const { return a_; }
  const Vec2& b() const { return b_; }
  double length() const { return length_; }
  /// Tracked inflection parameters (updated by evaluate / enforce).
  const std::vector<double>& inflections() const { return infl_; }
  /// Moves the line L (e.g. after the global LP step with one inflection).
  void set_line(double a, const Vec2& b);

  /// G(q) and its Jacobian J (rows × 2m, columns x₀, y₀, x₁, ...) at the curve's poles;
  /// the inflection parameters are re-tracked by Newton on det(γ', γ'') from their last
  /// values. Returns false (message set) if an inflection cannot be tracked.
  bool evaluate(const BSplineCurve2& curve, Eigen::VectorXd& G, Eigen::MatrixXd& J,
                std::string* message = nullptr);
  /// q ← q + Δq with Δq the least-norm solution of J Δq = −G, until max |G| ≤ tol·l₀.
  EnforceResult enforce(BSplineCurve2& curve);
  /// Orthogonal projection of a pole-space vector onto T_qM = ker J(q).
  Eigen::VectorXd project_to_tangent(const BSplineCurve2& curve, const Eigen::VectorXd& v);
  /// An orthonormal basis of T_qM (2m × (2m − rank J)), the explicit basis of §4.5.4.
  Eigen::MatrixXd tangent_basis(const BSplineCurve2& curve);

 private:
  StripConstraintOptions o_;
  double a_ = 0;
  Vec2 b_{0, 1};
  Vec2 p0_, p1_, n0_, n1_;
  double speed0_ = 1, speed1_ = 1, length_ = 0;
  std::vector<double> infl_;
  std::vector<double> quad_u_, quad_w_;
};

/// Flattened poles (x₀, y₀, x₁, y₁, ...) and back.
Eigen::VectorXd poles_vector(const BSplineCurve2& curve);
void set_poles_vector(BSplineCurve2& curve, const Eigen::VectorXd& q);

/// R_p = ‖K‖_p · ‖1/K‖_p (mean-normalized, so R_p ≤ max K / min K) over samples at fixed
/// parameters, K = (a + ⟨b, γ⟩)/κ, with its exact gradient with respect to the poles.
struct PNormRatio {
  bool valid = false;     ///< every sample has K > 0
  double value = NAN;     ///< R_p
  double R = NAN;         ///< max K / min K over the same samples
  double K_min = NAN, K_max = NAN;
  Eigen::VectorXd gradient;  ///< ∂R_p/∂q (2m)
};
/// Samples with |κ|·l below `skip_kappa` (0/0 at an inflection) are left out.
PNormRatio pnorm_ratio(const BSplineCurve2& curve, double a, const Vec2& b,
                       const std::vector<double>& sample_u, double p, double length,
                       double skip_kappa = 1e-7);

/// ProjectStep of Algorithm 4.2: if R + ⟨∇R, Δq⟩ > R_max, remove the component along ∇R so
/// the bound holds to first order (∇R should already lie in T_qM, then so does the result).
Eigen::VectorXd project_step(const Eigen::VectorXd& dq, double R, const Eigen::VectorXd& grad_R,
                             double R_max);

}  // namespace parafab
