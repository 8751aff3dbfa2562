// Framed equilibrium curves (thesis §5.7.5, Proposition 10): a Frénet curve with a prescribed
// adapted frame of twist τ(s) is an equilibrium of a rod with coercive, bounded (I, J) ∈ K iff
// some (c, c̄) has ⟨v_i, c×γ + c̄⟩ > 0, i = 1, 2, with v1 = γ'/τ and
// v2 = 4ωn/(Eκ²) − γ'/(μτ). Then J = ⟨γ', h⟩/(μτ) and 4⟨ωn, h⟩/(Eκ²) is the supremum of 4ψ(I)
// over the I with E·I·kn = Fnᵀh. Checked as a linear feasibility program in (c, c̄) on the
// samples (rows multiplied by |τ|; at samples with τ = 0 the rows become ⟨γ', h⟩ = 0 and
// ⟨ωn, h⟩ > 0, the necessary conditions of the limit τ → 0).
#pragma once

#include <string>
#include <vector>

#include "common/few_variable_lp.h"
#include "rods/rod_geometry.h"

namespace parafab {

struct FramedEquilibriumOptions {
  /// |τ|·length at or below this counts as a zero of the twist.
  double zero_twist_tolerance = 1e-12;
  LpForm form = LpForm::Dense;
};

struct FramedEquilibriumResult {
  bool feasible = false;
  LpStatus lp_status = LpStatus::Failed;
  Vec3 c{0, 0, 0}, c_bar{0, 0, 0};  ///< a feasible complex (arbitrary positive scale)
  /// min over samples with τ ≠ 0 of J / (4⟨ωn, h⟩/(Eκ²)) (< 1 when feasible) and of J > 0.
  double max_torsion_fraction = 0;
  int zero_twist_samples = 0;
  double seconds = 0;
  std::string message;
};

/// `twist[i]` is τ of the prescribed frame at samples[i] [1/m]. Throws parafab::Error for
/// size mismatch, non-Frénet samples or an invalid material.
FramedEquilibriumResult check_framed_equilibrium(const std::vector<RodSample>& samples,
                                                 const std::vector<double>& twist,
                                                 const RodMaterial& material,
                                                 const FramedEquilibriumOptions& options = {});

}  // namespace parafab
