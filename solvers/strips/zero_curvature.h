// Zero-curvature points of a plane curve (the set S0 of thesis Theorem 1, §4.3.2): roots of
// the signed curvature κ located on the continuous curve by bracketing and bisection, not by
// sign flips between samples alone, and classified (inflection, zero without sign change,
// straight pieces).
#pragma once

#include <vector>

#include "common/plane_curve.h"

namespace parafab {

struct ZeroCurvatureOptions {
  /// Scan points per knot span used to bracket roots and dips of |κ|; curves with more than
  /// 128 spans get fewer (about 8192 scan points in all, at least 16 per span).
  int scan_per_span = 64;
  /// |κ|·length below this counts as zero curvature.
  double zero_tolerance = 1e-9;
  /// κ₀ [1/m]: find the zeros of κ − κ₀ instead (rods with fixed natural curvature, thesis
  /// §4.3.3). The returned points then carry κ − κ₀ in `at.kappa`.
  double natural_curvature = 0.0;
};

enum class ZeroKind {
  Inflection,   ///< κ changes sign (interior point)
  AtEnd,        ///< κ vanishes at an end of the curve
  Touch         ///< κ reaches zero without changing sign (never secant-bounded)
};
const char* to_string(ZeroKind kind);

struct ZeroCurvaturePoint {
  CurvePoint at;
  ZeroKind kind = ZeroKind::Inflection;
};

struct ZeroCurvatureResult {
  std::vector<ZeroCurvaturePoint> points;  ///< sorted by arc length
  bool straight = false;                   ///< κ ≈ 0 on the whole curve (a line segment)
  bool flat_piece = false;                 ///< κ ≈ 0 on a sub-interval (S0 not finite)
  double flat_from_s = 0, flat_to_s = 0;   ///< that sub-interval, when flat_piece
  double kappa_scale = 0;                  ///< max |κ| over the scan
  std::vector<double> scan_parameters;     ///< the scan (reused for crossing checks)
  std::vector<double> scan_kappa;          ///< κ − κ₀ at the scan parameters
  double natural_curvature = 0;            ///< κ₀ of the options
};

ZeroCurvatureResult find_zero_curvature(const PlaneCurve& curve,
                                        const ZeroCurvatureOptions& options = {});

}  // namespace parafab
