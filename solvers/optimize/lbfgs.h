// Quasi-Newton shape optimization over projected parameters (thesis §6.5.2: "a standard
// quasi-Newton" on p, every evaluation at the valid model p⊥(p)): L-BFGS with bounds by
// projection onto the box and an Armijo backtracking line search (cubic interpolation of the
// rejected trial, see backtrack_factor); every iterate is recorded.
#pragma once

#include <Eigen/Core>
#include <functional>
#include <string>
#include <vector>

namespace parafab::optimize {

struct LbfgsOptions {
  int max_iterations = 50;              ///< accepted steps
  int memory = 8;                       ///< correction pairs kept
  double relative_improvement = 1e-6;   ///< stop when (f_k−1 − f_k) <= this·max(|f_k|, |f_0|·1e-12)
  double gradient_tolerance = 1e-12;    ///< stop when the projected gradient's max-norm falls below
  double first_step = 1.0;              ///< max-norm length of the first step (units of x)
  int max_line_search = 20;             ///< trial steps per line search before giving up
  double armijo = 1e-4;                 ///< sufficient decrease constant
};

struct LbfgsIterate {
  int iteration = 0;       ///< 0 = the start
  double objective = 0;
  Eigen::VectorXd x;
  double seconds = 0;      ///< since the start of the run
  int evaluations = 0;     ///< objective evaluations so far
};

struct LbfgsResult {
  bool done = false;        ///< converged by one of the stopping rules (not cancelled, not failed)
  std::string status;       ///< "converged", "max_iterations", "line_search_failed", "cancelled", "evaluation_failed"
  std::string message;
  Eigen::VectorXd x;
  double objective = 0;
  std::vector<LbfgsIterate> iterates;
  int evaluations = 0;
  double seconds = 0;
};

/// The factor in [0.1, 0.5] that shortens a trial step rejected by the Armijo test, from
/// φ(0) = f(x), φ'(0) = ∇f(x)·s, φ(1) = f(x + s), φ'(1) = ∇f(x + s)·s: the minimizer of their
/// cubic (or quadratic) interpolant, safeguarded.
double backtrack_factor(double phi0, double slope0, double phi1, double slope1);

/// f(x) and its gradient; returns false if x cannot be evaluated (the step is then shortened).
using ObjectiveFunction = std::function<bool(const Eigen::VectorXd& x, double& f, Eigen::VectorXd& gradient)>;
/// Called after every accepted iterate (and the start); false cancels the run.
using IterateCallback = std::function<bool(const LbfgsIterate&)>;

/// Minimizes f over lower <= x <= upper from x0 (clamped into the box). Throws parafab::Error
/// for mismatched sizes or an unevaluable start. `refresh`, if given, is called at every
/// accepted point before `callback`: returning true it replaces f and its gradient there (an
/// objective whose discrete switches were frozen during the line search, re-decided at the
/// new point); the step's improvement is still that of the line search's value.
LbfgsResult minimize_lbfgs(const ObjectiveFunction& f, const Eigen::VectorXd& x0, const Eigen::VectorXd& lower,
                           const Eigen::VectorXd& upper, const LbfgsOptions& options = {},
                           const IterateCallback& callback = {}, const ObjectiveFunction& refresh = {});

}  // namespace parafab::optimize
