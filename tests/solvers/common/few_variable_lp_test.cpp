// The few-variable LP solvers: the dense dual simplex and Clp's dual and primal forms agree
// with a hand-solved program, and the dense solver with Clp on random and degenerate programs.
#include <gtest/gtest.h>

#include "common/few_variable_lp.h"

#include <random>

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
  for (LpForm form : {LpForm::Dense, LpForm::Dual, LpForm::Primal}) {
    FewVariableLpOptions o;
    o.form = form;
    const auto r = solve_few_variable_lp(small_program(), o);
    ASSERT_TRUE(r.ok()) << r.message;
    EXPECT_NEAR(r.x(0), 1.5, 1e-12);
    EXPECT_NEAR(r.x(1), 2.5, 1e-12);
    EXPECT_NEAR(r.objective, 6.5, 1e-12);
    EXPECT_LE(r.max_violation, 1e-12);
    EXPECT_EQ(r.solved_by, form);
  }
}

TEST(FewVariableLp, ReportsInfeasibility) {
  FewVariableLp lp = small_program();
  lp.G.conservativeResize(4, 2);
  lp.h.conservativeResize(4);
  lp.G.row(3) << -1, 0;  // x ≤ 0 contradicts x ≥ 1
  lp.h(3) = 0;
  for (LpForm form : {LpForm::Dense, LpForm::Dual, LpForm::Primal}) {
    FewVariableLpOptions o;
    o.form = form;
    const auto r = solve_few_variable_lp(lp, o);
    EXPECT_EQ(r.status, LpStatus::Infeasible) << r.message;
    // The dense solver finds it itself; Clp confirms the verdict.
    if (form == LpForm::Dense) EXPECT_EQ(r.fallback.rfind("dense simplex infeasible", 0), 0u) << r.fallback;
  }
}

TEST(FewVariableLp, DenseSolverReportsUnboundedness) {
  FewVariableLp lp = small_program();
  lp.c = Eigen::Vector2d(-1, -1);  // x = y + ... grows without bound along (1, 1)
  const auto r = solve_few_variable_lp(lp);
  EXPECT_EQ(r.status, LpStatus::Unbounded) << r.message;
  EXPECT_EQ(r.fallback.rfind("dense simplex unbounded", 0), 0u) << r.fallback;
}

// A random bounded program around a known vertex x*: `active` rows pass through x* (more than
// d of them when `degenerate`), the others keep a random slack, and c is a positive
// combination of d active rows, so x* is optimal.
FewVariableLp random_program(std::mt19937& rng, int d, int n, int equalities, bool degenerate) {
  std::normal_distribution<double> N(0.0, 1.0);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  FewVariableLp lp;
  Eigen::VectorXd xs(d);
  for (int k = 0; k < d; ++k) xs(k) = N(rng);
  lp.G.resize(n, d);
  lp.h.resize(n);
  lp.E.resize(equalities, d);
  lp.f.resize(equalities);
  for (int i = 0; i < equalities; ++i) {
    for (int k = 0; k < d; ++k) lp.E(i, k) = N(rng);
    lp.f(i) = lp.E.row(i).dot(xs);
  }
  const int active = degenerate ? std::min(n, 3 * d) : d - equalities;
  for (int j = 0; j < n; ++j) {
    for (int k = 0; k < d; ++k) lp.G(j, k) = N(rng);
    lp.h(j) = lp.G.row(j).dot(xs) - (j < active ? 0.0 : U(rng));
  }
  lp.c = Eigen::VectorXd::Zero(d);
  for (int j = 0; j < d - equalities; ++j) lp.c += (0.5 + U(rng)) * lp.G.row(j).transpose();
  for (int i = 0; i < equalities; ++i) lp.c += N(rng) * lp.E.row(i).transpose();
  // Shuffle the rows so that the active ones are not first.
  std::vector<int> perm(n);
  for (int j = 0; j < n; ++j) perm[j] = j;
  std::shuffle(perm.begin(), perm.end(), rng);
  FewVariableLp out = lp;
  for (int j = 0; j < n; ++j) out.G.row(j) = lp.G.row(perm[j]), out.h(j) = lp.h(perm[j]);
  return out;
}

TEST(FewVariableLp, DenseSimplexMatchesClpOnRandomAndDegeneratePrograms) {
  std::mt19937 rng(20261125);
  int cases = 0;
  for (int d : {2, 3, 4, 7})
    for (int n : {d + 2, 60, 900})
      for (int equalities : {0, 1, 2})
        for (bool degenerate : {false, true})
          for (int rep = 0; rep < 4; ++rep) {
            if (equalities >= d) continue;
            const FewVariableLp lp = random_program(rng, d, n, equalities, degenerate);
            FewVariableLpOptions dense, clp;
            clp.form = LpForm::Dual;
            const auto a = solve_few_variable_lp(lp, dense), b = solve_few_variable_lp(lp, clp);
            SCOPED_TRACE(::testing::Message() << "d " << d << " n " << n << " eq " << equalities
                                              << " degenerate " << degenerate << " rep " << rep);
            ASSERT_TRUE(b.ok()) << b.message;
            ASSERT_TRUE(a.ok()) << a.message;
            EXPECT_EQ(a.solved_by, LpForm::Dense) << a.fallback;  // no fallback needed
            const double scale = std::max(1.0, std::abs(b.objective));
            EXPECT_NEAR(a.objective, b.objective, 1e-11 * scale);
            EXPECT_LE(a.max_violation, 1e-12 * std::max(1.0, lp.h.cwiseAbs().maxCoeff()));
            // Dual certificate: y ≥ 0, Gᵀy + Eᵀz = c, equal objectives, complementary slackness.
            EXPECT_GE(a.y.minCoeff(), 0.0);
            Eigen::VectorXd c = lp.G.transpose() * a.y;
            if (equalities) c += lp.E.transpose() * a.z;
            EXPECT_LE((c - lp.c).cwiseAbs().maxCoeff(), 1e-12 * std::max(1.0, lp.c.cwiseAbs().maxCoeff()));
            EXPECT_NEAR(a.dual_objective, a.objective, 1e-11 * scale);
            const Eigen::VectorXd slack = lp.G * a.x - lp.h;
            for (int j = 0; j < n; ++j)
              if (a.y(j) > 0) EXPECT_LE(slack(j), 1e-11 * std::max(1.0, std::abs(lp.h(j))));
            ++cases;
          }
  EXPECT_EQ(cases, (2 + 3 + 3 + 3) * 3 * 2 * 4);  // equality counts below d, n, degenerate, repeats
}

// Started from the basis a cold start ends on, the dense solver takes no step and returns the
// same bits (x is computed from the final basis in row order).
TEST(FewVariableLp, DenseWarmStartFromTheOptimalBasisGivesTheSameBits) {
  std::mt19937 rng(7);
  for (int rep = 0; rep < 20; ++rep) {
    const FewVariableLp lp = random_program(rng, 4, 400, rep % 2, rep % 3 == 0);
    const auto cold = solve_few_variable_lp(lp);
    ASSERT_TRUE(cold.ok()) << cold.message;
    FewVariableLpOptions o;
    o.basic_hint = cold.basic;
    std::reverse(o.basic_hint.begin(), o.basic_hint.end());
    const auto warm = solve_few_variable_lp(lp, o);
    ASSERT_TRUE(warm.ok()) << warm.message;
    EXPECT_EQ(warm.iterations, 0);
    for (int k = 0; k < 4; ++k) EXPECT_EQ(warm.x(k), cold.x(k));
    EXPECT_EQ(warm.basic, cold.basic);
  }
}

}  // namespace
}  // namespace parafab
