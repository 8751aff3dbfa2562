// The few-variable LP wrapper: dual and primal forms agree with a hand-solved program.
#include <gtest/gtest.h>

#include "common/few_variable_lp.h"

namespace parafab {
namespace {

// minimize x + 2y s.t. x ≥ 1, y ≥ 2, x + y ≥ 4, x − y = −1  →  x = 1.5, y = 2.5, obj 6.5.
FewVariableLp small_program() {
  FewVariableLp lp;
  lp.c = Eigen::Vector2d(1, 2);
  lp.G.resize(3, 2);
  lp.G << 1, 0, 0, 1, 1, 1;
  lp.h = Eigen::Vector3d(1, 2, 4);
  lp.E.resize(1, 2);
  lp.E << 1, -1;
  lp.f = Eigen::VectorXd::Constant(1, -1.0);
  return lp;
}

TEST(FewVariableLp, DualAndPrimalFormsAgreeWithHandSolution) {
  for (LpForm form : {LpForm::Dual, LpForm::Primal}) {
    FewVariableLpOptions o;
    o.form = form;
    const auto r = solve_few_variable_lp(small_program(), o);
    ASSERT_TRUE(r.ok()) << r.message;
    EXPECT_NEAR(r.x(0), 1.5, 1e-12);
    EXPECT_NEAR(r.x(1), 2.5, 1e-12);
    EXPECT_NEAR(r.objective, 6.5, 1e-12);
    EXPECT_LE(r.max_violation, 1e-12);
  }
}

TEST(FewVariableLp, ReportsInfeasibility) {
  FewVariableLp lp = small_program();
  lp.G.conservativeResize(4, 2);
  lp.h.conservativeResize(4);
  lp.G.row(3) << -1, 0;  // x ≤ 0 contradicts x ≥ 1
  lp.h(3) = 0;
  for (LpForm form : {LpForm::Dual, LpForm::Primal}) {
    FewVariableLpOptions o;
    o.form = form;
    const auto r = solve_few_variable_lp(lp, o);
    EXPECT_EQ(r.status, LpStatus::Infeasible) << r.message;
  }
}

}  // namespace
}  // namespace parafab
