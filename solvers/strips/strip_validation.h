// Validation of a strip design by forward simulation (thesis §4.6.1, §4.7.2): the designed
// stiffness profile, clamped (or freed) like the design assumed, under the same gravity and
// material law, is simulated with the plane rod simulator and compared with the target curve.
// Perturbations of the fabrication (Fig. 4.15) are options of the same function.
#pragma once

#include <string>

#include "strips/plane_rod_simulator.h"
#include "strips/strip_design.h"

namespace parafab {

/// Defects applied to the simulated strip, not to the design (defaults: none).
struct StripPerturbation {
  /// K ↦ 1 + scale (K − 1) (K normalized to min 1): the max/min ratio R becomes
  /// 1 + scale (R − 1); 1.5 / 0.5 = the stiffness range 50 % higher / lower than designed.
  double stiffness_ratio_scale = 1.0;
  double gravity_scale = 1.0;  ///< the weight (ρ/(E h²)) times this
  double start_angle_offset = 0.0, end_angle_offset = 0.0;  ///< added to the clamp angles [rad]
  /// Plasticity of the simulated strip: curvature limit and hardening of its moment law
  /// (replacing those of the design's law when the limit is finite).
  double curvature_limit = INFINITY;
  double plastic_hardening = 0.05;
};

struct StripValidationOptions {
  PlaneRodOptions rod{800};
  StripPerturbation perturbation;
};

struct StripValidation {
  bool converged = false;
  double deviation = NAN;     ///< max_k |x_k − γ(s_k)| / length (same arc length)
  double max_distance = NAN;  ///< max_k |x_k − γ(s_k)| [m]
  double worst_s = 0;         ///< arc length where it occurs
  int iterations = 0;
  int load_steps = 0;
  double seconds = 0;
  std::string message;
  PlaneRodResult simulation;
};

/// Throws parafab::Error if the design is not feasible.
StripValidation validate_strip(const BSplineCurve2& curve, const StripDesign& design,
                               const StripDesignOptions& design_options,
                               const StripValidationOptions& options = {});

}  // namespace parafab
