// Theorem 1 of thesis §4.3.2 as a diagnosis: a plane curve is an equilibrium curve of a
// straight rod with admissible stiffness iff a line meets it exactly in its zero-curvature
// points, is not tangent there, and κ is secant-bounded at every such point.
#pragma once

#include <string>
#include <vector>

#include "strips/zero_curvature.h"

namespace parafab {

enum class Infeasibility {
  None,
  FlatPiece,               ///< κ ≡ 0 on a sub-interval: S0 is not finite
  NotSecantBounded,        ///< κ' ≈ 0 at a zero, or κ = 0 without a sign change
  NotCollinear,            ///< zero-curvature points do not lie on one line
  LineTangentAtInflection, ///< the inflection line is tangent to the curve at a zero
  LineCrossesCurve,        ///< the inflection line meets the curve at a non-inflection point
  NoLineAvoidsCurve        ///< no line through the zero(s) avoids the curve (LP infeasible)
};
/// Stable snake_case code used in JSON ("not_collinear", ...); "" for None.
const char* to_code(Infeasibility reason);

struct EquilibriumCheckOptions {
  double collinear_tolerance = 1e-6;   ///< max distance from the line / length
  double tangent_tolerance = 1e-6;     ///< |sin(angle between line and tangent)|
  double secant_tolerance = 1e-6;      ///< |κ'|·length / max|κ| below this counts as zero
  /// An end of the curve that lies on the inflection line (within collinear_tolerance, or within
  /// this times the length) and has |κ − κ₀| up to this times max |κ − κ₀| is a zero at the
  /// end (kind end), e.g. a curve given as points whose curvature vanishes at the end up to
  /// the interpolation error.
  double end_zero_tolerance = 1e-3;
};

struct EquilibriumCheck {
  Infeasibility reason = Infeasibility::None;
  std::string message;        ///< human-readable reason with location; "" when feasible
  double where_s = -1;        ///< arc length of the offending point (−1 if not local)
  bool line_known = false;    ///< the zeros fix the line (two or more)
  Vec2 line_point{0, 0};      ///< a point on the inflection line
  Vec2 line_direction{1, 0};  ///< its unit direction
  double collinearity_error = 0;  ///< max distance of a zero from that line
  /// Ends on the line with (nearly) vanishing curvature that the zero finder did not list:
  /// zeros at the ends (ZeroKind::AtEnd) the caller adds to its zeros.
  std::vector<ZeroCurvaturePoint> end_zeros;
  bool feasible() const { return reason == Infeasibility::None; }
};

/// Checks every condition of Theorem 1 that does not need the LP. Curves with zero or one
/// zero-curvature point pass here and are decided by the LP (Eq. 4.4).
EquilibriumCheck check_equilibrium(const PlaneCurve& curve, const ZeroCurvatureResult& zeros,
                                   const EquilibriumCheckOptions& options = {});

}  // namespace parafab
