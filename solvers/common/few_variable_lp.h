// Linear programs with a handful of variables and many constraints, solved with COIN-OR Clp.
// The strip LP (thesis Eq. 4.4, 4 variables) and the rod LP (Eq. 5.19, 7 variables) have this
// shape. Solving the dual (d equality rows, one column per primal row) keeps the simplex basis
// d×d, so the cost grows linearly with the number of constraints.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

namespace parafab {

/// minimize cᵀx over free x ∈ R^d subject to G x ≥ h (inequalities) and E x = f (equalities).
struct FewVariableLp {
  Eigen::VectorXd c;
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> G;
  Eigen::VectorXd h;
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> E;
  Eigen::VectorXd f;
};

enum class LpForm {
  Dual,   ///< Clp solves the dual: d rows, n + m columns (default; linear growth)
  Primal  ///< Clp solves the row-wise primal: n + m rows, d columns (baseline for benchmarks)
};

enum class LpStatus { Optimal, Infeasible, Unbounded, Failed };
const char* to_string(LpStatus status);

struct FewVariableLpOptions {
  LpForm form = LpForm::Dual;
  int max_iterations = 1000000;
  double tolerance = 1e-10;      ///< Clp primal and dual feasibility tolerance
  /// A solution violating a row by more than this is reported as Failed, never returned
  /// as optimal (rows should be scaled to O(1) by the caller).
  double max_violation = 1e-8;
  /// Dual form only: start Clp from a basis containing these dual columns (indices of rows of
  /// [G; E], e.g. the rows active at the optimum of a similar LP), the rest from slacks. A warm
  /// start changes Clp's path, so the optimum can differ in the last bits (off when empty).
  std::vector<int> basic_hint;
};

struct FewVariableLpResult {
  LpStatus status = LpStatus::Failed;
  Eigen::VectorXd x;           ///< primal solution (valid when Optimal)
  double objective = 0;        ///< cᵀx
  double dual_objective = 0;   ///< hᵀy + fᵀz of the dual solution (Dual form only)
  /// Multipliers (valid when Optimal): c = Gᵀy + Eᵀz with y ≥ 0, so the optimal value V of
  /// a program whose rows depend on a parameter θ has dV/dθ = −yᵀ ∂(Gx − h)/∂θ − zᵀ ∂(Ex − f)/∂θ
  /// (envelope theorem; used for dR/dP in strips/strip_improve).
  Eigen::VectorXd y, z;
  std::vector<int> basic;      ///< Dual form: rows of [G; E] whose dual columns are basic at the end
  int iterations = 0;          ///< simplex iterations reported by Clp
  double max_violation = 0;    ///< max over rows of (h − Gx)⁺ and |Ex − f| at x
  double seconds = 0;          ///< wall time of load + solve
  std::string message;         ///< Clp's status in words when not Optimal
  bool ok() const { return status == LpStatus::Optimal; }
};

/// Solves `lp`; never throws for infeasible or unbounded programs (that is the status).
/// Throws parafab::Error only for inconsistent dimensions.
FewVariableLpResult solve_few_variable_lp(const FewVariableLp& lp,
                                          const FewVariableLpOptions& options = {});

}  // namespace parafab
