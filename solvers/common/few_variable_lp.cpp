#include "common/few_variable_lp.h"

#include <ClpSimplex.hpp>
#include <chrono>
#include <limits>
#include <vector>

#include "common/dense_dual_simplex.h"
#include "common/dense_primal_simplex.h"
#include "common/error.h"

namespace parafab {

const char* to_string(LpStatus status) {
  switch (status) {
    case LpStatus::Optimal: return "optimal";
    case LpStatus::Infeasible: return "infeasible";
    case LpStatus::Unbounded: return "unbounded";
    case LpStatus::Failed: return "failed";
  }
  return "unknown";
}

const char* to_string(LpForm form) {
  switch (form) {
    case LpForm::Dense: return "dense simplex";
    case LpForm::Dual: return "Clp (dual form)";
    case LpForm::Primal: return "Clp (primal form)";
  }
  return "unknown";
}

namespace {

// Clp's model.status(): 0 optimal, 1 primal infeasible, 2 dual infeasible (unbounded),
// 3 stopped on limits, 4 stopped on errors.
const char* clp_status_text(int s) {
  switch (s) {
    case 0: return "optimal";
    case 1: return "primal infeasible";
    case 2: return "dual infeasible (unbounded)";
    case 3: return "stopped on iteration or time limit";
    default: return "stopped on numerical errors";
  }
}

void solve_dual(const FewVariableLp& lp, const FewVariableLpOptions& options,
                FewVariableLpResult& r) {
  const int d = static_cast<int>(lp.c.size());
  const int n = static_cast<int>(lp.G.rows()), m = static_cast<int>(lp.E.rows());
  const int t = static_cast<int>(lp.D.rows());
  const int cols = n + m + t;
  // Column j of the dual is row j of [G; E], then −D_k with μ_k ∈ [−1, 1]:
  //   max hᵀy + fᵀz  s.t.  Gᵀy + Eᵀz − Dᵀμ = c,  y ≥ 0,  |μ| ≤ 1.
  std::vector<CoinBigIndex> start(cols + 1, 0);
  std::vector<int> index;
  std::vector<double> value;
  index.reserve(static_cast<size_t>(cols) * d);
  value.reserve(static_cast<size_t>(cols) * d);
  std::vector<double> collb(cols), colub(cols), obj(cols);
  const double inf = COIN_DBL_MAX;
  for (int j = 0; j < cols; ++j) {
    const bool ineq = j < n, abs_row = j >= n + m;
    for (int k = 0; k < d; ++k) {
      const double v = ineq ? lp.G(j, k) : abs_row ? -lp.D(j - n - m, k) : lp.E(j - n, k);
      if (v != 0.0) {
        index.push_back(k);
        value.push_back(v);
      }
    }
    start[j + 1] = static_cast<CoinBigIndex>(index.size());
    collb[j] = ineq ? 0.0 : abs_row ? -1.0 : -inf;
    colub[j] = abs_row ? 1.0 : inf;
    obj[j] = ineq ? -lp.h(j) : abs_row ? 0.0 : -lp.f(j - n);  // maximize hᵀy + fᵀz
  }
  std::vector<double> rowb(lp.c.data(), lp.c.data() + d);
  ClpSimplex model;
  model.setLogLevel(0);
  model.setMaximumIterations(options.max_iterations);
  model.loadProblem(cols, d, start.data(), index.data(), value.data(), collb.data(),
                    colub.data(), obj.data(), rowb.data(), rowb.data());
  // Row prices are read back as the primal solution, so they must be accurate: Clp's
  // automatic scaling with default tolerances left primal violations of 1e-3 on strip LPs
  // with an inflection (rows scaled by |κ| → 0); unscaled with tight tolerances they are 1e-11.
  model.scaling(0);
  model.setDualTolerance(options.tolerance);
  model.setPrimalTolerance(options.tolerance);
  if (t > 0 && options.x_hint.size() == d) {  // μ_k = sign(D_k x_hint), at its bound
    const Eigen::VectorXd dx = lp.D * options.x_hint;
    std::vector<double> mu0(cols, 0.0);
    for (int k = 0; k < t; ++k) {
      mu0[n + m + k] = dx(k) < 0 ? -1.0 : 1.0;
      model.setColumnStatus(n + m + k, dx(k) < 0 ? ClpSimplex::atLowerBound : ClpSimplex::atUpperBound);
    }
    model.setColSolution(mu0.data());
  }
  if (!options.basic_hint.empty()) {
    int basic = 0;
    for (int j = 0; j < n + m; ++j)  // the μ columns keep the statuses set from x_hint above
      model.setColumnStatus(j, j < n ? ClpSimplex::atLowerBound : ClpSimplex::isFree);
    for (int j : options.basic_hint)
      if (j >= 0 && j < cols && basic < d) model.setColumnStatus(j, ClpSimplex::basic), ++basic;
    for (int k = 0; k < d; ++k)
      model.setRowStatus(k, k < d - basic ? ClpSimplex::basic : ClpSimplex::isFixed);
  }
  model.primal();
  r.iterations = model.numberIterations();
  const int s = model.status();
  if (s == 0) {
    for (int j = 0; j < cols; ++j)
      if (model.getColumnStatus(j) == ClpSimplex::basic) r.basic.push_back(j);
    r.status = LpStatus::Optimal;
    const double* price = model.getRowPrice();
    r.x.resize(d);
    for (int k = 0; k < d; ++k) r.x(k) = -price[k];  // reduced costs ≥ 0 ⇔ G(−λ) ≥ h
    r.dual_objective = -model.objectiveValue();
    const double* col = model.getColSolution();
    r.y = Eigen::Map<const Eigen::VectorXd>(col, n);
    r.z = Eigen::Map<const Eigen::VectorXd>(col + n, m);
    r.mu = Eigen::Map<const Eigen::VectorXd>(col + n + m, t);
  } else if (s == 2) {
    r.status = LpStatus::Infeasible;  // dual unbounded ⇒ primal infeasible
  } else if (s == 1) {
    r.status = LpStatus::Unbounded;  // dual infeasible ⇒ primal unbounded (or infeasible)
  } else {
    r.status = LpStatus::Failed;
  }
  if (s != 0) r.message = std::string("Clp on the dual program: ") + clp_status_text(s);
}

void solve_primal(const FewVariableLp& lp, const FewVariableLpOptions& options,
                  FewVariableLpResult& r) {
  const int d = static_cast<int>(lp.c.size());
  const int n = static_cast<int>(lp.G.rows()), m = static_cast<int>(lp.E.rows());
  const int t = static_cast<int>(lp.D.rows());
  // Absolute values by bounds: variables u_k ≥ |D_k x| through the rows u_k − D_k x ≥ 0 and
  // u_k + D_k x ≥ 0 (after the rows of G and E), with cost Σ u_k.
  const int rows = n + m + 2 * t, vars = d + t;
  std::vector<CoinBigIndex> start(vars + 1, 0);
  std::vector<int> index;
  std::vector<double> value;
  for (int k = 0; k < vars; ++k) {
    for (int i = 0; i < rows; ++i) {
      double v = 0.0;
      if (k < d) {
        v = i < n ? lp.G(i, k) : i < n + m ? lp.E(i - n, k) : ((i - n - m) % 2 ? 1.0 : -1.0) * lp.D((i - n - m) / 2, k);
      } else if (i >= n + m) {
        v = (i - n - m) / 2 == k - d ? 1.0 : 0.0;
      }
      if (v != 0.0) {
        index.push_back(i);
        value.push_back(v);
      }
    }
    start[k + 1] = static_cast<CoinBigIndex>(index.size());
  }
  const double inf = COIN_DBL_MAX;
  std::vector<double> collb(vars, -inf), colub(vars, inf), obj(vars, 1.0);
  for (int k = 0; k < d; ++k) obj[k] = lp.c(k);
  std::vector<double> rowlb(rows), rowub(rows);
  for (int i = 0; i < rows; ++i) {
    rowlb[i] = i < n ? lp.h(i) : i < n + m ? lp.f(i - n) : 0.0;
    rowub[i] = i < n || i >= n + m ? inf : lp.f(i - n);
  }
  ClpSimplex model;
  model.setLogLevel(0);
  model.setMaximumIterations(options.max_iterations);
  model.loadProblem(vars, rows, start.data(), index.data(), value.data(), collb.data(),
                    colub.data(), obj.data(), rowlb.data(), rowub.data());
  model.primal();
  r.iterations = model.numberIterations();
  const int s = model.status();
  if (s == 0) {
    r.status = LpStatus::Optimal;
    r.x = Eigen::Map<const Eigen::VectorXd>(model.getColSolution(), d);
    const double* price = model.getRowPrice();
    r.y = Eigen::Map<const Eigen::VectorXd>(price, n);
    r.z = Eigen::Map<const Eigen::VectorXd>(price + n, m);
    r.mu.resize(t);  // c + Dᵀ(p_a − p_b) = Gᵀy + Eᵀz, p_a, p_b the prices of u − Dx ≥ 0, u + Dx ≥ 0
    for (int k = 0; k < t; ++k) r.mu(k) = price[n + m + 2 * k] - price[n + m + 2 * k + 1];
    r.dual_objective = (n ? lp.h.dot(r.y) : 0.0) + (m ? lp.f.dot(r.z) : 0.0);
  } else {
    r.status = s == 1 ? LpStatus::Infeasible : s == 2 ? LpStatus::Unbounded : LpStatus::Failed;
    r.message = std::string("Clp on the primal program: ") + clp_status_text(s);
  }
}

// One form, its solution checked against the rows.
FewVariableLpResult solve_checked(const FewVariableLp& lp, const FewVariableLpOptions& options,
                                  LpForm form) {
  FewVariableLpResult r;
  r.solved_by = form;
  if (form == LpForm::Dense && lp.D.rows() > 0 && options.x_hint.size() == lp.c.size()) {
    // From a feasible start the primal method's long steps pass many kinks at once; the dual
    // simplex (from its artificial box, one kink per step) takes over if it fails.
    solve_dense_primal_simplex(lp, options, r);
    if (!r.ok()) {
      const int primal_iterations = r.iterations;
      const std::string why = r.message;
      r = FewVariableLpResult{};
      r.solved_by = form;
      solve_dense_dual_simplex(lp, options, r);
      r.iterations += primal_iterations;
      r.fallback = why + "; dense dual simplex instead";
    }
  } else if (form == LpForm::Dense) solve_dense_dual_simplex(lp, options, r);
  else if (form == LpForm::Dual) solve_dual(lp, options, r);
  else solve_primal(lp, options, r);
  if (r.ok()) {
    r.objective = lp.c.dot(r.x) + (lp.D.rows() > 0 ? (lp.D * r.x).cwiseAbs().sum() : 0.0);
    double viol = 0.0;
    if (lp.G.rows() > 0) viol = std::max(viol, (lp.h - lp.G * r.x).maxCoeff());
    if (lp.E.rows() > 0) viol = std::max(viol, (lp.E * r.x - lp.f).cwiseAbs().maxCoeff());
    r.max_violation = std::max(0.0, viol);
    if (!(r.max_violation <= options.max_violation)) {
      r.status = LpStatus::Failed;
      r.message = std::string(to_string(form)) +
                  " reported optimal, but the solution violates a constraint by " +
                  std::to_string(r.max_violation) + " (limit " +
                  std::to_string(options.max_violation) + ")";
    } else if (lp.D.rows() > 0) {
      // A piecewise-linear objective: optimal only if the dual solution closes the gap.
      const double gap = std::abs(r.objective - r.dual_objective);
      const double scale = std::max({1.0, std::abs(r.objective), lp.D.cwiseAbs().maxCoeff() * r.x.cwiseAbs().maxCoeff()});
      if (!(gap <= 1e-8 * scale)) {
        r.status = LpStatus::Failed;
        r.message = std::string(to_string(form)) + " reported optimal, but the duality gap is " +
                    std::to_string(gap) + " (objective " + std::to_string(r.objective) + ")";
      }
    }
  }
  return r;
}

}  // namespace

FewVariableLpResult solve_few_variable_lp(const FewVariableLp& lp,
                                          const FewVariableLpOptions& options) {
  const Eigen::Index d = lp.c.size();
  PARAFAB_VERIFY(d >= 1, "LP needs at least one variable");
  PARAFAB_VERIFY(lp.G.cols() == d && lp.G.rows() == lp.h.size(),
                 "LP inequality block is " << lp.G.rows() << "x" << lp.G.cols() << " with "
                                           << lp.h.size() << " right-hand sides, d = " << d);
  PARAFAB_VERIFY(lp.E.rows() == 0 || lp.E.cols() == d, "LP equality block has "
                                                           << lp.E.cols() << " columns, d = " << d);
  PARAFAB_VERIFY(lp.E.rows() == lp.f.size(), "LP equality block has " << lp.E.rows()
                                                 << " rows but " << lp.f.size() << " values");
  PARAFAB_VERIFY(lp.D.rows() == 0 || lp.D.cols() == d, "LP absolute-value block has "
                                                           << lp.D.cols() << " columns, d = " << d);
  const auto t0 = std::chrono::steady_clock::now();
  FewVariableLpResult r = solve_checked(lp, options, options.form);
  if (options.form == LpForm::Dense && r.status != LpStatus::Optimal) {
    // A numerical breakdown, or an infeasible / unbounded verdict: Clp's dual form decides
    // (the verdicts are user-facing errors, so they are never the dense solver's alone).
    FewVariableLpOptions clp = options;
    clp.form = LpForm::Dual;
    const std::string why = std::string(to_string(r.status)) + ": " + r.message;
    const int dense_iterations = r.iterations;
    r = solve_checked(lp, clp, LpForm::Dual);
    r.fallback = "dense simplex " + why;
    r.iterations += dense_iterations;
  }
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return r;
}

}  // namespace parafab
