// ParaFab's own solver for few-variable LPs (LpForm::Dense): the simplex method on the dual
// program with a dense d×d basis, no set-up beyond the rows themselves. Used through
// solve_few_variable_lp, which checks the result and falls back to Clp when it fails.
#pragma once

#include "common/few_variable_lp.h"

namespace parafab {

/// Fills status, x, y, z, basic, iterations, dual_objective and message of `r` (not
/// objective, max_violation or seconds: solve_few_variable_lp sets those for every form).
/// Status Failed means a numerical breakdown (singular basis, iteration limit), never a
/// claim about the program; the caller then asks Clp.
void solve_dense_dual_simplex(const FewVariableLp& lp, const FewVariableLpOptions& options,
                              FewVariableLpResult& r);

}  // namespace parafab
