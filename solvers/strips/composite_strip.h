// Composite strips (thesis §4.7.1, Fig. 4.13 right): a broad strip of thickness h₁ and
// prescribed width w₁(s) glued to a narrow strip of thickness h₂ and width w₂(s), with
// c K = P₁ w₁ + P₂ w₂, P₁ = h₁³, P₂ = (h₁ + h₂)³ − h₁³. Feasible iff
// max c_min ≤ min c_max with c_min = P₁ w₁ / K, c_max = (P₁ + P₂) w₁ / K; then c = min c_max
// (the narrow strip as wide as possible without protruding). Infeasible designs get the
// largest thickness ratio h₁/h₂ that would make them feasible: with q = min(w₁/K) / max(w₁/K)
// and t = q^{1/3}, h₁/h₂ ≤ t / (1 − t).
#pragma once

#include <string>
#include <vector>

namespace parafab {

struct CompositeStripOptions {
  double outer_thickness = 0.3e-3;  ///< h₁ [m] (broad strip)
  double inner_thickness = 0.3e-3;  ///< h₂ [m] (narrow strip)
};

struct CompositeStripResult {
  bool feasible = false;
  std::vector<double> inner_width;  ///< w₂(s) [m], 0 ≤ w₂ ≤ w₁ (empty when infeasible)
  double scale = 0;                 ///< c = min c_max [m⁴ per unit of K]
  double max_c_min = 0, min_c_max = 0;
  double worst_s = -1;              ///< where c_min is largest (the binding point if infeasible)
  /// Largest h₁/h₂ for which this w₁, K pair is feasible (∞ if w₁/K is constant).
  double max_thickness_ratio = 0;
  std::string message;              ///< why infeasible, with the ratio that would work
};

/// `s`, `stiffness` (K > 0, any scale) and `outer_width` (w₁ > 0) of equal length ≥ 1.
/// Throws parafab::Error naming the offending input.
CompositeStripResult design_composite_strip(const std::vector<double>& s,
                                            const std::vector<double>& stiffness,
                                            const std::vector<double>& outer_width,
                                            const CompositeStripOptions& options = {});

}  // namespace parafab
