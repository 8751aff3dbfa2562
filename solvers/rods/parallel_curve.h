// Generator of parallel (twist-free) equilibrium curves (thesis §5.6.2, Prop. 8): the ODE
// γ'' = m(s)·(c×γ + c̄)×γ' (Eq. 5.14) with m = κ(s)/‖c×γ + c̄‖ for a user curvature κ(s) > 0,
// and the normalized constants and initial values of Eq. 5.15: c = e3, c̄ = p·e3,
// γ(0) = r·e1, γ'(0) = Q_α e1 (rotation by α about r·e2 + p·e3). Integrated with SUNDIALS
// CVODE (BDF, Newton with dense difference-quotient Jacobian).
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "rods/space_curve.h"

namespace parafab {

struct ParallelCurveOptions {
  double p = 0.5;      ///< c̄ = p·e3 [m] (pitch of the helical motion)
  double r = 0.5;      ///< γ(0) = r·e1 [m], r > 0
  double alpha = 0;    ///< α [rad]: initial tangent direction
  double relative_tolerance = 1e-10;
  double absolute_tolerance = 1e-12;  ///< [m]
};

enum class ParallelCurveStatus { Ok, IntegrationFailed };

struct ParallelCurveResult {
  ParallelCurveStatus status = ParallelCurveStatus::IntegrationFailed;
  std::vector<RodSample> samples;  ///< at the requested arc lengths (Frénet data)
  Vec3 c{0, 0, 1}, c_bar{0, 0, 0};
  long steps = 0;                  ///< CVODE steps
  double seconds = 0;
  std::string message;
  bool ok() const { return status == ParallelCurveStatus::Ok; }
};

/// Integrates on [0, length] and returns samples at `count` ≥ 2 equally spaced arc lengths.
/// κ must be positive and finite on [0, length] (else parafab::Error naming s); r must be
/// > 0 and r, p not both 0. Torsion uses a central difference of κ for κ'.
ParallelCurveResult generate_parallel_curve(const std::function<double(double)>& kappa,
                                            double length, int count,
                                            const ParallelCurveOptions& options = {});

}  // namespace parafab
