// CG preconditioned by an earlier factorization (solvers/xfem/reuse_solve.h) against a dense
// Cholesky solve of the changed system. The systems are spring networks on a 10³ grid held at
// one face: the change removes a ball of nodes (a hole that grows), softens the springs around
// it, adds nodes hanging off the hole's rim, and renumbers everything.
#include "xfem/reuse_solve.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cstdio>
#include <map>
#include <set>

#include "common/error.h"

namespace parafab::xfem {
namespace {

constexpr int kN = 10;
int id(int i, int j, int k) { return (i * kN + j) * kN + k; }

struct Network {
  int nodes = 0;
  std::map<std::pair<int, int>, double> springs;  // (a < b) → stiffness
  std::vector<double> ground;                     // stiffness to the ground per node
  Eigen::SparseMatrix<double> matrix() const {
    std::vector<Eigen::Triplet<double>> t;
    for (const auto& [ab, c] : springs) {
      const auto [a, b] = ab;
      t.emplace_back(a, a, c), t.emplace_back(b, b, c), t.emplace_back(a, b, -c), t.emplace_back(b, a, -c);
    }
    for (int i = 0; i < nodes; ++i)
      if (ground[i] != 0) t.emplace_back(i, i, ground[i]);
    Eigen::SparseMatrix<double> K(nodes, nodes);
    K.setFromTriplets(t.begin(), t.end());
    return K;
  }
};

// The grid network: spring stiffness varying in space, the face i = 0 grounded stiffly.
Network grid_network() {
  Network n;
  n.nodes = kN * kN * kN;
  n.ground.assign(n.nodes, 0.0);
  for (int i = 0; i < kN; ++i)
    for (int j = 0; j < kN; ++j)
      for (int k = 0; k < kN; ++k) {
        if (i == 0) n.ground[id(i, j, k)] = 1e4;
        const double c = 1 + 0.5 * std::sin(i + 2.0 * j + 3.0 * k);
        if (i + 1 < kN) n.springs[{id(i, j, k), id(i + 1, j, k)}] = c;
        if (j + 1 < kN) n.springs[{id(i, j, k), id(i, j + 1, k)}] = c;
        if (k + 1 < kN) n.springs[{id(i, j, k), id(i, j, k + 1)}] = c;
      }
  return n;
}

double dist2(int a, double x, double y, double z) {
  const int i = a / (kN * kN), j = (a / kN) % kN, k = a % kN;
  return (i - x) * (i - x) + (j - y) * (j - y) + (k - z) * (k - z);
}

struct Changed {
  Network network;             // in the new numbering
  std::vector<int> old_of;     // new node → old node (−1: added)
  std::set<int> changed_rows;  // new nodes whose row differs from the old row (or added)
};

// Removes the nodes within radius 2 of (6, 5, 5), softens springs within radius 3.5 to 30 %,
// hangs `added` new nodes off the rim, and numbers the new nodes in reverse.
Changed change(const Network& old, int added) {
  std::vector<char> removed(old.nodes, 0);
  for (int a = 0; a < old.nodes; ++a) removed[a] = dist2(a, 6, 5, 5) <= 4.0;
  std::vector<int> kept;
  for (int a = old.nodes - 1; a >= 0; --a)
    if (!removed[a]) kept.push_back(a);
  Changed c;
  const int nk = static_cast<int>(kept.size());
  c.network.nodes = nk + added;
  c.network.ground.assign(c.network.nodes, 0.0);
  std::vector<int> new_of(old.nodes, -1);
  for (int i = 0; i < nk; ++i) new_of[kept[i]] = i, c.old_of.push_back(kept[i]), c.network.ground[i] = old.ground[kept[i]];
  for (int i = 0; i < added; ++i) c.old_of.push_back(-1), c.changed_rows.insert(nk + i);
  for (const auto& [ab, s] : old.springs) {
    const auto [a, b] = ab;
    if (removed[a] || removed[b]) {  // the rows of the surviving end change
      if (!removed[a]) c.changed_rows.insert(new_of[a]);
      if (!removed[b]) c.changed_rows.insert(new_of[b]);
      continue;
    }
    double v = s;
    if (dist2(a, 6, 5, 5) <= 12.25 && dist2(b, 6, 5, 5) <= 12.25) {
      v = 0.3 * s;
      c.changed_rows.insert(new_of[a]), c.changed_rows.insert(new_of[b]);
    }
    c.network.springs[{std::min(new_of[a], new_of[b]), std::max(new_of[a], new_of[b])}] = v;
  }
  int hung = 0;  // new nodes, each on a rim node (a survivor next to the hole)
  for (int i = 0; i < nk && hung < added; ++i)
    if (dist2(kept[i], 6, 5, 5) <= 6.0) {
      c.network.springs[{i, nk + hung}] = 2.0;
      c.changed_rows.insert(i);
      ++hung;
    }
  EXPECT_EQ(hung, added);
  return c;
}

Eigen::VectorXd load(int n) {
  Eigen::VectorXd f(n);
  for (int i = 0; i < n; ++i) f(i) = std::cos(0.7 * i) + 0.2;
  return f;
}

TEST(ReuseSolve, ChangedNetworkSolvedWithTheOldFactorizationMatchesADenseSolve) {
  const Network old = grid_network();
  const Eigen::SparseMatrix<double> K_old = old.matrix();
  auto chol = std::make_shared<SparseCholesky>();
  ASSERT_TRUE(chol->factorize(K_old));
  const Changed c = change(old, 6);
  const Eigen::SparseMatrix<double> K = c.network.matrix();
  const Eigen::VectorXd f = load(c.network.nodes);
  const Eigen::VectorXd ref = Eigen::MatrixXd(K).llt().solve(f);
  const ReusedFactorization rf(chol, K_old, K, c.old_of);
  // The rows found changed are exactly those the change touched (counted here from the springs).
  EXPECT_EQ(rf.changed_dofs(), static_cast<int>(c.changed_rows.size()));
  EXPECT_EQ(rf.mapped_dofs(), c.network.nodes - 6);
  EXPECT_GT(rf.local_dofs(), rf.changed_dofs());  // one layer of overlap
  const PcgResult r = rf.solve(f, Eigen::VectorXd(), {1e-12, 100});
  ASSERT_TRUE(r.converged) << r.message;
  const double err = (r.x - ref).norm() / ref.norm();
  std::printf("changed %d of %d rows (local %d): %d iterations, residual %.1e, error vs dense %.1e\n", rf.changed_dofs(),
              c.network.nodes, rf.local_dofs(), r.iterations, r.residual, err);
  // Measured: 152 of 973 rows changed (local 293), 10 iterations, error 6.2e-14.
  EXPECT_LE(r.iterations, 12);
  EXPECT_LE(r.residual, 1e-12);
  EXPECT_LT(err, 5e-13);
  // A cap of one iteration: not converged, and says so.
  const PcgResult capped = rf.solve(f, Eigen::VectorXd(), {1e-12, 1});
  EXPECT_FALSE(capped.converged);
  EXPECT_EQ(capped.iterations, 1);
  EXPECT_NE(capped.message.find("after 1 iterations"), std::string::npos) << capped.message;
  // Refactorizing the old system invalidates the preconditioner: an error, not a wrong answer.
  ASSERT_TRUE(chol->factorize(K_old));
  EXPECT_THROW(rf.solve(f, Eigen::VectorXd(), {1e-12, 100}), Error);
}

TEST(ReuseSolve, AnUnchangedRenumberedSystemIsSolvedInOneIteration) {
  const Network old = grid_network();
  const Eigen::SparseMatrix<double> K_old = old.matrix();
  auto chol = std::make_shared<SparseCholesky>();
  ASSERT_TRUE(chol->factorize(K_old));
  // The same network numbered in reverse: nothing changed, no local block.
  Network same = old;
  const int n = old.nodes;
  same.springs.clear();
  for (const auto& [ab, s] : old.springs) same.springs[{n - 1 - ab.second, n - 1 - ab.first}] = s;
  for (int i = 0; i < n; ++i) same.ground[i] = old.ground[n - 1 - i];
  std::vector<int> old_of(n);
  for (int i = 0; i < n; ++i) old_of[i] = n - 1 - i;
  const Eigen::SparseMatrix<double> K = same.matrix();
  const ReusedFactorization rf(chol, K_old, K, old_of);
  EXPECT_EQ(rf.changed_dofs(), 0);
  EXPECT_EQ(rf.local_dofs(), 0);
  const Eigen::VectorXd f = load(n);
  const PcgResult r = rf.solve(f, Eigen::VectorXd(), {1e-12, 100});
  ASSERT_TRUE(r.converged) << r.message;
  EXPECT_EQ(r.iterations, 1);
  const Eigen::VectorXd ref = Eigen::MatrixXd(K).llt().solve(f);
  EXPECT_LT((r.x - ref).norm(), 1e-12 * ref.norm());
}

TEST(ReuseSolve, BadInputIsRefused) {
  const Network old = grid_network();
  const Eigen::SparseMatrix<double> K_old = old.matrix();
  auto empty = std::make_shared<SparseCholesky>();
  std::vector<int> old_of(old.nodes);
  for (int i = 0; i < old.nodes; ++i) old_of[i] = i;
  EXPECT_THROW(ReusedFactorization(empty, K_old, K_old, old_of), Error);  // nothing factorized
  auto chol = std::make_shared<SparseCholesky>();
  ASSERT_TRUE(chol->factorize(K_old));
  old_of.pop_back();
  EXPECT_THROW(ReusedFactorization(chol, K_old, K_old, old_of), Error);  // map of the wrong size
  EXPECT_THROW(preconditioned_cg(K_old, Eigen::VectorXd::Ones(3), [](const Eigen::VectorXd& r, Eigen::VectorXd& z) { z = r; },
                                 Eigen::VectorXd()),
               Error);
}

}  // namespace
}  // namespace parafab::xfem
