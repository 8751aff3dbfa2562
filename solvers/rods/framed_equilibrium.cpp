#include "rods/framed_equilibrium.h"

#include <algorithm>
#include <chrono>
#include <cmath>

#include "common/error.h"

namespace parafab {

FramedEquilibriumResult check_framed_equilibrium(const std::vector<RodSample>& samples,
                                                 const std::vector<double>& twist,
                                                 const RodMaterial& material,
                                                 const FramedEquilibriumOptions& options) {
  const auto t0 = std::chrono::steady_clock::now();
  validate(material);
  PARAFAB_VERIFY(samples.size() >= 2 && samples.size() == twist.size(),
                 "framed equilibrium: " << samples.size() << " samples and " << twist.size()
                                        << " twists (need equal, >= 2)");
  for (size_t i = 0; i < samples.size(); ++i) {
    if (!(samples[i].kappa > 0))
      PARAFAB_INPUT_ERROR("framed equilibrium: samples[" << i << "] at s = " << samples[i].s
                                                         << " has kappa = " << samples[i].kappa);
    if (!std::isfinite(twist[i]))
      PARAFAB_INPUT_ERROR("framed equilibrium: twist[" << i << "] is not finite");
  }
  // Normalized coordinates γ̂ = (γ − o)/L, ĥ = ĉ×γ̂ + c̄̂ (as in the line-complex LP).
  Vec3 o = Vec3::Zero();
  for (const auto& p : samples) o += p.point;
  o /= double(samples.size());
  const double L = samples.back().s - samples.front().s;
  const double ratio = material.shear_modulus() / material.youngs_modulus;  // μ/E
  using Row6 = Eigen::Matrix<double, 1, 6>;
  auto functional = [](const Vec3& g, const Vec3& v) {
    Row6 r;
    r << g.cross(v).transpose(), v.transpose();
    return r;
  };
  std::vector<Row6> ineq;
  std::vector<double> rhs;
  std::vector<Row6> eq;
  FramedEquilibriumResult out;
  for (size_t i = 0; i < samples.size(); ++i) {
    const RodSample& p = samples[i];
    const Vec3 g = (p.point - o) / L;
    const Row6 T = functional(g, p.tangent);
    const double kh = p.kappa * L;
    const Row6 W = functional(g, kh * p.binormal) / (kh * kh);  // ⟨ω̂, ĥ⟩/κ̂²
    const double th = twist[i] * L;
    if (std::abs(th) <= options.zero_twist_tolerance) {
      ++out.zero_twist_samples;
      eq.push_back(T);
      ineq.push_back(W), rhs.push_back(1.0);
      continue;
    }
    const double sg = th > 0 ? 1.0 : -1.0, a = std::abs(th);
    // J > 0:            sign(τ)⟨T, ĥ⟩ ≥ |τ̂|
    ineq.push_back(sg * T), rhs.push_back(a);
    // 4ψ_max − J > 0:   4 (μ/E) |τ̂| ⟨ω̂, ĥ⟩/κ̂² − sign(τ)⟨T, ĥ⟩ ≥ |τ̂|
    ineq.push_back(4 * ratio * a * W - sg * T), rhs.push_back(a);
  }
  FewVariableLp lp;
  lp.c = Eigen::VectorXd::Zero(6);
  lp.G.resize(ineq.size(), 6);
  lp.h.resize(ineq.size());
  for (size_t k = 0; k < ineq.size(); ++k) lp.G.row(k) = ineq[k], lp.h(k) = rhs[k];
  lp.E.resize(eq.size(), 6);
  lp.f = Eigen::VectorXd::Zero(eq.size());
  for (size_t k = 0; k < eq.size(); ++k) lp.E.row(k) = eq[k];
  FewVariableLpOptions lo;
  lo.form = options.form;
  const FewVariableLpResult r = solve_few_variable_lp(lp, lo);
  out.lp_status = r.status;
  out.feasible = r.ok();
  out.message = r.ok() ? "" : std::string("framed curve is not an equilibrium (Prop. 10): LP ") +
                                  to_string(r.status) + (r.message.empty() ? "" : " (" + r.message + ")");
  if (r.ok()) {
    const Vec3 ch = r.x.head<3>(), cbh = r.x.tail<3>();
    out.c = ch / L;
    out.c_bar = cbh - ch.cross(o) / L;
    const double E = material.youngs_modulus, mu = material.shear_modulus();
    for (size_t i = 0; i < samples.size(); ++i) {
      if (std::abs(twist[i] * L) <= options.zero_twist_tolerance) continue;
      const Vec3 h = out.c.cross(samples[i].point) + out.c_bar;
      const double J = samples[i].tangent.dot(h) / (mu * twist[i]);
      const double P = 4 * samples[i].omega_n().dot(h) / (E * samples[i].kappa * samples[i].kappa);
      out.max_torsion_fraction = std::max(out.max_torsion_fraction, J / P);
    }
  }
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

}  // namespace parafab
