// Linear programs with a handful of variables and many constraints. The strip LP (thesis
// Eq. 4.4, 4 variables) and the rod LP (Eq. 5.19, 7 variables) have this shape. Solving the
// dual (d equality rows, one column per primal row) keeps the simplex basis d×d, so the cost
// grows linearly with the number of constraints. ParaFab's dense dual simplex does this
// without any set-up (dense_dual_simplex.h); absolute-value terms Σ|D_k x| (the strip's
// smoothing under gravity) from a feasible start go to its primal simplex with long steps
// (dense_primal_simplex.h); COIN-OR Clp on the dual or the primal program is the reference and
// the fallback.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

namespace parafab {

/// minimize cᵀx + Σ_k |D_k x| over free x ∈ R^d subject to G x ≥ h (inequalities) and
/// E x = f (equalities). The absolute-value rows D (none by default) make the objective
/// piecewise linear, as in the strip's smoothing phase under gravity (Σ |ΔK′|).
struct FewVariableLp {
  Eigen::VectorXd c;
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> G;
  Eigen::VectorXd h;
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> E;
  Eigen::VectorXd f;
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> D;
};

enum class LpForm {
  Dense,  ///< ParaFab's dense dual simplex, d×d basis (default; with absolute-value rows and a
          ///< feasible x_hint its primal simplex with long steps); Clp's dual form if it fails
  Dual,   ///< Clp solves the dual: d rows, n + m columns (linear growth; the reference)
  Primal  ///< Clp solves the row-wise primal: n + m rows, d columns (baseline for benchmarks)
};
const char* to_string(LpForm form);

enum class LpStatus { Optimal, Infeasible, Unbounded, Failed };
const char* to_string(LpStatus status);

struct FewVariableLpOptions {
  LpForm form = LpForm::Dense;
  int max_iterations = 1000000;
  double tolerance = 1e-10;      ///< Clp primal and dual feasibility tolerance
  /// A solution violating a row by more than this is reported as Failed, never returned
  /// as optimal (rows should be scaled to O(1) by the caller).
  double max_violation = 1e-8;
  /// Dense and dual forms: start from a basis containing these rows of [G; E] (e.g. the rows
  /// active at the optimum of a similar LP). A warm start changes Clp's path, so its optimum
  /// can differ in the last bits; the dense solver computes x from the final basis, so it
  /// returns the same bits whenever it ends on the same basis (off when empty).
  std::vector<int> basic_hint;
  /// Programs with absolute-value rows: a point near the optimum (e.g. the x of a similar
  /// program). Dense form: when it is feasible the primal simplex with long steps starts there
  /// (dense_primal_simplex.h), else the dual simplex takes |D_k x| as sign(D_k x_hint) D_k x at
  /// first; Clp's dual form starts its μ_k at those signs. Empty: +D_k x, dual simplex.
  Eigen::VectorXd x_hint;
};

struct FewVariableLpResult {
  LpStatus status = LpStatus::Failed;
  Eigen::VectorXd x;           ///< primal solution (valid when Optimal)
  double objective = 0;        ///< cᵀx + Σ_k |D_k x|
  double dual_objective = 0;   ///< hᵀy + fᵀz of the dual solution
  /// Multipliers (valid when Optimal): c + Dᵀμ = Gᵀy + Eᵀz with y ≥ 0, |μ| ≤ 1 (μ_k = sign(D_k x)
  /// where D_k x ≠ 0), so the optimal value V of
  /// a program whose rows depend on a parameter θ has dV/dθ = −yᵀ ∂(Gx − h)/∂θ − zᵀ ∂(Ex − f)/∂θ
  /// (envelope theorem; used for dR/dP in strips/strip_improve).
  Eigen::VectorXd y, z, mu;
  std::vector<int> basic;      ///< Dense, dual form: rows of [G; E; D] whose dual columns are basic at the end
  int iterations = 0;          ///< simplex iterations (of the solver that gave the result)
  LpForm solved_by = LpForm::Dense;  ///< the form that gave the result (Dual after a fallback)
  std::string fallback;        ///< why the dense solver handed over to Clp or its primal method to its dual one (empty: neither)
  double max_violation = 0;    ///< max over rows of (h − Gx)⁺ and |Ex − f| at x
  double seconds = 0;          ///< wall time of load + solve
  std::string message;         ///< the solver's status in words when not Optimal
  bool ok() const { return status == LpStatus::Optimal; }
};

/// Solves `lp`; never throws for infeasible or unbounded programs (that is the status).
/// Throws parafab::Error only for inconsistent dimensions.
FewVariableLpResult solve_few_variable_lp(const FewVariableLp& lp,
                                          const FewVariableLpOptions& options = {});

}  // namespace parafab
