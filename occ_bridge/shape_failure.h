// Failure (stress) objective of shape optimization (thesis §6.2.3 Eq. 6.4, the exponentiated
// failure metric of [SZB18]): I = ∫_V exp(α(σ_vm/σ_y − 1)) dV over the uncut cells' Gauss points
// and, per cut cell, the Gauss points of its frame with weights fitted to the cell's moments
// (shape_failure.cpp FrameRule; xfem::GridElement::frame) of the linear XFEM solve
// (shape_compliance.h: same job, same fixed grid).
// Reported form J = I / V when `normalize` (a smooth maximum of exp(α(σ_vm/σ_y − 1)): 1 when
// σ_vm = σ_y everywhere, well scaled for any part size), I otherwise. σ_vm is the von Mises stress
// of the nodal field (xfem::stress_at; hex8 incompatible modes are not part of it).
// Gradient: adjoint K λ = −∂J/∂u with the kept factorization, then
// dJ/ds = ∂J/∂s|_u + λᵀ(dK u − df): by the exact route (failure_gradient: boundary integrals over
// the moving patches, every entry of p at once) or, where that route flags an entry, both terms
// as central differences over the re-cut cells only (failure_derivative).
#pragma once

#include <Eigen/Core>
#include <memory>
#include <string>

#include "shape_compliance.h"

namespace parafab::occ {

struct FailureOptions {
  double yield_stress = 0;  ///< σ_y (> 0, required)
  double exponent = 0;      ///< α (> 0, required; larger: closer to the maximum stress)
  bool normalize = true;    ///< J = I / V instead of I
};

/// Throws parafab::Error naming the field (yield_stress, exponent) and the value when invalid.
void check_failure_options(const FailureOptions& options);

struct FailureValue {
  bool done = false;
  std::string message;
  double objective = 0;       ///< J (I / V when normalized, else I)
  double integral = 0;        ///< I = ∫ exp(α(σ_vm/σ_y − 1)) dV
  double volume = 0;          ///< V = Σ rule weights
  double max_von_mises = 0;   ///< max σ_vm over the material quadrature points
  Eigen::VectorXd gradient_u; ///< ∂J/∂u (3 per DOF node); empty unless asked for
};

/// J of a solved state (and ∂J/∂u when with_gradient).
FailureValue failure_value(const ComplianceState& state, const ComplianceSetup& setup, const FailureOptions& options,
                           bool with_gradient = false);

/// dJ/ds along a perturbation (models plus at s = +h, minus at s = −h, either may be null):
/// λ = −K⁻¹ ∂J/∂u solved once with `state`'s kept factorization (pass it in `adjoint` to reuse it
/// for several directions; empty: solved here), then the changed cells' elements differenced:
/// Σ w·[λₑᵀ(Kₑuₑ − fₑ) + Iₑ(uₑ)/V − (I/V²)Vₑ] (normalized) or Σ w·[λₑᵀ(Kₑuₑ − fₑ) + Iₑ(uₑ)].
ComplianceDerivative failure_derivative(const ComplianceState& state, const FailureValue& value,
                                        const Eigen::VectorXd& adjoint, std::shared_ptr<const PartShape> plus,
                                        std::shared_ptr<const PartShape> minus, double h,
                                        const ComplianceSetup& setup, const FailureOptions& options);

/// dJ/dp by the exact route (adjoint_shape_gradient, thesis Eq. 6.30–6.31): λ as in
/// failure_derivative (empty `adjoint`: solved here) and J's own density on the moving patches,
/// ĵ/V − I/V² (normalized; ĵ otherwise), ĵ the projection of exp(α(σ_vm/σ_y − 1)) on the rules'
/// span over the cut cell's frame (σ_vm of the nodal field as failure_value takes it): with u
/// and the frames frozen, the exact derivative of J's frame-rule sum (to the moments'
/// accuracy). Entries flagged `incomplete` as in compliance_gradient: use failure_derivative there.
ComplianceGradient failure_gradient(const ComplianceState& state, const FailureValue& value,
                                    const Eigen::VectorXd& adjoint, const ComplianceSetup& setup,
                                    const FailureOptions& options, const ShapeParameters& parameters,
                                    const Eigen::VectorXd& p, const std::vector<char>* moving = nullptr);

/// λ = −K⁻¹ ∂J/∂u (value must carry gradient_u).
Eigen::VectorXd failure_adjoint(const ComplianceState& state, const FailureValue& value);

}  // namespace parafab::occ
