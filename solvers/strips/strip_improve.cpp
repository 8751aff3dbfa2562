#include "strips/strip_improve.h"

#include <Eigen/Dense>
#include <algorithm>
#include <chrono>
#include <optional>
#include <cmath>
#include <sstream>

#include "common/error.h"
#include "common/plane_curve.h"
#include "strips/curve_fairing.h"
#include "strips/stiffness_lp.h"

namespace parafab {

namespace {
using Clock = std::chrono::steady_clock;
double since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }
double det(const Vec2& a, const Vec2& b) { return a.x() * b.y() - a.y() * b.x(); }

CurvePoint to_curve_point(const PoleJet& J) {
  CurvePoint p;
  p.u = J.u;
  p.point = J.d[0];
  p.tangent = J.tangent;
  p.kappa = J.kappa;
  p.dkappa_ds = J.dkappa_ds;
  return p;
}

// Parameters equally spaced in arc length.
std::vector<double> arc_length_parameters(const BSplineCurve2& curve, int n) {
  const PlaneCurve pc(curve);
  std::vector<double> u(n);
  for (int i = 0; i < n; ++i) u[i] = pc.parameter_at(pc.length() * i / (n - 1));
  return u;
}

double chord_length(const BSplineCurve2& c, int n = 64) {
  double l = 0;
  Vec2 prev = c.point(c.first_parameter());
  for (int i = 1; i <= n; ++i) {
    const Vec2 p = c.point(c.first_parameter() + (c.last_parameter() - c.first_parameter()) * i / n);
    l += (p - prev).norm();
    prev = p;
  }
  return l;
}

// ∂t₀/∂P_j[c] = −∂det(γ',γ'')/∂P_j[c] / det(γ',γ''') at an inflection.
double dt0(const PoleJet& J, int j, int c) {
  Vec2 e = Vec2::Zero();
  e(c) = 1;
  const double dD2 = det(J.basis.N[1][j] * e, J.d[2]) + det(J.d[1], J.basis.N[2][j] * e);
  return -dD2 / det(J.d[1], J.d[3]);
}

// K of the line (a, b) at every sample: max/min, or NaN if some K ≤ 0.
double line_ratio(const BSplineCurve2& curve, double a, const Vec2& b, const std::vector<double>& u,
                  const std::vector<double>& infl, double length) {
  double kmin = INFINITY, kmax = 0;
  for (double x : u) {
    const auto d = curve.derivatives(x);
    const double v = d[1].norm(), kappa = det(d[1], d[2]) / (v * v * v);
    if (std::abs(kappa) * length <= 1e-7) continue;
    const double K = (a + b.dot(d[0])) / kappa;
    if (!(K > 0)) return NAN;
    kmin = std::min(kmin, K), kmax = std::max(kmax, K);
  }
  for (double x : infl) {
    const PoleJet J = pole_jet(curve, x);
    const double K = b.dot(J.tangent) / J.dkappa_ds;
    if (!(K > 0)) return NAN;
    kmin = std::min(kmin, K), kmax = std::max(kmax, K);
  }
  return kmax / kmin;
}
}  // namespace

LpRatioGradient lp_ratio_gradient(const BSplineCurve2& curve, const std::vector<double>& sample_u,
                                  const std::vector<double>& inflection_u) {
  LpRatioGradient out;
  const double l = chord_length(curve);
  std::vector<PoleJet> sj, zj;
  std::vector<CurvePoint> samples, zeros;
  for (double u : sample_u) {
    PoleJet J = pole_jet(curve, u);
    if (std::abs(J.kappa) * l <= 1e-7) continue;
    bool near = false;
    for (double z : inflection_u) near |= std::abs(z - u) <= 1e-9 * (curve.last_parameter() - curve.first_parameter());
    if (near) continue;
    samples.push_back(to_curve_point(J));
    sj.push_back(J);
  }
  for (double u : inflection_u) {
    zj.push_back(pole_jet(curve, u));
    zeros.push_back(to_curve_point(zj.back()));
  }
  std::vector<Vec2> line_points;
  std::vector<int> line_zero;
  if (!zeros.empty()) {
    line_points.push_back(zeros.front().point), line_zero.push_back(0);
    if (zeros.size() >= 2)
      line_points.push_back(zeros.back().point), line_zero.push_back(static_cast<int>(zeros.size()) - 1);
  }
  const StiffnessLpResult lp = solve_stiffness_lp(samples, zeros, line_points, l);
  if (!lp.ok()) {
    out.message = "LP Eq. 4.4: " + std::string(to_string(lp.status)) + (lp.message.empty() ? "" : ": " + lp.message);
    return out;
  }
  out.ok = true;
  out.R = lp.R;
  out.objective = lp.objective;
  out.a = lp.a, out.b = lp.b;
  const double L = lp.scale, Rs = lp.objective;
  const Vec2 bh = lp.normalized_line.tail<2>();
  const Vec2 c = lp.center;
  out.gradient.setZero(2 * curve.pole_count());
  auto add = [&](const PoleJet& J, int j, int coord, double v) { out.gradient(2 * (J.basis.first + j) + coord) += v; };
  const int n = static_cast<int>(samples.size());
  for (int i = 0; i < n; ++i) {
    const PoleJet& J = sj[i];
    const double sg = J.kappa > 0 ? 1.0 : -1.0, ylo = lp.dual_rows(2 * i), yup = lp.dual_rows(2 * i + 1);
    if (ylo == 0 && yup == 0) continue;
    for (int j = 0; j < J.count; ++j)
      for (int cc = 0; cc < 2; ++cc) {
        const double dlin = sg * bh(cc) * J.basis.N[0][j] / L, dk = sg * L * J.dkappa[j](cc);
        add(J, j, cc, -(ylo * (dlin - dk) + yup * (-dlin + Rs * dk)));
      }
  }
  for (size_t k = 0; k < zj.size(); ++k) {
    const PoleJet& J = zj[k];
    const double ylo = lp.dual_rows(2 * n + 2 * k), yup = lp.dual_rows(2 * n + 2 * k + 1);
    const double sg = J.dkappa_ds > 0 ? 1.0 : -1.0;
    const Vec2 nrm(-J.tangent.y(), J.tangent.x());
    const Vec2 t_u = J.kappa * J.speed * nrm;  // 0 at an inflection, kept for completeness
    const double hu = 1e-6 * (curve.last_parameter() - curve.first_parameter());
    const double ks_u = (pole_jet(curve, J.u + hu).dkappa_ds - pole_jet(curve, J.u - hu).dkappa_ds) / (2 * hu);
    for (int j = 0; j < J.count; ++j)
      for (int cc = 0; cc < 2; ++cc) {
        const double du = dt0(J, j, cc);
        const double dbt = bh.dot(J.dtangent[j].col(cc) + t_u * du);
        const double dks = L * L * (J.ddkappa_ds[j](cc) + ks_u * du);
        if (ylo != 0 || yup != 0) add(J, j, cc, -(ylo * (sg * dbt - sg * dks) + yup * (-sg * dbt + Rs * sg * dks)));
      }
  }
  for (size_t e = 0; e < line_zero.size(); ++e) {
    const PoleJet& J = zj[line_zero[e]];
    const double z = lp.dual_line(e);
    for (int j = 0; j < J.count; ++j)
      for (int cc = 0; cc < 2; ++cc)
        add(J, j, cc, -z * (bh(cc) * J.basis.N[0][j] + bh.dot(J.d[1]) * dt0(J, j, cc)) / L);
  }
  (void)c;
  return out;
}

PoleDescentResult descend_poles(const BSplineCurve2& input, const PoleObjective& F, const PoleDescentOptions& o) {
  const auto t0 = Clock::now();
  PARAFAB_VERIFY(o.samples >= 8, "descent: samples must be >= 8, got " << o.samples);
  PARAFAB_VERIFY(o.p >= 1, "descent: p must be >= 1, got " << o.p);
  PARAFAB_VERIFY(o.quasi_halvings >= 0, "descent: quasi_halvings must be >= 0, got " << o.quasi_halvings);
  PARAFAB_VERIFY(o.bound_returns >= 0, "descent: bound_returns must be >= 0, got " << o.bound_returns);
  PoleDescentResult res(input);
  BSplineCurve2 curve = input;
  const std::vector<double> su = arc_length_parameters(curve, o.samples);
  std::vector<double> infl = inflection_parameters(curve);
  const double l = PlaneCurve(curve).length();
  // The line L: through the first and last inflection (≥ 2), else LP Eq. 4.4's optimum.
  double a = 0;
  Vec2 b(0, 0);
  if (infl.size() >= 2) {
    const Vec2 p = curve.point(infl.front()), q = curve.point(infl.back());
    b = Vec2(-(q - p).y(), (q - p).x()).normalized();
    a = -b.dot(p);
    if (!(line_ratio(curve, a, b, su, infl, l) > 0)) a = -a, b = -b;
  } else {
    const LpRatioGradient g = lp_ratio_gradient(curve, su, infl);
    if (!g.ok) {
      res.status = "constraints_failed";
      res.message = "no admissible line for the input curve: " + g.message;
      return res;
    }
    a = g.a, b = g.b;
  }
  StripConstraints cons(curve, a, b, infl, o.constraints);
  {
    const EnforceResult er = cons.enforce(curve);
    if (!er.converged) {
      res.status = "constraints_failed";
      res.message = "the input curve does not satisfy the constraints: " + er.message;
      return res;
    }
  }
  const Eigen::VectorXd q_orig = poles_vector(input);
  auto max_move = [&](const BSplineCurve2& c) {
    const Eigen::VectorXd d = poles_vector(c) - q_orig;
    double m = 0;
    for (int i = 0; i < c.pole_count(); ++i) m = std::max(m, d.segment<2>(2 * i).norm());
    return m;
  };
  auto min_dk = [&](const BSplineCurve2& c, const std::vector<double>& z) {
    double m = NAN;
    for (double u : z) {
      const double v = std::abs(pole_jet(c, u).dkappa_ds) * l * l;
      m = std::isnan(m) ? v : std::min(m, v);
    }
    return m;
  };
  const bool bounded = std::isfinite(o.R_max);
  Eigen::VectorXd gF;
  double f = F(curve, cons, &gF);
  PNormRatio Rp = pnorm_ratio(curve, cons.a(), cons.b(), su, o.p, l);
  auto record = [&](int it, double step) {
    PoleDescentIteration h;
    h.iteration = it;
    h.F = f;
    h.R = line_ratio(curve, cons.a(), cons.b(), su, cons.inflections(), l);
    h.R_p = Rp.value;
    h.step = step;
    h.max_pole_move = max_move(curve);
    h.min_inflection_dkappa = min_dk(curve, cons.inflections());
    h.seconds = since(t0);
    res.history.push_back(h);
    return &res.history.back();
  };
  if (record(0, 0)->R <= 0) {}
  if (o.on_accept && o.on_accept(curve, cons, res.history.back())) {
    res.converged = true;
    res.status = "target";
  }
  // Quasi-Newton in the tangent space: L-BFGS on the projected gradients of accepted steps
  // (pairs s = Δq, y = ΔP∇F), the direction projected onto T_qM; steepest descent of length
  // initial_step·l whenever the memory is empty or gives no descent direction.
  std::vector<Eigen::VectorXd> S, Y;
  const int memory = std::max(0, o.memory);
  double t = 1.0;  // step multiplier on the current direction
  // The projection onto T_qM at the current iterate, factored once per iterate.
  Eigen::MatrixXd Jc;
  Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd> cod;
  auto refactor = [&] {
    Eigen::VectorXd G;
    cons.evaluate(curve, G, Jc);
    if (Jc.rows() > 0) cod.compute(Jc);
  };
  auto project = [&](const Eigen::VectorXd& v) -> Eigen::VectorXd {
    return Jc.rows() > 0 ? Eigen::VectorXd(v - cod.solve(Jc * v)) : v;
  };
  refactor();
  Eigen::VectorXd g = project(gF);
  Eigen::VectorXd dir;
  bool new_direction = true;
  int accepted = 0;
  for (int it = 1; res.status.empty(); ++it) {
    if (accepted >= o.max_iterations) { res.status = "max_iterations"; break; }
    if (o.max_seconds > 0 && since(t0) > o.max_seconds) { res.status = "time"; break; }
    if (new_direction) {
      const double gn = g.norm();
      if (!(gn > 0)) { res.status = "stationary"; res.converged = true; break; }
      dir = -g;
      bool quasi = !S.empty();
      if (quasi) {  // two-loop recursion
        std::vector<double> alpha(S.size());
        for (int k = static_cast<int>(S.size()) - 1; k >= 0; --k) {
          alpha[k] = S[k].dot(dir) / Y[k].dot(S[k]);
          dir -= alpha[k] * Y[k];
        }
        dir *= S.back().dot(Y.back()) / Y.back().squaredNorm();
        for (size_t k = 0; k < S.size(); ++k) dir += (alpha[k] - Y[k].dot(dir) / Y[k].dot(S[k])) * S[k];
        dir = project(dir);
        if (!(dir.dot(g) < -1e-12 * dir.norm() * gn)) quasi = false, S.clear(), Y.clear(), dir = -g;
      }
      if (!quasi) dir *= o.initial_step * l / gn;
      const double cap = o.max_step * l;
      if (dir.norm() > cap) dir *= cap / dir.norm();
      t = 1.0;
      new_direction = false;
    }
    Eigen::VectorXd dq = t * dir;
    if (bounded && Rp.valid) {
      const Eigen::VectorXd gR = project(Rp.gradient);
      const Eigen::VectorXd full = dq;
      dq = project_step(dq, Rp.value, gR, o.R_max);
      // On the bound with the step pointing out of it: a KKT point of min F s.t. R_p ≤ R_max.
      if (dq.norm() <= 1e-6 * full.norm()) { res.status = "stationary"; res.converged = true; break; }
    }
    BSplineCurve2 trial = curve;
    StripConstraints tc = cons;
    set_poles_vector(trial, poles_vector(curve) + dq);
    const EnforceResult er = tc.enforce(trial);
    const size_t n_infl = er.converged ? inflection_parameters(trial).size() : 0;
    bool ok = er.converged && n_infl == cons.inflections().size();
    if (!er.converged) res.last_rejection = "EnforceConstraints: " + er.message;
    else if (!ok) res.last_rejection = "the step changes the number of inflections to " + std::to_string(n_infl);
    double ft = NAN;
    Eigen::VectorXd gt;
    PNormRatio Rt;
    if (ok) {  // without the bound K may change sign: the failure mode the bound prevents
      Rt = pnorm_ratio(trial, tc.a(), tc.b(), su, o.p, l);
      ok = Rt.valid || !bounded;
      if (!ok) res.last_rejection = "K changes sign on the samples (the line meets the curve)";
    }
    if (ok && bounded) {  // before F: R_p is cheap, F designs the strip (and may run a stability test)
      const double R_allowed = std::max(o.R_max * (1 + o.bound_tolerance), Rp.value * (1 + 1e-3));
      // The linearized ProjectStep overshoots where the bound curves; instead of halving the
      // step, return onto R_p = R_max along the projected ∇R_p at the trial (Newton on the one
      // active constraint, §4.5.4's step projection repeated at the new point).
      std::string return_blocked;  // why a return left the manifold (then the trial is blocked, not too high)
      for (int k = 0; k < o.bound_returns && Rp.valid && Rt.valid && Rt.value > R_allowed; ++k) {
        Eigen::VectorXd G;
        Eigen::MatrixXd Jt;
        if (!tc.evaluate(trial, G, Jt)) { return_blocked = "the constraints cannot be evaluated"; break; }
        Eigen::VectorXd gR = Rt.gradient;
        if (Jt.rows() > 0) gR -= Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd>(Jt).solve(Jt * gR);
        const double g2 = gR.squaredNorm();
        if (!(g2 > 0)) break;
        BSplineCurve2 back = trial;
        StripConstraints bc = tc;
        set_poles_vector(back, poles_vector(trial) - ((Rt.value - o.R_max) / g2) * gR);
        const EnforceResult eb = bc.enforce(back);
        if (!eb.converged) { return_blocked = "EnforceConstraints: " + eb.message; break; }
        if (inflection_parameters(back).size() != cons.inflections().size()) {
          return_blocked = "it changes the number of inflections";
          break;
        }
        const PNormRatio Rb = pnorm_ratio(back, bc.a(), bc.b(), su, o.p, l);
        if (!Rb.valid || !(Rb.value < Rt.value)) break;
        trial = std::move(back), tc = std::move(bc), Rt = Rb;
        ++res.bound_returns;
      }
      ok = Rp.valid && Rt.valid && Rt.value <= R_allowed;
      // A return that left the manifold blocks the step (stalled if nothing else is left); one
      // that could not lower R_p enough leaves it above the bound (stationary: a KKT point).
      if (!ok) res.last_rejection = return_blocked.empty() ? "R_p exceeds R_max after the step"
                                                           : "returning onto R_max: " + return_blocked;
    }
    if (ok) {
      ft = F(trial, tc, &gt);
      ok = std::isfinite(ft) && ft < f - 1e-4 * std::abs(gF.dot(dq));
      if (!ok) res.last_rejection = "no sufficient decrease of F";
    }
    if (!ok) {
      ++res.rejected_steps;
      t *= 0.5;
      // A quasi-Newton direction that still fails after quasi_halvings halvings is dropped for
      // steepest descent (on the bound the pairs mix curvature of F with that of the bound).
      if (t * dir.norm() < o.min_step * l || (!S.empty() && t < std::ldexp(1.0, -o.quasi_halvings))) {
        if (!S.empty()) {  // retry from steepest descent before giving up
          S.clear(), Y.clear();
          new_direction = true;
          continue;
        }
        // No admissible step left. Stationary if the objective cannot decrease; stalled at
        // the edge of the equilibrium manifold if the constraints or the inflection count
        // block every step (the failure mode the R_max bound prevents, §4.5.4).
        const bool blocked = res.last_rejection.rfind("no sufficient decrease", 0) != 0 &&
                             res.last_rejection.rfind("R_p exceeds", 0) != 0;
        res.status = blocked ? "stalled" : "stationary";
        res.converged = !blocked;
        res.message = res.last_rejection;
      }
      continue;
    }
    const Eigen::VectorXd q_old = poles_vector(curve), g_old = g;
    curve = trial;
    cons = tc;
    ++accepted;
    f = ft;
    gF = gt;
    Rp = Rt;
    PoleDescentIteration* rec = record(accepted, (poles_vector(curve) - q_old).norm());  // after enforce and returns
    const double a_before = cons.a();
    const Vec2 b_before = cons.b();
    const bool stop = o.on_accept && o.on_accept(curve, cons, *rec);
    // The hook may have moved the line (global step): refresh F, and drop the memory, which
    // belongs to the old objective.
    const bool line_moved = cons.a() != a_before || cons.b() != b_before;
    if (line_moved) {
      f = F(curve, cons, &gF);
      Rp = pnorm_ratio(curve, cons.a(), cons.b(), su, o.p, l);
    }
    refactor();
    g = project(gF);
    if (stop) {
      res.converged = true;
      res.status = "target";
      break;
    }
    if (line_moved) S.clear(), Y.clear();
    else if (memory > 0) {
      const Eigen::VectorXd sk = poles_vector(curve) - q_old, yk = g - g_old;
      if (sk.dot(yk) > 1e-12 * sk.norm() * yk.norm()) {
        S.push_back(sk), Y.push_back(yk);
        if (static_cast<int>(S.size()) > memory) S.erase(S.begin()), Y.erase(Y.begin());
      }
    }
    new_direction = true;
  }
  res.curve = curve;
  res.a = cons.a();
  res.b = cons.b();
  res.inflections = cons.inflections();
  res.seconds = since(t0);
  return res;
}

namespace {
// Distance from x to the curve Y, given n samples (yu, yp) of Y: the nearest sample, refined
// by Newton on ⟨Y(u) − x, Y'(u)⟩ = 0.
double distance_to_curve(const BSplineCurve2& Y, const std::vector<double>& yu, const std::vector<Vec2>& yp,
                         const Vec2& x) {
  size_t best = 0;
  for (size_t k = 1; k < yp.size(); ++k)
    if ((yp[k] - x).squaredNorm() < (yp[best] - x).squaredNorm()) best = k;
  double u = yu[best];
  for (int it = 0; it < 20; ++it) {
    const auto d = Y.derivatives(u);
    const double g = (d[0] - x).dot(d[1]), hh = d[1].squaredNorm() + (d[0] - x).dot(d[2]);
    if (hh <= 0) break;
    const double un = std::clamp(u - g / hh, Y.first_parameter(), Y.last_parameter());
    if (std::abs(un - u) < 1e-15) { u = un; break; }
    u = un;
  }
  return std::min((Y.point(u) - x).norm(), (yp[best] - x).norm());
}

void sample_curve(const BSplineCurve2& Y, int n, std::vector<double>& yu, std::vector<Vec2>& yp) {
  yu.resize(n), yp.resize(n);
  for (int i = 0; i < n; ++i) {
    yu[i] = Y.first_parameter() + (Y.last_parameter() - Y.first_parameter()) * i / (n - 1);
    yp[i] = Y.point(yu[i]);
  }
}
}  // namespace

double curve_deviation(const BSplineCurve2& A, const BSplineCurve2& B, int samples) {
  auto one_sided = [&](const BSplineCurve2& X, const BSplineCurve2& Y) {
    const int n = std::max(8, samples);
    std::vector<Vec2> yp;
    std::vector<double> yu;
    sample_curve(Y, n, yu, yp);
    double worst = 0;
    for (int i = 0; i < n; ++i)
      worst = std::max(worst, distance_to_curve(Y, yu, yp, X.point(X.first_parameter() +
                                                                     (X.last_parameter() - X.first_parameter()) * i / (n - 1))));
    return worst;
  };
  return std::max(one_sided(A, B), one_sided(B, A));
}

double points_deviation(const std::vector<Vec2>& points, const BSplineCurve2& curve, int samples) {
  std::vector<Vec2> yp;
  std::vector<double> yu;
  sample_curve(curve, std::max(8, samples), yu, yp);
  double worst = 0;
  for (const Vec2& x : points) worst = std::max(worst, distance_to_curve(curve, yu, yp, x));
  return worst;
}

std::string gravity_target_shortfall(double R_estimate, double target_R, bool gravity_feasible, double R_gravity,
                                     const std::string& infeasible_reason) {
  if (gravity_feasible && R_gravity <= target_R) return {};
  std::ostringstream m;
  m << "R without gravity " << R_estimate << " <= target " << target_R << ", but the requested design "
    << "under gravity (LP Eq. 4.6, accounted for afterwards, §4.6.2) has ";
  if (gravity_feasible) m << "R_gravity " << R_gravity << " > target";
  else m << "no feasible design (" << infeasible_reason << ")";
  return m.str();
}

StripImproveResult improve_strip_fabricability(const BSplineCurve2& input, const StripImproveOptions& o) {
  const auto t0 = Clock::now();
  PARAFAB_VERIFY(std::isfinite(o.target_R) && o.target_R >= 1,
                 "target_R must be a ratio >= 1, got " << o.target_R);
  PARAFAB_VERIFY(!input.rational(), "curve.bspline.weights: fabricability optimization moves the poles of a "
                                    "non-rational B-spline; give the curve without weights");
  // The descent lowers R_p of LP Eq. 4.4 (clamped ends, κ₀ = 0, linear law, §4.3.2); a design
  // with other ends, a natural curvature or a nonlinear law has another LP (§4.3.3, App. A.5),
  // whose R the descent does not lower: refused rather than reported as done on Eq. 4.4.
  // Gravity is accounted for afterwards (Eq. 4.6, §4.6.2) and `done` tests that design.
  if (!o.design.boundary.kinematic())
    PARAFAB_INPUT_ERROR("boundary: fabricability optimization (thesis §4.6.2) lowers R of LP Eq. 4.4 with "
                        "clamped ends; free ends are not supported, remove \"boundary\" (or its free_x / free_y / "
                        "free_angle) from the request");
  if (o.design.natural_curvature != 0)
    PARAFAB_INPUT_ERROR("natural_curvature: fabricability optimization (thesis §4.6.2) lowers R of LP Eq. 4.4 "
                        "without natural curvature, got " << o.design.natural_curvature << " 1/m; remove it");
  if (!o.design.law.linear())
    PARAFAB_INPUT_ERROR("material.law: fabricability optimization (thesis §4.6.2) lowers R of LP Eq. 4.4 with "
                        "the linear moment law; remove material.law");
  StripImproveResult res(input);
  BSplineCurve2 curve = input;
  if (curve.degree() < o.min_degree) {  // control points of degree ≥ 4 (thesis §4.5.4)
    FairFitOptions fo;
    fo.degree = o.min_degree;
    fo.poles = o.fit_poles > 0 ? o.fit_poles : curve.pole_count() + 2;
    fo.fairness = 1e-7;
    const PlaneCurve pc(input);
    std::vector<Vec2> pts;
    for (int i = 0; i < 400; ++i) pts.push_back(pc.at_arc_length(pc.length() * i / 399).point);
    curve = fit_fair_bspline(pts, fo).curve;
    res.refit = true;
    res.refit_deviation = curve_deviation(input, curve, o.deviation_samples);
  }
  StripDesignOptions plain = o.design;
  plain.gravity = StripGravity{};
  // R as the target test sees it: the estimate R_continuous of the ratio of the LP's line on the
  // continuous curve (sampled extrema refined; an estimate, not a certified bound), so that a
  // finer design of the result stays ≤ target unless a peak of K hides between samples.
  auto estimate = [](const StripDesign& d) { return std::isfinite(d.R_continuous) ? d.R_continuous : d.R; };
  const StripDesign d0 = design_strip(curve, plain);
  if (!d0.feasible)
    PARAFAB_INPUT_ERROR("curve: not an equilibrium curve, so there is no R to lower (" << d0.reason_code << ": "
                        << d0.reason << "); remove spurious inflections first (strip-improve \"fair\")");
  res.R_initial = d0.R;
  const double l = d0.length;
  std::vector<double> infl = inflection_parameters(curve);
  std::optional<StripDesign> last;  // the plain design of the current result, when known
  if (estimate(d0) <= o.target_R) {
    res.done = true;
    res.status = "already";
    res.curve = curve;
    res.R = d0.R;
  } else {
    PoleDescentOptions po;
    po.max_iterations = o.max_iterations;
    po.p = o.p;
    po.samples = o.samples;
    po.initial_step = o.initial_step;
    po.max_seconds = o.max_seconds;
    po.constraints = o.constraints;
    const std::vector<double> su = arc_length_parameters(curve, o.samples);
    int since_global = 0;
    double target_now = o.target_R;
    po.on_accept = [&](BSplineCurve2& c, StripConstraints& cons, PoleDescentIteration& rec) {
      if (cons.inflections().size() >= 2) return rec.R <= target_now;
      if (rec.iteration > 0 && ++since_global < o.global_every && rec.R > target_now) return false;
      since_global = 0;
      // Global step: LP Eq. 4.4 for (a, b) with the poles fixed.
      const LpRatioGradient g = lp_ratio_gradient(c, su, cons.inflections());
      if (g.ok && g.R < rec.R) {
        cons.set_line(g.a, g.b);
        rec.R = g.R;
      }
      return rec.R <= target_now;
    };
    // Local objective: log R_p of the current line.
    const PoleObjective F = [&](const BSplineCurve2& c, const StripConstraints& cons, Eigen::VectorXd* grad) {
      const PNormRatio r = pnorm_ratio(c, cons.a(), cons.b(), su, o.p, l);
      if (!r.valid) return static_cast<double>(NAN);
      if (grad) *grad = r.gradient / r.value;
      return std::log(r.value);
    };
    // The descent stops on the samples' R; the estimated R of the design may sit slightly
    // above (a peak between samples): then continue with the sample target lowered by the excess.
    BSplineCurve2 current = curve;
    double sample_target = o.target_R;
    for (int round = 0; round < 4; ++round) {
      const PoleDescentResult dr = descend_poles(current, F, po);
      const double offset = res.history.empty() ? 0.0 : res.history.back().seconds;
      for (auto h : dr.history) {
        if (!res.history.empty() && h.iteration == 0) continue;
        h.seconds += offset;
        h.iteration = static_cast<int>(res.history.size());
        res.history.push_back(h);
      }
      res.status = dr.status;
      res.message = dr.message.empty() ? dr.last_rejection : dr.message;
      current = dr.curve;
      last.reset();
      if (dr.status != "target") break;
      last = design_strip(current, plain);
      if (!last->feasible || estimate(*last) <= o.target_R) break;
      sample_target *= o.target_R / estimate(*last) * 0.999;
      target_now = sample_target;
    }
    res.curve = current;
  }
  // Final figures: the design of the result (tolerance 1e-3), and the requested design (gravity:
  // LP Eq. 4.6 afterwards, §4.6.2).
  const StripDesign d1 = last ? *last : (res.status == "already" ? d0 : design_strip(res.curve, plain));
  res.R = d1.feasible ? d1.R : NAN;
  res.R_estimate = d1.feasible ? estimate(d1) : NAN;
  res.done = d1.feasible && res.R_estimate <= o.target_R;
  if (!res.done && res.status == "target") res.status = "target_on_samples";
  const bool same = !o.design.gravity.enabled;  // plain == o.design then
  res.design = same ? d1 : design_strip(res.curve, o.design);
  if (o.design.gravity.enabled) {
    // done is the requested design's: R under gravity (a sampled optimum on nested grids,
    // §4.4) must meet the target too, not only R of Eq. 4.4 that the descent lowered.
    res.R_gravity = res.design.feasible ? res.design.R : NAN;
    const std::string shortfall =
        gravity_target_shortfall(res.R_estimate, o.target_R, res.design.feasible, res.R_gravity, res.design.reason);
    if (res.done && !shortfall.empty()) {
      res.done = false;
      res.status = "target_without_gravity";
      res.message = shortfall;
    }
  }
  res.inflections = static_cast<int>(inflection_parameters(res.curve).size());
  {
    const Eigen::VectorXd d = poles_vector(res.curve) - poles_vector(curve);
    for (int i = 0; i < res.curve.pole_count(); ++i)
      res.max_pole_move = std::max(res.max_pole_move, d.segment<2>(2 * i).norm());
  }
  res.deviation = curve_deviation(input, res.curve, o.deviation_samples);
  res.deviation_relative = res.deviation / l;
  res.seconds = since(t0);
  (void)infl;
  return res;
}

}  // namespace parafab
