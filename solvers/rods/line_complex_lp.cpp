#include "rods/line_complex_lp.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <sstream>

#include "common/error.h"

namespace parafab {

const char* to_string(LineComplexStatus status) {
  switch (status) {
    case LineComplexStatus::Feasible: return "feasible";
    case LineComplexStatus::Infeasible: return "infeasible";
    case LineComplexStatus::SolverFailed: return "solver_failed";
  }
  return "unknown";
}

std::vector<Vec3> complex_field(const std::vector<RodSample>& samples, const Vec3& c,
                                const Vec3& c_bar) {
  std::vector<Vec3> h;
  h.reserve(samples.size());
  for (const auto& p : samples) h.push_back(c.cross(p.point) + c_bar);
  return h;
}

namespace {

using Row6 = Eigen::Matrix<double, 1, 6>;

// ⟨v, ĉ×γ̂ + c̄̂⟩ = ⟨γ̂×v, ĉ⟩ + ⟨v, c̄̂⟩ as a row over (ĉ, c̄̂).
Row6 functional(const Vec3& g, const Vec3& v) {
  Row6 r;
  r << g.cross(v).transpose(), v.transpose();
  return r;
}

struct Normalized {
  std::vector<Row6> binormal, tangent, normal;  // rows of ω̂n, T, N
  std::vector<double> kappa;                    // κ̂ = κ L
  Vec3 origin;
  double L;
};

Normalized normalize(const std::vector<RodSample>& samples) {
  Normalized n;
  n.origin = Vec3::Zero();
  for (const auto& p : samples) n.origin += p.point;
  n.origin /= double(samples.size());
  n.L = std::max(samples.back().s - samples.front().s, 1e-300);
  for (const auto& p : samples) {
    const Vec3 g = (p.point - n.origin) / n.L;
    n.kappa.push_back(p.kappa * n.L);
    n.binormal.push_back(functional(g, p.kappa * n.L * p.binormal));
    n.tangent.push_back(functional(g, p.tangent));
    n.normal.push_back(functional(g, p.normal));
  }
  return n;
}

// Is there x with ⟨ω̂_i, ĥ(x)⟩ ≥ 1 for all i in `rows`?
bool binormal_feasible(const Normalized& n, const std::vector<int>& rows, LpForm form, int& lps) {
  FewVariableLp lp;
  lp.c = Eigen::VectorXd::Zero(6);
  lp.G.resize(rows.size(), 6);
  lp.h = Eigen::VectorXd::Ones(rows.size());
  for (size_t k = 0; k < rows.size(); ++k) lp.G.row(k) = n.binormal[rows[k]];
  lp.E.resize(0, 6);
  lp.f.resize(0);
  FewVariableLpOptions o;
  o.form = form;
  ++lps;
  return solve_few_variable_lp(lp, o).status != LpStatus::Infeasible;
}

}  // namespace

LineComplexLpResult solve_line_complex_lp(const std::vector<RodSample>& samples,
                                          const LineComplexLpOptions& options) {
  const auto t0 = std::chrono::steady_clock::now();
  PARAFAB_VERIFY(samples.size() >= 2, "line complex LP: need at least 2 samples, got "
                                          << samples.size());
  if (!(options.regularization_weight >= 0) || !std::isfinite(options.regularization_weight))
    PARAFAB_INPUT_ERROR("line complex LP: regularization_weight must be >= 0, got "
                        << options.regularization_weight);
  for (size_t i = 0; i < samples.size(); ++i)
    if (!(samples[i].kappa > 0))
      PARAFAB_INPUT_ERROR("line complex LP: samples[" << i << "] at s = " << samples[i].s
                                                      << " has kappa = " << samples[i].kappa
                                                      << "; the curve must be Frenet");
  const Normalized nz = normalize(samples);
  const int n = int(samples.size());
  const double w = options.regularization_weight;
  const bool reg = w > 0;
  LineComplexLpResult out;
  FewVariableLpOptions lo;
  lo.form = options.form;

  // Stage 1, Eq. 5.19: x = (ĉ, c̄̂, R).
  const int per = reg ? 5 : 3;
  FewVariableLp lp;
  lp.c = Eigen::VectorXd::Zero(7);
  lp.c(6) = 1;
  lp.G.setZero(per * n, 7);
  lp.h.setZero(per * n);
  lp.E.resize(0, 7);
  lp.f.resize(0);
  for (int i = 0, r = 0; i < n; ++i) {
    lp.G.row(r).head<6>() = nz.binormal[i], lp.h(r++) = 1;
    lp.G.row(r).head<6>() = -nz.tangent[i], lp.G(r++, 6) = 1;
    lp.G.row(r).head<6>() = nz.tangent[i], lp.G(r++, 6) = 1;
    if (reg) {
      lp.G.row(r).head<6>() = -w * nz.normal[i], lp.G(r++, 6) = 1;
      lp.G.row(r).head<6>() = w * nz.normal[i], lp.G(r++, 6) = 1;
    }
  }
  FewVariableLpResult r1 = solve_few_variable_lp(lp, lo);
  out.lps_solved = 1;
  out.iterations = r1.iterations;
  Eigen::VectorXd x;
  if (r1.status == LpStatus::Infeasible) {
    out.status = LineComplexStatus::Infeasible;
    std::ostringstream os;
    os << "no linear complex avoids all binormal lines of the curve (Prop. 9): the curve is "
          "not an equilibrium curve of a Kirchhoff rod";
    if (options.find_binding_samples) {
      // Deletion filter in halving blocks: drop a block if the rest stays infeasible.
      std::vector<int> keep(n);
      for (int i = 0; i < n; ++i) keep[i] = i;
      for (size_t block = std::max<size_t>(1, keep.size() / 2);; block = std::max<size_t>(1, block / 2)) {
        for (size_t start = 0; start < keep.size();) {
          std::vector<int> rest;
          for (size_t k = 0; k < keep.size(); ++k)
            if (k < start || k >= start + block) rest.push_back(keep[k]);
          if (!rest.empty() && !binormal_feasible(nz, rest, options.form, out.lps_solved))
            keep = rest;
          else
            start += block;
        }
        if (block == 1) break;
      }
      out.binding_samples = keep;
      os << "; binding samples at s =";
      for (int i : keep) {
        out.binding_s.push_back(samples[i].s);
        os << " " << samples[i].s;
      }
      os << " m";
    }
    out.message = os.str();
    out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return out;
  }
  if (!r1.ok()) {
    out.status = LineComplexStatus::SolverFailed;
    out.message = "line complex LP (Eq. 5.19): " + r1.message;
    out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return out;
  }
  x = r1.x.head<6>();
  const double R1 = r1.x(6);

  if (options.minimize_stiffness_ratio) {
    // Stage 2: x = (ĉ, c̄̂, σ, ρ); ⟨ω̂,ĥ⟩ ≥ σ, |⟨T,ĥ⟩| ≤ Rmax σ, K̂ = ⟨ω̂,ĥ⟩/κ̂² ∈ [1, ρ].
    const double Rmax = R1 * (1 + options.twist_slack_relative) + options.twist_slack_absolute;
    const int per2 = reg ? 7 : 5;
    FewVariableLp lp2;
    lp2.c = Eigen::VectorXd::Zero(8);
    lp2.c(7) = 1;
    lp2.G.setZero(per2 * n, 8);
    lp2.h.setZero(per2 * n);
    lp2.E.resize(0, 8);
    lp2.f.resize(0);
    for (int i = 0, r = 0; i < n; ++i) {
      const double k2 = nz.kappa[i] * nz.kappa[i];
      lp2.G.row(r).head<6>() = nz.binormal[i], lp2.G(r++, 6) = -1;
      lp2.G.row(r).head<6>() = -nz.tangent[i], lp2.G(r++, 6) = Rmax;
      lp2.G.row(r).head<6>() = nz.tangent[i], lp2.G(r++, 6) = Rmax;
      if (reg) {
        lp2.G.row(r).head<6>() = -w * nz.normal[i], lp2.G(r++, 6) = Rmax;
        lp2.G.row(r).head<6>() = w * nz.normal[i], lp2.G(r++, 6) = Rmax;
      }
      lp2.G.row(r).head<6>() = nz.binormal[i] / k2, lp2.h(r++) = 1;
      lp2.G.row(r).head<6>() = -nz.binormal[i] / k2, lp2.G(r++, 7) = 1;
    }
    FewVariableLpResult r2 = solve_few_variable_lp(lp2, lo);
    ++out.lps_solved;
    out.iterations += r2.iterations;
    if (r2.ok()) {
      x = r2.x.head<6>();
    } else {
      out.message = std::string("stiffness-ratio stage: ") + to_string(r2.status) + " (" +
                    r2.message + "); returning the Eq. 5.19 solution";
    }
  }

  // Back to input units: ĥ = ĉ×γ̂ + c̄̂ with γ̂ = (γ − o)/L ⇒ h = c×γ + c̄ with
  // c = ĉ/L, c̄ = c̄̂ − ĉ×o/L; then scale so that min ⟨ω_n, h⟩ = 1.
  Vec3 c = x.head<3>() / nz.L;
  Vec3 cb = x.segment<3>(3) - x.head<3>().cross(nz.origin) / nz.L;
  double mn = INFINITY, kmin = INFINITY, kmax = 0, tw = 0, rg = 0;
  for (const auto& p : samples) {
    const Vec3 h = c.cross(p.point) + cb;
    const double b = p.omega_n().dot(h);
    mn = std::min(mn, b);
    kmin = std::min(kmin, b / (p.kappa * p.kappa));
    kmax = std::max(kmax, b / (p.kappa * p.kappa));
    tw = std::max(tw, std::abs(p.tangent.dot(h)));
    rg = std::max(rg, w * std::abs(p.normal.dot(h)));
  }
  if (!(mn > 0)) {
    out.status = LineComplexStatus::SolverFailed;
    out.message = "line complex LP returned a complex that meets a binormal line (min = " +
                  std::to_string(mn) + ")";
    return out;
  }
  out.c = c / mn;
  out.c_bar = cb / mn;
  out.twist_ratio = tw / (mn * nz.L);
  out.R = std::max(tw, rg) / (mn * nz.L);
  out.stiffness_ratio = kmax / kmin;
  out.parallel = out.twist_ratio <= options.parallel_tolerance;
  out.status = LineComplexStatus::Feasible;
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

}  // namespace parafab
