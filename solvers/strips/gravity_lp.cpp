#include "strips/gravity_lp.h"

#include <Eigen/Dense>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <sstream>

#include "common/error.h"

namespace parafab {

double total_variation_of_derivative(const std::vector<double>& s, const std::vector<double>& K) {
  double tv = 0;
  for (size_t i = 1; i + 1 < K.size(); ++i) {
    const double d1 = (K[i + 1] - K[i]) / (s[i + 1] - s[i]);
    const double d0 = (K[i] - K[i - 1]) / (s[i] - s[i - 1]);
    tv += std::abs(d1 - d0);
  }
  return tv;
}

namespace {

using Row3 = Eigen::RowVector3d;
using Rows3 = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;
using Clock = std::chrono::steady_clock;
double since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

// The affine maps x = (â, b̂₁, b̂₂) ↦ K_i = Num_i x / den_i of the backward sweep, in
// normalized coordinates (γ̂ = (γ − c)/l, ŝ = s/l, μ̂ = μ l, ê = e l³).
struct Sweep {
  Rows3 num, A, Phi;       // Num_i, A_i = Num_i/den_i, F̂_i = Φ_i x
  Eigen::VectorXd den, sh;
  std::vector<Row3> equalities;
};

Sweep backward_sweep(const std::vector<StripLpSample>& smp, const Vec2& c, double l,
                     const Vec2& eh) {
  const int n = static_cast<int>(smp.size());
  const Vec2 Re(-eh.y(), eh.x());
  Sweep w;
  w.num.resize(n, 3);
  w.A.resize(n, 3);
  w.Phi.resize(n, 3);
  w.den.resize(n);
  w.sh.resize(n);
  Row3 Psi_next = Row3::Zero();
  double c_next = 0;
  for (int i = n - 1; i >= 0; --i) {
    const Vec2 g = (smp[i].point - c) / l;
    const double ci = Re.dot(g), di = Re.dot(smp[i].tangent);
    w.sh(i) = smp[i].s / l;
    const Row3 P(1.0, g.x(), g.y());
    Row3 Fnext = Row3::Zero(), Gnext = Row3::Zero();
    double h = 0;
    if (i < n - 1) {
      h = w.sh(i + 1) - w.sh(i);
      const double wn = smp[i + 1].weight;
      Fnext = w.Phi.row(i + 1) + 0.5 * h * wn * w.A.row(i + 1);
      Gnext = Psi_next + 0.5 * h * c_next * wn * w.A.row(i + 1);
    }
    // rhs = a + ⟨b, γ⟩ + c_i F_i − G_i; the K_i terms of the trapezoid cancel.
    const Row3 rhs = P + ci * Fnext - Gnext;
    if (!smp[i].zero) {
      w.num.row(i) = rhs;
      w.den(i) = smp[i].mu * l;
    } else {
      w.equalities.push_back(rhs);
      w.num.row(i) = Row3(0.0, smp[i].tangent.x(), smp[i].tangent.y()) + di * Fnext;
      w.den(i) = smp[i].dmu_ds * l * l - 0.5 * di * h * smp[i].weight;
    }
    w.A.row(i) = w.num.row(i) / w.den(i);
    w.Phi.row(i) = Fnext + 0.5 * h * smp[i].weight * w.A.row(i);
    Psi_next = Gnext + 0.5 * h * ci * smp[i].weight * w.A.row(i);
    c_next = ci;
  }
  return w;
}

// Input-units line (a, b) from normalized x (see stiffness_lp.cpp).
void to_line(const Eigen::Vector3d& x, const Vec2& c, double l, double& a, Vec2& b) {
  const Vec2 bh(x(1), x(2));
  a = (x(0) - bh.dot(c) / l) / l;
  b = bh / (l * l);
}

}  // namespace

GravityLpResult solve_gravity_lp(const std::vector<StripLpSample>& samples_in, double length,
                                 const GravityLpOptions& o) {
  const auto t0 = Clock::now();
  PARAFAB_VERIFY(length > 0 && std::isfinite(length),
                 "gravity LP: curve length must be positive, got " << length);
  PARAFAB_VERIFY(o.smoothing_margin >= 0, "smoothing_margin must be >= 0, got " << o.smoothing_margin);
  std::vector<StripLpSample> smp;
  smp.reserve(samples_in.size());
  for (const auto& p : samples_in)
    if (o.inflection_rows || !p.zero) smp.push_back(p);
  const int n = static_cast<int>(smp.size());
  PARAFAB_VERIFY(n >= 3, "gravity LP needs at least 3 samples, got " << n);
  for (int i = 1; i < n; ++i)
    PARAFAB_VERIFY(smp[i].s > smp[i - 1].s, "gravity LP: samples must be sorted by strictly "
                                            "increasing s; sample " << i << " has s = " << smp[i].s
                                            << " after " << smp[i - 1].s);
  for (int i = 0; i < n; ++i)
    PARAFAB_VERIFY(smp[i].zero || smp[i].mu != 0.0,
                   "gravity LP: sample " << i << " at s = " << smp[i].s
                                         << " has zero curvature but is not marked as a zero");
  const double l = length;
  Vec2 c = Vec2::Zero();
  for (const auto& p : smp) c += p.point;
  c /= n;
  const Vec2 eh = o.load * (l * l * l);
  Sweep w = backward_sweep(smp, c, l, eh);

  // Boundary rows (§4.3.3): n(l) = Rᵀb, n(0) = Rᵀb + e F(0); a free direction d at an end
  // has ⟨d, n⟩ = 0 there. Rᵀb̂ = (b̂₂, −b̂₁).
  const Row3 nx_l(0, 0, 1), ny_l(0, -1, 0);
  auto add_free = [&](const StripEnd& end, bool at_start) {
    if (end.free_x) w.equalities.push_back(at_start ? Row3(nx_l + eh.x() * w.Phi.row(0)) : nx_l);
    if (end.free_y) w.equalities.push_back(at_start ? Row3(ny_l + eh.y() * w.Phi.row(0)) : ny_l);
  };
  add_free(o.boundary.start, true);
  add_free(o.boundary.end, false);

  GravityLpResult out;
  // Equality rows through their SVD: rows with rank ≤ 2 are replaced by an orthonormal basis
  // of their span; a third singular value above the tolerance means no line exists.
  std::vector<Row3> eq;
  if (!w.equalities.empty()) {
    Rows3 M(static_cast<int>(w.equalities.size()), 3);
    for (size_t k = 0; k < w.equalities.size(); ++k)
      M.row(k) = w.equalities[k] / w.equalities[k].norm();
    Eigen::JacobiSVD<Eigen::MatrixXd> svd(M, Eigen::ComputeFullV);
    const Eigen::VectorXd sv = svd.singularValues();
    if (sv.size() >= 3) out.zero_consistency = sv(2) / sv(0);
    for (int k = 0; k < std::min<int>(2, sv.size()); ++k)
      if (sv(k) > o.zero_consistency_tolerance * sv(0)) eq.push_back(svd.matrixV().col(k).transpose());
    if (out.zero_consistency > o.zero_consistency_tolerance) {
      std::ostringstream os;
      os << "the " << w.equalities.size() << " equality rows (zero-curvature points and free "
         << "end directions) admit no common line: σ₃/σ₁ = " << out.zero_consistency
         << " > zero_consistency_tolerance " << o.zero_consistency_tolerance;
      out.status = LpStatus::Infeasible;
      out.message = os.str();
      out.seconds = since(t0);
      return out;
    }
  }
  out.equality_rows = static_cast<int>(eq.size());

  // Phase one: minimize R s.t. 1 ≤ K_i ≤ R, rows multiplied by |den_i|.
  FewVariableLp lp;
  lp.c = Eigen::Vector4d(0, 0, 0, 1);
  lp.G.resize(2 * n, 4);
  lp.h.resize(2 * n);
  for (int i = 0; i < n; ++i) {
    const double sg = w.den(i) > 0 ? 1.0 : -1.0, ad = std::abs(w.den(i));
    lp.G.row(2 * i) << sg * w.num.row(i), 0.0;
    lp.h(2 * i) = ad;
    lp.G.row(2 * i + 1) << -sg * w.num.row(i), ad;
    lp.h(2 * i + 1) = 0.0;
  }
  lp.E.resize(static_cast<int>(eq.size()), 4);
  lp.f = Eigen::VectorXd::Zero(static_cast<int>(eq.size()));
  for (size_t k = 0; k < eq.size(); ++k) lp.E.row(k) << eq[k], 0.0;
  FewVariableLpOptions lo;
  lo.form = o.form;
  if (!o.warm_rows.empty()) {  // samples matched by s (nested grids reuse them bit for bit)
    size_t i = 0;
    for (const auto& [sw, which] : o.warm_rows) {
      while (i < smp.size() && smp[i].s < sw) ++i;
      if (i < smp.size() && smp[i].s == sw) lo.basic_hint.push_back(2 * static_cast<int>(i) + which);
    }
  }
  const auto t1 = Clock::now();
  const FewVariableLpResult r1 = o.phase_one ? *o.phase_one : solve_few_variable_lp(lp, lo);
  out.seconds_first = o.phase_one ? r1.seconds : since(t1);  // reused: when it was solved
  out.iterations_first = r1.iterations;
  out.phase_one_lp = r1;
  for (int j : r1.basic)
    if (j < 2 * n) out.active_rows.emplace_back(smp[j / 2].s, j % 2);
  out.max_violation = r1.max_violation;
  out.status = r1.status;
  out.message = r1.message;
  if (!r1.ok()) {
    out.seconds = since(t0);
    return out;
  }
  std::vector<double> s(n);
  for (int i = 0; i < n; ++i) s[i] = smp[i].s;
  auto profile = [&](const Eigen::Vector3d& x, std::vector<double>& K, double& kmin) {
    const Eigen::VectorXd k = w.A * x;
    K.assign(k.data(), k.data() + n);
    kmin = *std::min_element(K.begin(), K.end());
    const double kmax = *std::max_element(K.begin(), K.end());
    for (double& v : K) v /= kmin;
    return kmax / kmin;
  };
  Eigen::Vector3d x1 = r1.x.head<3>();
  double kmin1 = 1;
  out.R_first = profile(x1, out.K_first, kmin1);
  x1 /= kmin1;
  to_line(x1, c, l, out.a_first, out.b_first);
  out.tv_first = total_variation_of_derivative(s, out.K_first);
  Eigen::Vector3d x = x1;

  if (o.smooth && n >= 3) {
    // Phase two: minimize Σ_j |D_j x| (D_j x = ĥ ΔK′_j, the second difference of K over the
    // spacings times the mean spacing) subject to the rows of phase one with R ≤ R₁(1+ε).
    // K is affine in x ∈ R³, so this is a 3-variable program with n − 2 absolute values,
    // solved by the dense solver from phase one's optimum (feasible here; the primal simplex
    // with long steps over the kinks), in y = x / xs.
    const auto t2 = Clock::now();
    const int nt = n - 2;
    const double hm = (w.sh(n - 1) - w.sh(0)) / (n - 1);
    const double xs = std::max(1e-300, x1.cwiseAbs().maxCoeff());  // x = xs · y
    const double Rb = out.R_first * (1.0 + o.smoothing_margin);
    FewVariableLp lp2;
    lp2.c = Eigen::Vector3d::Zero();
    lp2.G.resize(2 * n, 3);
    lp2.h.resize(2 * n);
    for (int i = 0; i < n; ++i) {  // sg Num x ≥ |den| and −sg Num x ≥ −Rb |den|
      const double sg = w.den(i) > 0 ? 1.0 : -1.0, ad = std::abs(w.den(i));
      lp2.G.row(2 * i) = sg * w.num.row(i) * xs;
      lp2.h(2 * i) = ad;
      lp2.G.row(2 * i + 1) = -sg * w.num.row(i) * xs;
      lp2.h(2 * i + 1) = -Rb * ad;
    }
    lp2.E.resize(static_cast<int>(eq.size()), 3);
    lp2.f = Eigen::VectorXd::Zero(static_cast<int>(eq.size()));
    for (size_t q = 0; q < eq.size(); ++q) lp2.E.row(q) = eq[q] * xs;
    lp2.D.resize(nt, 3);
    for (int j = 0; j < nt; ++j) {
      const int i = j + 1;
      const double h1 = w.sh(i + 1) - w.sh(i), h0 = w.sh(i) - w.sh(i - 1);
      lp2.D.row(j) = hm * xs * ((w.A.row(i + 1) - w.A.row(i)) / h1 - (w.A.row(i) - w.A.row(i - 1)) / h0);
    }
    FewVariableLpOptions lo2;
    lo2.form = o.form;
    lo2.x_hint = x1 / xs;
    out.phase_two_lp = solve_few_variable_lp(lp2, lo2);
    const FewVariableLpResult& r2 = out.phase_two_lp;
    out.iterations_second = r2.iterations;
    if (r2.ok()) {
      const Eigen::Vector3d x2 = r2.x * xs;
      std::vector<double> K2;
      double kmin2 = 1;
      const double R2 = profile(x2, K2, kmin2);
      // Accept only a solution that keeps the rows of phase one within round-off.
      double eqv = 0;
      for (const auto& e : eq) eqv = std::max(eqv, std::abs(e.dot(x2 / kmin2)));
      eqv /= std::max(1.0, (x2 / kmin2).norm());
      if (kmin2 > 0 && R2 <= Rb * (1 + 1e-6) && eqv <= 1e-8) {
        x = x2 / kmin2;
        out.K = std::move(K2);
        out.R = R2;
        out.smoothed = true;
      } else {
        std::ostringstream os;
        os << "phase two rejected (min K " << kmin2 << ", R = " << R2 << " vs bound " << Rb
           << ", equality residual " << eqv << "); phase one returned";
        out.message = os.str();
      }
    } else {
      out.message = "phase two: " + std::string(to_string(r2.status)) + " (" + r2.message + "); phase one returned";
    }
    out.seconds_second = since(t2);
  }
  if (!out.smoothed) {
    out.K = out.K_first;
    out.R = out.R_first;
  }
  to_line(x, c, l, out.a, out.b);
  out.tv = total_variation_of_derivative(s, out.K);
  // End forces for K normalized to min 1: n(l) = Rᵀb, n(0) = Rᵀb + e F(0).
  const Vec2 nl(out.b.y(), -out.b.x());
  out.end_force = nl;
  out.start_force = nl + o.load * (w.Phi.row(0).dot(x) * l);
  out.seconds = since(t0);
  return out;
}

}  // namespace parafab
