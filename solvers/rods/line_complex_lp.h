// Linear complexes (c, c̄) for Kirchhoff rod design (thesis §5.6–5.7): the linear program of
// Eq. 5.19, minimize R subject to ⟨γ'×γ'', c×γ + c̄⟩ ≥ 1 (no binormal line in the complex,
// Prop. 9 / Eq. 5.18), |⟨γ', c×γ + c̄⟩| ≤ R (twist couple, Eq. 5.19a) and
// w_reg·|⟨γ''/κ, c×γ + c̄⟩| ≤ R (Eq. 5.19b) on the samples. With w_reg = 0 and R = 0 this is
// the parallel-curve condition Eq. 5.13 (Prop. 7). Unknowns x = (c, c̄, R), 7 variables,
// solved with solve_few_variable_lp.
#pragma once

#include <string>
#include <vector>

#include "common/few_variable_lp.h"
#include "rods/space_curve.h"

namespace parafab {

struct LineComplexLpOptions {
  double regularization_weight = 0;  ///< w_reg ≥ 0 of Eq. 5.19b
  /// Second stage (ParaFab extension, not in the thesis): among the complexes whose twist
  /// objective is within `twist_slack` of the optimum R*, minimize the ratio of the largest
  /// to the smallest effective bending stiffness K = ⟨γ'×γ'', c×γ + c̄⟩ / κ² (the moment
  /// about the bending axis per curvature). Eq. 5.19 leaves this scale profile free; for a
  /// plane curve K is exactly the strip stiffness of Eq. 4.4 and the second stage is the
  /// strip LP. Costs one more LP.
  bool minimize_stiffness_ratio = true;
  double twist_slack_relative = 1e-7;  ///< R ≤ R*(1 + rel) + abs in the second stage
  double twist_slack_absolute = 1e-12; ///< (in the normalized units of R, see below)
  /// R·(length units) below this counts as a parallel curve (Eq. 5.13 holds on the samples).
  double parallel_tolerance = 1e-7;
  /// On infeasibility, find a minimal set of samples whose binormal lines no complex avoids
  /// (deletion filter over LPs; at most 7 samples by Helly's theorem in R⁶).
  bool find_binding_samples = true;
  LpForm form = LpForm::Dense;
};

enum class LineComplexStatus { Feasible, Infeasible, SolverFailed };
const char* to_string(LineComplexStatus status);

struct LineComplexLpResult {
  LineComplexStatus status = LineComplexStatus::SolverFailed;
  /// The complex, scaled so that min over samples of ⟨γ'×γ'', c×γ + c̄⟩ = 1 [c: 1/m², c̄: 1/m].
  Vec3 c{0, 0, 0};
  Vec3 c_bar{0, 0, 0};
  /// Eq. 5.19 objective in normalized form: max |⟨γ', h⟩| (and w_reg·|⟨N, h⟩|) divided by
  /// min ⟨γ'×γ'', h⟩·length, h = c×γ + c̄ (dimensionless; 0 for a parallel curve).
  double R = 0;
  double twist_ratio = 0;      ///< max |⟨γ', h⟩| / (min ⟨γ'×γ'', h⟩ · length)
  double stiffness_ratio = 0;  ///< max K / min K of the returned complex
  bool parallel = false;       ///< twist_ratio ≤ parallel_tolerance
  std::vector<int> binding_samples;  ///< infeasible: sample indices of a minimal conflict
  std::vector<double> binding_s;     ///< their arc lengths [m]
  int lps_solved = 0;
  int iterations = 0;
  double seconds = 0;
  std::string message;
  bool ok() const { return status == LineComplexStatus::Feasible; }
};

/// `samples` must be Frénet (κ > 0; see require_frenet_curve) and at least 2. Throws
/// parafab::Error for invalid options; infeasibility is a status with the binding samples.
LineComplexLpResult solve_line_complex_lp(const std::vector<RodSample>& samples,
                                          const LineComplexLpOptions& options = {});

/// h(s) = c × γ(s) + c̄ at every sample.
std::vector<Vec3> complex_field(const std::vector<RodSample>& samples, const Vec3& c,
                                const Vec3& c_bar);

}  // namespace parafab
