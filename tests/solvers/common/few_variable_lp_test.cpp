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

// Absolute-value rows, closed form: min Σ_k w_k |x − a_k| (x = (x, 1), D_k = w_k (1, −a_k),
// the second component fixed by an equality row) is the weighted median of the a_k; with a
// row x ≥ b above it, x = b.
TEST(FewVariableLp, AbsoluteValueRowsGiveTheWeightedMedian) {
  const std::vector<double> a = {0.3, -1.2, 2.5, 0.9, 4.0, -0.4, 1.7};
  const std::vector<double> w = {1.0, 2.0, 0.5, 1.5, 1.0, 0.7, 0.8};  // total 7.5; median 0.9
  FewVariableLp lp;
  lp.c = Eigen::Vector2d::Zero();
  lp.E.resize(1, 2);
  lp.E << 0, 1;
  lp.f = Eigen::VectorXd::Ones(1);
  lp.D.resize(static_cast<int>(a.size()), 2);
  for (size_t k = 0; k < a.size(); ++k) lp.D.row(static_cast<int>(k)) << w[k], -w[k] * a[k];
  auto value = [&](double x) {
    double v = 0;
    for (size_t k = 0; k < a.size(); ++k) v += w[k] * std::abs(x - a[k]);
    return v;
  };
  for (const double bound : {-10.0, 2.0}) {
    lp.G.resize(1, 2);
    lp.G << 1, -bound;  // x ≥ bound
    lp.h = Eigen::VectorXd::Zero(1);
    const double expect = bound < 0.9 ? 0.9 : bound;
    for (LpForm form : {LpForm::Dense, LpForm::Dual, LpForm::Primal}) {
      FewVariableLpOptions o;
      o.form = form;
      const auto r = solve_few_variable_lp(lp, o);
      SCOPED_TRACE(::testing::Message() << to_string(form) << ", x >= " << bound);
      ASSERT_TRUE(r.ok()) << r.message;
      EXPECT_EQ(r.solved_by, form) << r.fallback;
      // Clp's primal form runs with its default tolerances (measured 4.5e-11 off here).
      const double tol = form == LpForm::Primal ? 1e-10 : 1e-12;
      EXPECT_NEAR(r.x(0), expect, tol);
      EXPECT_NEAR(r.objective, value(expect), tol);
      EXPECT_NEAR(r.dual_objective, r.objective, tol);
      // μ_k = sign(x − a_k) away from the kink; c + Dᵀμ = Gᵀy + Eᵀz.
      for (size_t k = 0; k < a.size(); ++k)
        if (std::abs(expect - a[k]) > 1e-9) EXPECT_EQ(r.mu(static_cast<int>(k)), expect > a[k] ? 1.0 : -1.0);
      const Eigen::VectorXd stat = lp.c + lp.D.transpose() * r.mu - lp.G.transpose() * r.y - lp.E.transpose() * r.z;
      EXPECT_LE(stat.cwiseAbs().maxCoeff(), 1e-12);
    }
    // The primal method from a feasible start, and what happens from an infeasible one: the
    // dual simplex takes over and says why.
    for (const double start : {-5.0, 3.0}) {
      FewVariableLpOptions o;
      o.x_hint = Eigen::Vector2d(start, 1.0);
      const auto r = solve_few_variable_lp(lp, o);
      SCOPED_TRACE(::testing::Message() << "x_hint " << start << ", x >= " << bound);
      ASSERT_TRUE(r.ok()) << r.message;
      EXPECT_NEAR(r.x(0), expect, 1e-12);
      if (start < bound) EXPECT_EQ(r.fallback, "dense primal simplex: the start violates inequality row 0; dense dual simplex instead");
      else EXPECT_EQ(r.fallback, "");
    }
  }
}

// Random programs with absolute-value rows: inequality rows around a feasible point x* and a
// box that bounds them, equality rows, and D rows through the origin. In half of them the origin
// is feasible too, where every D row vanishes at once (an optimum there is highly degenerate).
// Starts: none (dual simplex from its box), x* (primal simplex from inside) and the origin (the
// primal simplex starting on every kink). The dense solver agrees with Clp's dual and primal
// forms and gives its own certificate, without falling back.
TEST(FewVariableLp, AbsoluteValueRowsMatchClpOnRandomPrograms) {
  std::mt19937 rng(20261127);
  std::normal_distribution<double> N(0.0, 1.0);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  int cases = 0, primal_steps = 0, dual_steps = 0, degenerate = 0;
  for (int d : {2, 3, 4})
    for (int t : {d, 40, 400})
      for (int equalities : {0, 1})
        for (int rep = 0; rep < 6; ++rep) {
          const bool origin_inside = rep >= 3;
          Eigen::VectorXd xs = Eigen::VectorXd::NullaryExpr(d, [&]() { return N(rng); });
          const int n = 20;
          FewVariableLp lp;
          lp.c = 0.3 * Eigen::VectorXd::NullaryExpr(d, [&]() { return N(rng); });
          lp.E.resize(equalities, d);
          lp.f.resize(equalities);
          for (int i = 0; i < equalities; ++i) {
            for (int k = 0; k < d; ++k) lp.E(i, k) = N(rng);
            if (origin_inside) xs -= lp.E.row(i).dot(xs) / lp.E.row(i).squaredNorm() * lp.E.row(i).transpose();
            lp.f(i) = origin_inside ? 0.0 : lp.E.row(i).dot(xs);
          }
          lp.G.resize(n + 2 * d, d);
          lp.h.resize(n + 2 * d);
          for (int j = 0; j < n; ++j) {
            for (int k = 0; k < d; ++k) lp.G(j, k) = N(rng);
            const double at = lp.G.row(j).dot(xs);
            lp.h(j) = (origin_inside ? std::min(at, 0.0) : at) - U(rng);
          }
          for (int k = 0; k < d; ++k) {  // |x_k| ≤ 10
            lp.G.row(n + 2 * k) = Eigen::RowVectorXd::Unit(d, k);
            lp.G.row(n + 2 * k + 1) = -Eigen::RowVectorXd::Unit(d, k);
            lp.h(n + 2 * k) = lp.h(n + 2 * k + 1) = -10.0;
          }
          lp.D.resize(t, d);
          for (int i = 0; i < t; ++i)
            for (int k = 0; k < d; ++k) lp.D(i, k) = N(rng) / std::sqrt(static_cast<double>(t));
          SCOPED_TRACE(::testing::Message() << "d " << d << " t " << t << " eq " << equalities << " rep " << rep);
          FewVariableLpOptions dense, dual, primal;
          dual.form = LpForm::Dual;
          primal.form = LpForm::Primal;
          const int start = rep % 3;  // 0: none, 1: x*, 2: the origin (x* if it is not feasible)
          if (start == 1 || (start == 2 && !origin_inside)) dense.x_hint = dual.x_hint = xs;
          if (start == 2 && origin_inside) dense.x_hint = dual.x_hint = Eigen::VectorXd::Zero(d);
          const auto a = solve_few_variable_lp(lp, dense), b = solve_few_variable_lp(lp, dual),
                     c = solve_few_variable_lp(lp, primal);
          ASSERT_TRUE(b.ok()) << b.message;
          ASSERT_TRUE(c.ok()) << c.message;
          ASSERT_TRUE(a.ok()) << a.message;
          EXPECT_EQ(a.solved_by, LpForm::Dense) << a.fallback;
          EXPECT_EQ(a.fallback, "");  // the primal method's own result when started
          const double scale = std::max(1.0, std::abs(b.objective));
          EXPECT_NEAR(a.objective, b.objective, 1e-11 * scale);
          EXPECT_NEAR(c.objective, b.objective, 1e-8 * scale);  // Clp primal form, default tolerances (measured 7.9e-9)
          EXPECT_LE(a.max_violation, 1e-12 * 10);
          EXPECT_NEAR(a.dual_objective, a.objective, 1e-11 * scale);
          EXPECT_GE(a.y.minCoeff(), 0.0);
          EXPECT_LE(a.mu.cwiseAbs().maxCoeff(), 1.0);
          Eigen::VectorXd stat = lp.c + lp.D.transpose() * a.mu - lp.G.transpose() * a.y;
          if (equalities) stat -= lp.E.transpose() * a.z;
          EXPECT_LE(stat.cwiseAbs().maxCoeff(), 1e-12 * (1 + lp.D.cwiseAbs().colwise().sum().maxCoeff()));
          const Eigen::VectorXd dx = lp.D * a.x;
          int zeros = 0;
          for (int i = 0; i < t; ++i) {
            if (std::abs(dx(i)) > 1e-10) EXPECT_EQ(a.mu(i), dx(i) > 0 ? 1.0 : -1.0) << "row " << i;
            else ++zeros;
          }
          degenerate += zeros > d;
          (dense.x_hint.size() ? primal_steps : dual_steps) += a.iterations;
          ++cases;
        }
  EXPECT_EQ(cases, 3 * 3 * 2 * 6);
  EXPECT_GE(degenerate, 20);  // optima where more than d absolute-value rows vanish (measured 36)
  std::printf("[ absolute-value rows ] %d random programs (%d degenerate optima): dual simplex %d steps, "
              "primal %d steps\n", cases, degenerate, dual_steps, primal_steps);
}

// Infeasible and unbounded programs with absolute-value rows: the dense solver's verdict is
// confirmed by Clp's dual form (as for every verdict), and the Clp forms agree.
TEST(FewVariableLp, AbsoluteValueRowsInfeasibleAndUnbounded) {
  FewVariableLp lp;
  lp.c = Eigen::Vector2d(0, 0);
  lp.D.resize(2, 2);
  lp.D << 1, 0.5, -0.3, 1;
  lp.G.resize(2, 2);
  lp.G << 1, 0, -1, 0;  // x ≥ 1 and x ≤ 0
  lp.h = Eigen::Vector2d(1, 0);
  lp.E.resize(0, 2);
  lp.f.resize(0);
  for (LpForm form : {LpForm::Dense, LpForm::Dual, LpForm::Primal}) {
    FewVariableLpOptions o;
    o.form = form;
    EXPECT_EQ(solve_few_variable_lp(lp, o).status, LpStatus::Infeasible) << to_string(form);
  }
  lp.G.resize(1, 2);
  lp.G << 1, 0;  // x ≥ 1 only, and a cost falling faster along +x than the |D x| rise
  lp.h = Eigen::VectorXd::Ones(1);
  lp.c = Eigen::Vector2d(-3, 0);
  for (LpForm form : {LpForm::Dense, LpForm::Dual, LpForm::Primal}) {
    FewVariableLpOptions o;
    o.form = form;
    o.x_hint = Eigen::Vector2d(2, 0);  // feasible: the dense primal method finds the edge, Clp confirms
    EXPECT_EQ(solve_few_variable_lp(lp, o).status, LpStatus::Unbounded) << to_string(form);
  }
}

}  // namespace
}  // namespace parafab
