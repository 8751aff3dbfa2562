#include "strips/stiffness_lp.h"

#include <algorithm>
#include <cmath>

#include "common/error.h"

namespace parafab {

double stiffness_at(const CurvePoint& p, double a, const Vec2& b, bool is_zero) {
  if (is_zero) return b.dot(p.tangent) / p.dkappa_ds;
  return (a + b.dot(p.point)) / p.kappa;
}

StiffnessLpResult solve_stiffness_lp(const std::vector<CurvePoint>& samples,
                                     const std::vector<CurvePoint>& zeros,
                                     const std::vector<Vec2>& line_points, double length,
                                     const StiffnessLpOptions& options) {
  PARAFAB_VERIFY(length > 0, "stiffness LP: curve length must be positive, got " << length);
  PARAFAB_VERIFY(!samples.empty() || !zeros.empty(), "stiffness LP: no samples");
  // Normalize: γ̂ = (γ − c)/l, κ̂ = κ l, κ̂' = κ' l² so that all rows are O(1).
  Vec2 c = Vec2::Zero();
  for (const auto& p : samples) c += p.point;
  if (!samples.empty()) c /= static_cast<double>(samples.size());
  const double l = length;
  const int n = static_cast<int>(samples.size()), m = static_cast<int>(zeros.size());
  const int e = static_cast<int>(line_points.size());
  FewVariableLp lp;
  lp.c = Eigen::Vector4d(0, 0, 0, 1);  // x = (â, b̂₁, b̂₂, R)
  lp.G.resize(2 * (n + m), 4);
  lp.h.resize(2 * (n + m));
  lp.E.resize(e, 4);
  lp.f = Eigen::VectorXd::Zero(e);
  for (int j = 0; j < e; ++j) {
    const Vec2 g = (line_points[j] - c) / l;
    lp.E.row(j) << 1.0, g.x(), g.y(), 0.0;
  }
  int row = 0;
  // K ≥ 1 and K ≤ R, multiplied by |κ| so that rows stay bounded near inflections.
  auto add_bounds = [&](const Eigen::Vector3d& p, double k) {
    const double sg = k > 0 ? 1.0 : -1.0, w = std::abs(k);
    lp.G.row(row) << sg * p(0), sg * p(1), sg * p(2), 0.0;
    lp.h(row++) = w;
    lp.G.row(row) << -sg * p(0), -sg * p(1), -sg * p(2), w;
    lp.h(row++) = 0.0;
  };
  for (const auto& p : samples) {
    const Vec2 g = (p.point - c) / l;
    add_bounds(Eigen::Vector3d(1.0, g.x(), g.y()), p.kappa * l);
  }
  for (int j = 0; j < m; ++j) {
    // lim K = ⟨b̂, γ̂'⟩ / κ̂'  with γ̂' = t / l in ŝ = s / l units: ⟨b̂, t⟩ / (κ' l²).
    add_bounds(Eigen::Vector3d(0.0, zeros[j].tangent.x(), zeros[j].tangent.y()),
               zeros[j].dkappa_ds * l * l);
  }
  FewVariableLpOptions lo;
  lo.form = options.form;
  if (!options.warm_samples.empty() || !options.warm_other.empty()) {
    size_t i = 0;
    for (const auto& [sw, which] : options.warm_samples) {
      while (i < samples.size() && samples[i].s < sw) ++i;
      if (i < samples.size() && samples[i].s == sw) lo.basic_hint.push_back(2 * static_cast<int>(i) + which);
    }
    for (int k : options.warm_other) lo.basic_hint.push_back(2 * n + k);
  }
  const FewVariableLpResult r = solve_few_variable_lp(lp, lo);
  StiffnessLpResult out;
  out.status = r.status;
  out.rows = static_cast<int>(lp.G.rows());
  out.iterations = r.iterations;
  for (int j : r.basic) {
    if (j < 2 * n) out.active_samples.emplace_back(samples[j / 2].s, j % 2);
    else out.active_other.push_back(j - 2 * n);
  }
  out.seconds = r.seconds;
  out.max_violation = r.max_violation;
  out.message = r.message;
  if (!r.ok()) return out;
  out.dual_rows = r.y;
  out.dual_line = r.z;
  out.center = c;
  out.scale = l;
  out.normalized_line = r.x.head<3>();
  // Back to input units: (a + ⟨b, γ⟩)/κ = (â + ⟨b̂, γ̂⟩)/κ̂.
  const Vec2 bh(r.x(1), r.x(2));
  out.a = (r.x(0) - bh.dot(c) / l) / l;
  out.b = bh / (l * l);
  // R of the returned line, evaluated on the rows themselves: the LP variable R can sit a
  // dual tolerance (~1e-9) above max K / min K, and users get the line, not the variable.
  double kmax = -INFINITY, kmin = INFINITY;
  for (const auto& p : samples) {
    const double k = stiffness_at(p, out.a, out.b, false);
    kmax = std::max(kmax, k), kmin = std::min(kmin, k);
  }
  for (const auto& z : zeros) {
    const double k = stiffness_at(z, out.a, out.b, true);
    kmax = std::max(kmax, k), kmin = std::min(kmin, k);
  }
  out.R = kmax / kmin;
  out.objective = r.x(3);
  return out;
}

}  // namespace parafab
