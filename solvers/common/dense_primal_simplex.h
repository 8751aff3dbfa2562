// ParaFab's primal solver for few-variable programs with absolute-value rows (FewVariableLp::D,
// objective cᵀx + Σ_k |D_k x|) started from a feasible point: an active-set (primal simplex)
// method in x whose line search walks over the kinks of the objective along an edge, as
// Barrodale and Roberts' L1 simplex does, so one step passes many sign changes of D_k x.
// Used through solve_few_variable_lp (Dense form, x_hint feasible); the dual simplex and Clp
// take over when it fails.
#pragma once

#include "common/few_variable_lp.h"

namespace parafab {

/// Fills status, x, y, z, mu, basic, iterations, dual_objective and message of `r` from the
/// feasible start options.x_hint (Failed when it is not feasible, or on a numerical
/// breakdown; never a claim about the program).
void solve_dense_primal_simplex(const FewVariableLp& lp, const FewVariableLpOptions& options,
                                FewVariableLpResult& r);

}  // namespace parafab
