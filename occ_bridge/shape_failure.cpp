// Failure objective (thesis §6.2.3 Eq. 6.4, [SZB18]) and its adjoint shape derivative; see
// shape_failure.h.
#include "shape_failure.h"

#include <tbb/parallel_for.h>

#include <cmath>
#include <mutex>

#include "common/error.h"
#include "xfem/moment_fitting.h"
#include "xfem/volume_rules.h"

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

// The failure integral of a cut element on a frame of fixed points, so that Eq. 6.31 holds for
// it: the tensor Gauss points ξ_q (weights W_q on the unit cube) of the element's frame box F
// (xfem::rule_frame: its own fitting box, or the one frozen from the line search's start), with
// weights fitted to the subvolume's moments in F's frame, ω_q = |F| W_q Σ_k L_k(ξ_q) β_k,
// β_k = Σ_j w_j L_k(ξ_F(X_j)) / |F| from the element's own rule (exact: L_k(ξ_F(X)) is in the
// span that rule fits, whatever its box). Then I_e = Σ ω_q j(X_q) = ∫_Ω ĵ dV, ĵ = Σ_k c_k L_k with
// c_k = Σ_q W_q L_k(ξ_q) j(X_q) (j's projection on the span over F), and with u and F frozen
// dI_e = ∫_Γ ĵ Vₙ dA to the moments' accuracy. The element's rule itself would not do: its
// points sit in the fitting box, which moves with the shape, and Σ w j(X) changes with that box
// wherever j is not in the span (the exponential never is): by 1.4 % to 3× of dI on the turned
// bracket. F is not the cell: a sliver's field extended over its cell reaches σ_vm ~ 10⁴ MPa and
// exp overflows.
struct FrameRule {
  std::vector<std::array<int, 3>> exponents;
  int top = 0;                  ///< largest exponent
  std::vector<xfem::Vec3> xi;   ///< unit-cube Gauss points
  std::vector<double> W;        ///< their weights (Σ = 1)
  Eigen::MatrixXd L;            ///< basis k at point q
  explicit FrameRule(const xfem::VolumeRuleOptions& ro) {
    const xfem::FittingSystem& system = xfem::cube_fitting_system(ro.degree, ro.points_per_direction, ro.max_exponent);
    exponents = system.exponents;
    for (const auto& ex : exponents) top = std::max({top, ex[0], ex[1], ex[2]});
    const xfem::QuadratureRule1& g = xfem::gauss_legendre(ro.points_per_direction);
    for (size_t i = 0; i < g.points.size(); ++i)
      for (size_t j = 0; j < g.points.size(); ++j)
        for (size_t k = 0; k < g.points.size(); ++k) {
          xi.emplace_back(g.points[i], g.points[j], g.points[k]);
          W.push_back(g.weights[i] * g.weights[j] * g.weights[k]);
        }
    L.resize(static_cast<Eigen::Index>(exponents.size()), static_cast<Eigen::Index>(xi.size()));
    for (size_t q = 0; q < xi.size(); ++q) L.col(static_cast<Eigen::Index>(q)) = basis(xi[q]);
  }
  Eigen::VectorXd basis(const xfem::Vec3& x) const {
    std::vector<double> v(3 * (top + 1)), integral(3 * (top + 1));
    for (int d = 0; d < 3; ++d) xfem::legendre_basis(x[d], top + 1, &v[d * (top + 1)], &integral[d * (top + 1)]);
    Eigen::VectorXd b(static_cast<Eigen::Index>(exponents.size()));
    for (size_t k = 0; k < exponents.size(); ++k)
      b[static_cast<Eigen::Index>(k)] = v[exponents[k][0]] * v[(top + 1) + exponents[k][1]] * v[2 * (top + 1) + exponents[k][2]];
    return b;
  }
  xfem::Vec3 unit(const xfem::Box3& F, const xfem::Vec3& X) const { return (X - F.min).cwiseQuotient(F.size()); }
  xfem::Vec3 physical(const xfem::Box3& F, int q) const { return F.min + F.size().cwiseProduct(xi[q]); }
  /// ω of a cut element on its frame F (see above).
  std::vector<double> weights(const xfem::GridElement& el, const xfem::Box3& F) const {
    Eigen::VectorXd beta = Eigen::VectorXd::Zero(L.rows());
    for (size_t j = 0; j < el.rule.points.size(); ++j) beta += el.rule.weights[j] * basis(unit(F, el.rule.points[j]));
    std::vector<double> omega(xi.size());
    for (size_t q = 0; q < xi.size(); ++q) omega[q] = W[q] * L.col(static_cast<Eigen::Index>(q)).dot(beta);
    return omega;
  }
};

struct ElementFailure {
  double integral = 0, volume = 0, max_vm = 0;
  Eigen::VectorXd gradient;  ///< ∂I_e/∂u_e (if asked)
};

// I_e = Σ_q w_q exp(α(σ_vm/σ_y − 1)) of element `el` with nodal values ue: on its own rule
// (uncut cells), on its frame's points (cut cells). The volume and the largest σ_vm are
// those of its own rule's points (the largest over points of positive weight).
ElementFailure element_failure(const xfem::GridElement& el, const Eigen::VectorXd& ue, const Eigen::Matrix<double, 6, 6>& D,
                               const FailureOptions& o, const FrameRule& frame, bool with_gradient) {
  ElementFailure r;
  const int n = static_cast<int>(ue.size() / 3);
  if (with_gradient) r.gradient = Eigen::VectorXd::Zero(ue.size());
  Eigen::MatrixXd G;
  auto stress = [&](const xfem::Vec3& X, Eigen::MatrixXd& B) {
    shape(el.box, n, X, G);
    B = strain_matrix(G);
    return Voigt(D * (B * ue));
  };
  Eigen::MatrixXd B;
  for (size_t q = 0; q < el.rule.points.size(); ++q) {
    const double w = el.rule.weights[q];
    r.volume += w;
    if (el.subvolume && !(w > 0)) continue;
    const Voigt s = stress(el.rule.points[q], B);
    const double vm = xfem::von_mises(s);
    if (w > 0) r.max_vm = std::max(r.max_vm, vm);
    if (el.subvolume) continue;
    const double e = std::exp(o.exponent * (vm / o.yield_stress - 1));
    r.integral += w * e;
    if (with_gradient) r.gradient += (w * e * o.exponent / o.yield_stress) * (B.transpose() * (D * von_mises_derivative(s, vm)));
  }
  if (!el.subvolume || el.rule.points.empty()) return r;
  const xfem::Box3 F = xfem::rule_frame(el);
  const std::vector<double> omega = frame.weights(el, F);
  for (size_t q = 0; q < omega.size(); ++q) {
    const Voigt s = stress(frame.physical(F, static_cast<int>(q)), B);
    const double vm = xfem::von_mises(s);
    const double e = std::exp(o.exponent * (vm / o.yield_stress - 1));
    r.integral += omega[q] * e;
    if (with_gradient)
      r.gradient += (omega[q] * e * o.exponent / o.yield_stress) * (B.transpose() * (D * von_mises_derivative(s, vm)));
  }
  return r;
}

// exp(α(σ_vm/σ_y − 1)) of the element's nodal values ue at X.
double failure_density(const xfem::GridElement& el, const Eigen::VectorXd& ue, const Eigen::Matrix<double, 6, 6>& D,
                       const FailureOptions& o, const xfem::Vec3& X) {
  Eigen::MatrixXd G;
  shape(el.box, static_cast<int>(ue.size() / 3), X, G);
  const Voigt s = D * (strain_matrix(G) * ue);
  return std::exp(o.exponent * (xfem::von_mises(s) / o.yield_stress - 1));
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
  const FrameRule frame(setup.grid.rule);
  std::vector<ElementFailure> per(elements.size());
  tbb::parallel_for(size_t(0), elements.size(), [&](size_t e) {
    per[e] = element_failure(elements[e], element_values(state.solution.u, state.solution.node[e]), D, o, frame,
                             with_gradient);
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
  const FrameRule frame(setup.grid.rule);
  return element_difference(
      state, std::move(plus), std::move(minus), h, setup,
      [&](const xfem::GridElement& el, const std::vector<xfem::TractionCondition>& tractions, int base) {
        const std::vector<int>& nodes = state.solution.node[base];
        const Eigen::VectorXd ue = element_values(state.solution.u, nodes), le = element_values(lambda, nodes);
        const ElementFailure ef = element_failure(el, ue, D, o, frame, false);
        const double explicit_term = o.normalize ? ef.integral / V - I / (V * V) * ef.volume : ef.integral;
        return le.dot(element_residual(el, tractions, ue, setup)) + explicit_term;
      });
}

ComplianceGradient failure_gradient(const ComplianceState& state, const FailureValue& value,
                                    const Eigen::VectorXd& adjoint, const ComplianceSetup& setup, const FailureOptions& o,
                                    const ShapeParameters& sp, const Eigen::VectorXd& p, const std::vector<char>* moving) {
  check_failure_options(o);
  PARAFAB_VERIFY(value.done, "failure_gradient: the value is not computed");
  ShapeAdjoint a;
  a.lambda = adjoint.size() ? adjoint : failure_adjoint(state, value);
  const Eigen::Matrix<double, 6, 6> D = elasticity_matrix(setup.material);
  const double V = value.volume, I = value.integral;
  // J = I/V: dJ = dI/V − (I/V²) dV, dI = ∫ exp(·) Vₙ, dV = ∫ Vₙ.
  const double scale = o.normalize ? 1 / V : 1.0, shift = o.normalize ? I / (V * V) : 0.0;
  // ĵ of the cut element (FrameRule): the projection of j on the span over its frame, whose
  // integral over the subvolume is I_e; so dI_e = ∫_Γ ĵ Vₙ dA (Eq. 6.31 on fixed points).
  const auto frame = std::make_shared<const FrameRule>(setup.grid.rule);
  a.density = [&, frame](int e, const std::vector<xfem::Vec3>& points) {
    const xfem::GridElement& el = state.model->elements[e];
    PARAFAB_VERIFY(el.subvolume, "failure_gradient: element " << e << " is not cut");
    const Eigen::VectorXd ue = element_values(state.solution.u, state.solution.node[e]);
    std::vector<double> j(points.size(), 0.0);
    if (el.rule.points.empty()) return j;  // a failed rule: I_e = 0 whatever the shape
    const xfem::Box3 F = xfem::rule_frame(el);
    Eigen::VectorXd c = Eigen::VectorXd::Zero(frame->L.rows());
    for (size_t q = 0; q < frame->xi.size(); ++q)
      c += frame->W[q] * failure_density(el, ue, D, o, frame->physical(F, static_cast<int>(q))) *
           frame->L.col(static_cast<Eigen::Index>(q));
    for (size_t q = 0; q < points.size(); ++q) j[q] = scale * c.dot(frame->basis(frame->unit(F, points[q]))) - shift;
    return j;
  };
  return adjoint_shape_gradient(state, setup, sp, p, a, moving);
}

}  // namespace parafab::occ
