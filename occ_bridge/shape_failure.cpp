// Failure objective (thesis §6.2.3 Eq. 6.4, [SZB18]) and its adjoint shape derivative; see
// shape_failure.h.
#include "shape_failure.h"

#include <tbb/parallel_for.h>

#include <cmath>
#include <mutex>

#include "common/error.h"

namespace parafab::occ {

namespace {

using Voigt = Eigen::Matrix<double, 6, 1>;

Eigen::Matrix<double, 6, 6> elasticity_matrix(const xfem::ElasticMaterial& m) {
  const double E = m.youngs_modulus, nu = m.poisson_ratio;
  const double lambda = E * nu / ((1 + nu) * (1 - 2 * nu)), mu = E / (2 * (1 + nu));
  Eigen::Matrix<double, 6, 6> D = Eigen::Matrix<double, 6, 6>::Zero();
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) D(i, j) = lambda;
    D(i, i) = lambda + 2 * mu;
    D(i + 3, i + 3) = mu;
  }
  return D;
}

void shape(const xfem::Box3& box, int n, const xfem::Vec3& X, Eigen::MatrixXd& G) {
  if (n == 8) {
    Eigen::Matrix<double, 8, 1> N;
    Eigen::Matrix<double, 8, 3> g;
    xfem::trilinear_shape(box, X, N, g);
    G = g;
  } else {
    Eigen::Matrix<double, 27, 1> N;
    Eigen::Matrix<double, 27, 3> g;
    xfem::triquadratic_shape(box, X, N, g);
    G = g;
  }
}

// Strain–displacement matrix (Voigt xx, yy, zz, γxy, γyz, γxz) of the element's nodes.
Eigen::MatrixXd strain_matrix(const Eigen::MatrixXd& G) {
  const int n = static_cast<int>(G.rows());
  Eigen::MatrixXd B = Eigen::MatrixXd::Zero(6, 3 * n);
  for (int k = 0; k < n; ++k) {
    const double gx = G(k, 0), gy = G(k, 1), gz = G(k, 2);
    B(0, 3 * k) = gx;
    B(1, 3 * k + 1) = gy;
    B(2, 3 * k + 2) = gz;
    B(3, 3 * k) = gy, B(3, 3 * k + 1) = gx;
    B(4, 3 * k + 1) = gz, B(4, 3 * k + 2) = gy;
    B(5, 3 * k) = gz, B(5, 3 * k + 2) = gx;
  }
  return B;
}

// ∂σ_vm/∂σ (Voigt, shear entries for the tensor shears τ).
Voigt von_mises_derivative(const Voigt& s, double vm) {
  Voigt d = Voigt::Zero();
  if (vm <= 0) return d;
  d(0) = (2 * s(0) - s(1) - s(2)) / (2 * vm);
  d(1) = (2 * s(1) - s(0) - s(2)) / (2 * vm);
  d(2) = (2 * s(2) - s(0) - s(1)) / (2 * vm);
  for (int i = 3; i < 6; ++i) d(i) = 3 * s(i) / vm;
  return d;
}

struct ElementFailure {
  double integral = 0, volume = 0, max_vm = 0;
  Eigen::VectorXd gradient;  ///< ∂I_e/∂u_e (if asked)
};

// I_e = Σ_q w_q exp(α(σ_vm/σ_y − 1)) of element `el` with nodal values ue.
ElementFailure element_failure(const xfem::GridElement& el, const Eigen::VectorXd& ue,
                               const Eigen::Matrix<double, 6, 6>& D, const FailureOptions& o, bool with_gradient) {
  ElementFailure r;
  const int n = static_cast<int>(ue.size() / 3);
  if (with_gradient) r.gradient = Eigen::VectorXd::Zero(ue.size());
  Eigen::MatrixXd G;
  for (size_t q = 0; q < el.rule.points.size(); ++q) {
    const double w = el.rule.weights[q];
    shape(el.box, n, el.rule.points[q], G);
    const Eigen::MatrixXd B = strain_matrix(G);
    const Voigt s = D * (B * ue);
    const double vm = xfem::von_mises(s);
    const double e = std::exp(o.exponent * (vm / o.yield_stress - 1));
    r.integral += w * e;
    r.volume += w;
    if (w > 0) r.max_vm = std::max(r.max_vm, vm);
    if (with_gradient) r.gradient += (w * e * o.exponent / o.yield_stress) * (B.transpose() * (D * von_mises_derivative(s, vm)));
  }
  return r;
}

}  // namespace

void check_failure_options(const FailureOptions& o) {
  if (!(std::isfinite(o.yield_stress) && o.yield_stress > 0))
    PARAFAB_INPUT_ERROR("objective.yield_stress: the failure objective needs a positive yield stress, got " << o.yield_stress);
  if (!(std::isfinite(o.exponent) && o.exponent > 0))
    PARAFAB_INPUT_ERROR("objective.exponent: the failure objective's alpha must be positive, got " << o.exponent);
}

FailureValue failure_value(const ComplianceState& state, const ComplianceSetup& setup, const FailureOptions& o,
                           bool with_gradient) {
  check_failure_options(o);
  FailureValue v;
  if (!state.done || !state.model) {
    v.message = "the elasticity state is not solved: " + state.message;
    return v;
  }
  const auto& elements = state.model->elements;
  const Eigen::Matrix<double, 6, 6> D = elasticity_matrix(setup.material);
  std::vector<ElementFailure> per(elements.size());
  tbb::parallel_for(size_t(0), elements.size(), [&](size_t e) {
    per[e] = element_failure(elements[e], element_values(state.solution.u, state.solution.node[e]), D, o, with_gradient);
  });
  for (const ElementFailure& r : per) {  // element order: deterministic
    v.integral += r.integral;
    v.volume += r.volume;
    v.max_von_mises = std::max(v.max_von_mises, r.max_vm);
  }
  PARAFAB_VERIFY(v.volume > 0, "failure objective: the rules integrate a volume of " << v.volume);
  const double scale = o.normalize ? 1 / v.volume : 1.0;
  v.objective = scale * v.integral;
  if (with_gradient) {
    v.gradient_u = Eigen::VectorXd::Zero(state.solution.u.size());
    for (size_t e = 0; e < elements.size(); ++e) {
      const std::vector<int>& nodes = state.solution.node[e];
      for (size_t a = 0; a < nodes.size(); ++a)
        v.gradient_u.segment<3>(3 * nodes[a]) += scale * per[e].gradient.segment<3>(3 * a);
    }
  }
  v.done = true;
  v.message = "ok";
  return v;
}

Eigen::VectorXd failure_adjoint(const ComplianceState& state, const FailureValue& value) {
  PARAFAB_VERIFY(value.done, "failure_adjoint: the value is not computed");
  return adjoint_of(state, value.gradient_u, "failure_adjoint");
}

ComplianceDerivative failure_derivative(const ComplianceState& state, const FailureValue& value,
                                        const Eigen::VectorXd& adjoint, std::shared_ptr<const PartShape> plus,
                                        std::shared_ptr<const PartShape> minus, double h,
                                        const ComplianceSetup& setup, const FailureOptions& o) {
  check_failure_options(o);
  PARAFAB_VERIFY(value.done, "failure_derivative: the value is not computed");
  const Eigen::VectorXd lambda = adjoint.size() ? adjoint : failure_adjoint(state, value);
  PARAFAB_VERIFY(lambda.size() == state.solution.u.size(),
                 "failure_derivative: adjoint of size " << lambda.size() << ", expected " << state.solution.u.size());
  const Eigen::Matrix<double, 6, 6> D = elasticity_matrix(setup.material);
  const double V = value.volume, I = value.integral;
  return element_difference(
      state, std::move(plus), std::move(minus), h, setup,
      [&](const xfem::GridElement& el, const std::vector<xfem::TractionCondition>& tractions, int base) {
        const std::vector<int>& nodes = state.solution.node[base];
        const Eigen::VectorXd ue = element_values(state.solution.u, nodes), le = element_values(lambda, nodes);
        const ElementFailure ef = element_failure(el, ue, D, o, false);
        const double explicit_term = o.normalize ? ef.integral / V - I / (V * V) * ef.volume : ef.integral;
        return le.dot(element_residual(el, tractions, ue, setup)) + explicit_term;
      });
}

}  // namespace parafab::occ
