// Projected L-BFGS (thesis §6.5.2: quasi-Newton over projected shape parameters).
#include "optimize/lbfgs.h"

#include <chrono>
#include <cmath>
#include <deque>

#include "common/error.h"

namespace parafab::optimize {

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
      for (int ls = 0; ls < options.max_line_search; ++ls, step *= 0.5) {
        xn = clamp(x + step * d);
        const bool ok = f(xn, fn, gn) && std::isfinite(fn);
        ++r.evaluations;
        if (ok && fn <= fx + options.armijo * g.dot(xn - x)) {
          accepted = true;
          break;
        }
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
