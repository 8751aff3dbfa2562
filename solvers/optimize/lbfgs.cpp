// Projected L-BFGS (thesis §6.5.2: quasi-Newton over projected shape parameters).
#include "optimize/lbfgs.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <deque>

#include "common/error.h"

namespace parafab::optimize {

// Minimizer of the cubic through φ(0), φ'(0), φ(1), φ'(1) (Nocedal & Wright, Numerical
// Optimization, §3.5, Eq. 3.59), else of the quadratic through φ(0), φ'(0), φ(1) (Eq. 3.57):
// a stiff penalty whose first step overshoots many times is cut by up to 10 per trial, not 2.
// The lower safeguard 0.1 (Dennis & Schnabel, §6.3.2) keeps a penalty's kink, where the cubic
// through a slope deep in the penalty predicts a far too short step, from shrinking the step
// (and the next curvature pair) by more than that: with 0.01 the L-bracket's volume-bounded run
// crept at 0.025 mm per iteration.
double backtrack_factor(double phi0, double slope0, double phi1, double slope1) {
  double alpha = 0.5;
  const double d1 = slope0 + slope1 + 3 * (phi0 - phi1);
  const double disc = d1 * d1 - slope0 * slope1;
  if (disc >= 0 && std::isfinite(disc)) {
    const double d2 = std::sqrt(disc), den = slope1 - slope0 + 2 * d2;
    if (den != 0) alpha = 1 - (slope1 + d2 - d1) / den;
  } else {
    const double curvature = phi1 - phi0 - slope0;  // > 0 when Armijo failed with slope0 < 0
    if (curvature > 0) alpha = -slope0 / (2 * curvature);
  }
  return std::isfinite(alpha) ? std::clamp(alpha, 0.1, 0.5) : 0.5;
}

LbfgsResult minimize_lbfgs(const ObjectiveFunction& f, const Eigen::VectorXd& x0, const Eigen::VectorXd& lower,
                           const Eigen::VectorXd& upper, const LbfgsOptions& options,
                           const IterateCallback& callback, const ObjectiveFunction& refresh) {
  const int n = static_cast<int>(x0.size());
  PARAFAB_VERIFY(lower.size() == n && upper.size() == n,
                 "L-BFGS: bounds need " << n << " entries, got " << lower.size() << " and " << upper.size());
  PARAFAB_VERIFY(options.memory >= 1 && options.max_iterations >= 0, "L-BFGS: memory must be >= 1");
  const auto t0 = std::chrono::steady_clock::now();
  auto seconds = [&] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(); };
  auto clamp = [&](const Eigen::VectorXd& x) { return Eigen::VectorXd(x.cwiseMax(lower).cwiseMin(upper)); };

  LbfgsResult r;
  Eigen::VectorXd x = clamp(x0), g(n);
  double fx = 0;
  PARAFAB_VERIFY(f(x, fx, g) && std::isfinite(fx), "L-BFGS: the objective cannot be evaluated at the start");
  r.evaluations = 1;
  auto record = [&](int k) {
    r.iterates.push_back({k, fx, x, seconds(), r.evaluations});
    return !callback || callback(r.iterates.back());
  };
  r.status = "max_iterations";
  if (!record(0)) {
    r.status = "cancelled";
  } else {
    std::deque<Eigen::VectorXd> S, Y;
    const double f0 = fx;
    for (int k = 1; k <= options.max_iterations; ++k) {
      // Projected gradient: zero where a bound is active and the gradient pushes outward.
      Eigen::VectorXd pg = g;
      for (int i = 0; i < n; ++i)
        if ((x[i] <= lower[i] && g[i] > 0) || (x[i] >= upper[i] && g[i] < 0)) pg[i] = 0;
      if (pg.lpNorm<Eigen::Infinity>() <= options.gradient_tolerance) {
        r.status = "converged";
        r.message = "projected gradient below tolerance";
        break;
      }
      // Two-loop recursion on the free entries.
      Eigen::VectorXd q = pg;
      std::vector<double> alpha(S.size());
      for (int j = static_cast<int>(S.size()) - 1; j >= 0; --j) {
        alpha[j] = S[j].dot(q) / Y[j].dot(S[j]);
        q -= alpha[j] * Y[j];
      }
      if (!S.empty()) q *= S.back().dot(Y.back()) / Y.back().squaredNorm();
      for (size_t j = 0; j < S.size(); ++j) q += (alpha[j] - Y[j].dot(q) / Y[j].dot(S[j])) * S[j];
      Eigen::VectorXd d = -q;
      for (int i = 0; i < n; ++i)
        if (pg[i] == 0) d[i] = 0;
      if (d.dot(pg) >= 0) d = -pg, S.clear(), Y.clear();  // not a descent direction: restart
      double step = 1.0;
      if (S.empty()) step = options.first_step / std::max(d.lpNorm<Eigen::Infinity>(), 1e-300);
      bool accepted = false;
      Eigen::VectorXd xn, gn(n);
      double fn = 0;
      for (int ls = 0; ls < options.max_line_search; ++ls) {
        xn = clamp(x + step * d);
        const bool ok = f(xn, fn, gn) && std::isfinite(fn);
        ++r.evaluations;
        const double slope0 = g.dot(xn - x);  // φ'(0) along the (clamped) trial step, per unit α
        if (ok && fn <= fx + options.armijo * slope0) {
          accepted = true;
          break;
        }
        step *= ok && gn.allFinite() ? backtrack_factor(fx, slope0, fn, gn.dot(xn - x)) : 0.5;
      }
      if (!accepted) {
        r.status = "line_search_failed";
        r.message = "no sufficient decrease along the search direction";
        break;
      }
      const double improvement = fx - fn;
      if (refresh) {
        double fr = 0;
        Eigen::VectorXd gr(n);
        if (refresh(xn, fr, gr) && std::isfinite(fr)) fn = fr, gn = gr, ++r.evaluations;
      }
      const Eigen::VectorXd s = xn - x, y = gn - g;
      x = xn, g = gn, fx = fn;
      if (s.dot(y) > 1e-12 * s.norm() * y.norm()) {
        S.push_back(s), Y.push_back(y);
        if (static_cast<int>(S.size()) > options.memory) S.pop_front(), Y.pop_front();
      }
      if (!record(k)) {
        r.status = "cancelled";
        r.message = "cancelled by the progress callback";
        break;
      }
      if (improvement <= options.relative_improvement * std::max(std::abs(fx), std::abs(f0) * 1e-12)) {
        r.status = "converged";
        r.message = "relative improvement below " + std::to_string(options.relative_improvement);
        break;
      }
    }
  }
  r.done = r.status == "converged" || r.status == "max_iterations";
  if (r.message.empty()) r.message = r.status;
  r.x = x;
  r.objective = fx;
  r.seconds = seconds();
  return r;
}

}  // namespace parafab::optimize
