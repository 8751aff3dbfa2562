// Optimal stiffness profile of a plane equilibrium curve: the linear program of thesis
// Eq. 4.4 (§4.3.4), minimize R subject to 1 ≤ (a + ⟨b, γ(s_i)⟩)/κ(s_i) ≤ R and
// a + ⟨b, γ(s_j)⟩ = 0 at the zero-curvature points, solved through its dual (4 rows).
#pragma once

#include <vector>

#include "common/few_variable_lp.h"
#include "common/plane_curve.h"

namespace parafab {

struct StiffnessLpOptions {
  LpForm form = LpForm::Dense;
  /// Warm start (dual form): rows active at the optimum of a similar LP, as
  /// StiffnessLpResult::active_samples / active_other of an earlier call (samples matched by s;
  /// the zeros' and line rows by their index). Empty: a cold start.
  std::vector<std::pair<double, int>> warm_samples;
  std::vector<int> warm_other;
};

struct StiffnessLpResult {
  LpStatus status = LpStatus::Failed;
  double a = 0;               ///< K(s) = (a + ⟨b, γ(s)⟩) / κ(s) with min over samples = 1
  Vec2 b{0, 0};
  double R = 0;               ///< max K / min K of the line over the samples and the zeros
  double objective = 0;       ///< the LP variable R (≥ R by at most the solver tolerance)
  int rows = 0;               ///< inequality rows of the primal program
  int iterations = 0;
  /// Rows whose dual columns are basic at the optimum: samples as (s, 0 for K ≥ 1 / 1 for
  /// K ≤ R), the zeros' rows and the line rows as their column index after the samples'.
  std::vector<std::pair<double, int>> active_samples;
  std::vector<int> active_other;
  double seconds = 0;
  double max_violation = 0;   ///< of the normalized program
  std::string message;
  /// LP multipliers (dR/dP, strips/strip_improve): rows of sample i are 2i (K ≥ 1) and
  /// 2i + 1 (K ≤ R), then the zeros likewise; `dual_line` per line point. The rows are
  /// written in x̂ = (â, b̂, R) with γ̂ = (γ − center)/scale, κ̂ = κ·scale, κ̂' = κ'·scale².
  Eigen::VectorXd dual_rows, dual_line;
  Vec2 center{0, 0};
  double scale = 1;
  Eigen::Vector3d normalized_line{0, 0, 0};  ///< (â, b̂₁, b̂₂)
  bool ok() const { return status == LpStatus::Optimal; }
};

/// `samples` must have κ ≠ 0. The line a + ⟨b, x⟩ = 0 must pass through every point of
/// `line_points` (the zero-curvature points themselves, or two points of the line fitted
/// through three or more nearly collinear ones). At each zero-curvature point the limit
/// K = ⟨b, γ'⟩ / κ' (l'Hôpital) is bounded like a sample. `length` sets the scale used to
/// normalize coordinates for the solver (results are in input units).
StiffnessLpResult solve_stiffness_lp(const std::vector<CurvePoint>& samples,
                                     const std::vector<CurvePoint>& zeros,
                                     const std::vector<Vec2>& line_points, double length,
                                     const StiffnessLpOptions& options = {});

/// K at a point: the ratio at a sample, or the l'Hôpital limit at a zero-curvature point.
double stiffness_at(const CurvePoint& p, double a, const Vec2& b, bool is_zero);

}  // namespace parafab
