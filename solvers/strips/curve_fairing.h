// Curves from sections for strip design (thesis §4.8.2): "smoothed to remove high
// frequencies and approximated by quartic spline curves", then "spurious inflection points"
// removed. A least-squares B-spline fit with a fairness term ∫|γ''|² (end points interpolated,
// parameter correction by projection), and the removal of inflection pairs closer than a
// threshold by a local ∫|γ'''|² penalty on the lobe between them, raised until the pair is gone
// (γ''' ≈ (κ n)' penalizes curvature variation, so κ there tends to the linear blend of its
// same-signed neighbours and stops changing sign).
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "common/bspline.h"

namespace parafab {

struct FairFitOptions {
  int degree = 4;
  int poles = 16;               ///< uniform clamped knots
  double fairness = 1e-6;       ///< weight of ∫|γ''|² du against the mean squared distance (u ∈ [0, 1], lengths / chord)
  int parameter_corrections = 3;
};

struct FairFitResult {
  explicit FairFitResult(BSplineCurve2 c) : curve(std::move(c)) {}
  BSplineCurve2 curve;
  double max_error = 0;   ///< max distance of a data point from the curve (after projection)
  double rms_error = 0;
};

/// Throws parafab::Error for fewer points than poles, non-finite or repeated points.
FairFitResult fit_fair_bspline(const std::vector<Vec2>& points, const FairFitOptions& options = {});

struct SpuriousInflectionOptions {
  FairFitOptions fit;
  double min_separation = 0.08;  ///< inflections closer than this · length pair up as spurious
  /// An inflection closer than this · length to an end is spurious (0: keep them): a fit
  /// through noisy end points tends to hook there.
  double end_separation = 0.05;
  int max_rounds = 30;
  double growth = 8;             ///< factor on the local penalty per round
};

struct SpuriousInflectionResult {
  explicit SpuriousInflectionResult(BSplineCurve2 c) : curve(std::move(c)) {}
  BSplineCurve2 curve;
  int inflections_before = 0;    ///< of the plain fair fit
  int inflections = 0;           ///< after removal
  std::vector<double> inflection_s;  ///< arc lengths of the remaining inflections
  int rounds = 0;
  bool done = false;             ///< no pair closer than the threshold is left
  double max_error = 0;          ///< max distance of a data point from the final curve
  std::string message;
};

/// The fair fit of `points`, then local penalties until no two inflections are closer than
/// min_separation · length.
SpuriousInflectionResult fair_section_curve(const std::vector<Vec2>& points,
                                            const SpuriousInflectionOptions& options = {});

}  // namespace parafab
