// Robustness of a strip design against fabrication and material defects (thesis §4.7.2,
// Fig. 4.15): the designed strip is simulated with the stiffness range ±50 %, the weight
// ±50 %, the clamp angles ±10° and plastic zones in the top 25 % / 50 % of the curvature,
// and each deviation from the target is returned.
#pragma once

#include <string>
#include <vector>

#include "strips/strip_validation.h"

namespace parafab {

struct StripRobustnessOptions {
  double stiffness_change = 0.5;        ///< ± relative change of the stiffness range (K − 1)
  double gravity_change = 0.5;          ///< ± relative change of the weight
  double angle_change = 10 * M_PI / 180;  ///< ± at both clamps, opening (+) and closing (−)
  /// Plastic zones: the curvature limit is the quantile of |κ − κ₀| over the design's samples
  /// above which this fraction of them lies (thesis: top 25 % and 50 %).
  std::vector<double> plastic_fractions{0.25, 0.5};
  double plastic_hardening = 0.05;      ///< slope beyond the limit (0 is singular)
  StripValidationOptions validation;    ///< simulator settings (edges, tolerances)
};

struct StripRobustnessCase {
  std::string name;         ///< "baseline", "stiffness_range+50%", "gravity-50%", ...
  StripPerturbation perturbation;
  bool converged = false;
  double deviation = NAN;   ///< max distance to the target / length
  double max_distance = NAN;  ///< [m]
  std::string message;
  std::vector<Vec2> nodes;    ///< the simulated strip (edges + 1 nodes, uniform in arc length)
};

struct StripRobustness {
  std::vector<StripRobustnessCase> cases;  ///< baseline first
  double worst_deviation = 0;             ///< over converged cases
  std::string worst_case;
  double seconds = 0;
};

/// Throws parafab::Error if the design is not feasible. Gravity cases are included only
/// when the design options enable gravity.
StripRobustness strip_robustness_study(const BSplineCurve2& curve, const StripDesign& design,
                                       const StripDesignOptions& design_options,
                                       const StripRobustnessOptions& options = {});

}  // namespace parafab
