// The threaded XFEM simulator (thesis §6.4; issue 11 §3): quadrature rules, assembly and the
// Newton evaluations run on TBB threads, with results independent of the thread count; the
// one interior-cell matrix equals a per-cell integration; the kept factorization solves a
// second load case like an independent sparse solver.
#include <gtest/gtest.h>

#include <algorithm>
#include <tbb/global_control.h>

#include <Eigen/Geometry>
#include <Eigen/SparseCholesky>
#include <cstdio>

#include "face_lookup.h"
#include "grid_model.h"
#include "occt_shape.h"
#include "part_reader.h"
#include "xfem/nonlinear_xfem.h"

namespace parafab::occ {
namespace {

std::string sample(const char* name) { return std::string(PARAFAB_SAMPLES_DIR) + "/parts/" + name; }

// The L-bracket turned off the grid axes (every boundary face cuts cells), clamped on its
// back (the face through (0, 20, 30) before the turn) and pulled at the end of the base.
struct Bracket {
  std::shared_ptr<const PartShape> part;
  std::vector<xfem::DirichletCondition> clamp;
  std::vector<xfem::TractionCondition> load;
};

Bracket turned_bracket() {
  Bracket b;
  const auto straight = read_part(sample("l_bracket.step"));
  const Eigen::Vector3d axis = Eigen::Vector3d(1, 2, 3).normalized(), center(30, 20, 15);
  b.part = rotated_part(*straight, center, axis, 17);
  const Eigen::Matrix3d R = Eigen::AngleAxisd(17 * M_PI / 180, axis).toRotationMatrix();
  const int back = face_at_point(*b.part, center + R * (Eigen::Vector3d(0, 20, 30) - center), 0.1);
  const int end = face_at_point(*b.part, center + R * (Eigen::Vector3d(60, 20, 4) - center), 0.1);
  b.clamp.push_back({back, Eigen::Matrix3d::Zero(), xfem::Vec3::Zero()});
  b.load.push_back({end, xfem::Vec3(0, 0, -2)});
  return b;
}

GridModel model_with_threads(const PartShape& part, int cells, int threads) {
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
  GridModelOptions o;
  o.grid.cells_longest = cells;
  return build_grid_model(part, o);
}

TEST(XfemParallel, RulesAndLinearSolveIdenticalForOneAndTwoThreads) {
  const Bracket b = turned_bracket();
  const GridModel m1 = model_with_threads(*b.part, 10, 1), m2 = model_with_threads(*b.part, 10, 2);
  ASSERT_TRUE(m1.done && m2.done) << m1.message << m2.message;
  ASSERT_EQ(m1.elements.size(), m2.elements.size());
  ASSERT_GT(m1.cut->subvolumes.size(), 50u);
  size_t points = 0;
  for (size_t e = 0; e < m1.elements.size(); ++e) {
    ASSERT_EQ(m1.elements[e].rule.points.size(), m2.elements[e].rule.points.size());
    for (size_t q = 0; q < m1.elements[e].rule.points.size(); ++q, ++points) {
      EXPECT_EQ(m1.elements[e].rule.weights[q], m2.elements[e].rule.weights[q]);
      EXPECT_EQ((m1.elements[e].rule.points[q] - m2.elements[e].rule.points[q]).norm(), 0.0);
    }
  }
  EXPECT_EQ(m1.adjacent, m2.adjacent);
  const xfem::ElasticMaterial steel{210000, 0.3, 7.85e-9};
  xfem::LinearXfemOptions lo;
  lo.gravity = xfem::Vec3(0, 0, -9810);
  xfem::LinearXfemResult r[2];
  for (int t : {1, 2}) {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, t);
    r[t - 1] = xfem::solve_linear(m1.elements, m1.adjacent, steel, b.clamp, b.load, lo);
    ASSERT_TRUE(r[t - 1].solved) << r[t - 1].message;
  }
  std::printf("%zu elements (%d cut), %zu rule points, %d dofs, max |u| %.6e, |u1 - u2|max %.1e\n",
              m1.elements.size(), r[0].cut_elements, points, r[0].dofs, r[0].u.cwiseAbs().maxCoeff(),
              (r[0].u - r[1].u).cwiseAbs().maxCoeff());
  EXPECT_GT(r[0].u.cwiseAbs().maxCoeff(), 1e-4);  // a real deflection
  EXPECT_EQ((r[0].u - r[1].u).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_EQ(r[0].energy, r[1].energy);
}

TEST(XfemParallel, NewtonIdenticalForOneAndTwoThreads) {
  const Bracket b = turned_bracket();
  const GridModel m = model_with_threads(*b.part, 8, 2);
  ASSERT_TRUE(m.done) << m.message;
  const auto law = xfem::make_material("neo_hooke", 210000, 0.3);
  xfem::NonlinearXfemOptions no;
  no.load_steps = 2;
  xfem::NonlinearXfemResult r[2];
  for (int t : {1, 2}) {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, t);
    r[t - 1] = xfem::solve_nonlinear(m.elements, m.adjacent, *law, {210000, 0.3, 0}, b.clamp, b.load, no);
    ASSERT_TRUE(r[t - 1].converged) << r[t - 1].message;
  }
  std::printf("Newton: %d / %d iterations, max |u| %.6e\n", r[0].iterations, r[1].iterations, r[0].u.cwiseAbs().maxCoeff());
  EXPECT_EQ(r[0].iterations, r[1].iterations);
  EXPECT_EQ(r[0].residuals, r[1].residuals);
  EXPECT_EQ((r[0].u - r[1].u).cwiseAbs().maxCoeff(), 0.0);
}

// All interior cells get the matrix integrated for the first one; each of them integrated on
// its own (a one-element assembly, which has nothing to copy) gives the same block.
TEST(XfemParallel, SharedInteriorCellMatrixEqualsPerCellIntegration) {
  const Bracket b = turned_bracket();
  const GridModel m = model_with_threads(*b.part, 16, 2);
  ASSERT_TRUE(m.done) << m.message;
  int count = 0;
  const auto node = xfem::number_dof_nodes(m.elements, m.adjacent, count);
  const xfem::ElasticMaterial steel{210000, 0.3, 7.85e-9};
  xfem::LinearXfemOptions lo;
  lo.gravity = xfem::Vec3(0, 0, -9810);
  const xfem::LinearSystem all = xfem::assemble_linear(m.elements, node, count, steel, b.clamp, b.load, lo);
  const int interior = static_cast<int>(m.cut->interior_cells.size());
  ASSERT_GT(interior, 20);
  std::printf("%d interior cells, %d given the shared matrix\n", interior, all.reused_element_matrices);
  // Cells next to planes shifted off vertices have another size and are integrated apart.
  EXPECT_GE(all.reused_element_matrices, (interior - 1) / 2);
  EXPECT_LE(all.reused_element_matrices, interior - 1);
  // Sum of every element assembled alone into the same numbering.
  Eigen::SparseMatrix<double> K(3 * count, 3 * count);
  Eigen::VectorXd f = Eigen::VectorXd::Zero(3 * count);
  for (size_t e = 0; e < m.elements.size(); ++e) {
    const xfem::LinearSystem one = xfem::assemble_linear({m.elements[e]}, {node[e]}, count, steel, b.clamp, b.load, lo);
    EXPECT_EQ(one.reused_element_matrices, 0);
    K += one.K;
    f += one.f;
  }
  const double dK = (Eigen::SparseMatrix<double>(all.K - K)).norm() / K.norm(), df = (all.f - f).norm() / f.norm();
  std::printf("shared vs per-cell: |dK|/|K| %.1e, |df|/|f| %.1e\n", dK, df);
  EXPECT_LT(dK, 1e-14);
  EXPECT_LT(df, 1e-14);
}

// The kept factorization (LinearXfemResult::solve_again) on a second load vector against an
// independent sparse LDLᵀ (Eigen's simplicial) of the same assembled system.
TEST(XfemParallel, KeptFactorizationSolvesASecondLoadCase) {
  const Bracket b = turned_bracket();
  const GridModel m = model_with_threads(*b.part, 10, 2);
  ASSERT_TRUE(m.done) << m.message;
  const xfem::ElasticMaterial steel{210000, 0.3, 0};
  xfem::LinearXfemSolver solver;
  const xfem::LinearXfemResult r = solver.solve(m.elements, m.adjacent, steel, b.clamp, b.load);
  ASSERT_TRUE(r.solved) << r.message;
  ASSERT_TRUE(r.factorization && r.factorization->IsDone());
  EXPECT_EQ(r.aggregated_nodes > 0, r.aggregation.size() > 0);
  int count = 0;
  const auto node = xfem::number_dof_nodes(m.elements, m.adjacent, count);
  // Second load case: gravity along x (a load vector an adjoint solve would bring).
  xfem::LinearXfemOptions lo;
  lo.gravity = xfem::Vec3(3000, 0, 0);
  const xfem::LinearSystem sys =
      xfem::assemble_linear(m.elements, node, count, {210000, 0.3, 7.85e-6}, b.clamp, {}, lo);
  const Eigen::VectorXd u = r.solve_again(sys.f);
  Eigen::SparseMatrix<double> T = r.aggregation;
  if (T.size() == 0) {
    T.resize(sys.K.rows(), sys.K.rows());
    T.setIdentity();
  }
  const Eigen::SparseMatrix<double> Tt = T.transpose(), Kr = Tt * sys.K * T;
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt(Kr);
  ASSERT_EQ(ldlt.info(), Eigen::Success);
  const Eigen::VectorXd ref = T * ldlt.solve(Eigen::VectorXd(Tt * sys.f));
  std::printf("second load case: max |u| %.6e, |u - ref| / |ref| %.1e\n", u.cwiseAbs().maxCoeff(),
              (u - ref).norm() / ref.norm());
  EXPECT_GT(u.cwiseAbs().maxCoeff(), 1e-6);
  EXPECT_LT((u - ref).norm(), 1e-9 * ref.norm());
  // The same grid solved again: every element matrix is the kept one, and CG preconditioned
  // by the kept factorization starts at the old solution, already within its tolerance.
  const xfem::LinearXfemResult again = solver.solve(m.elements, m.adjacent, steel, b.clamp, b.load);
  EXPECT_EQ(again.solve_info.method, "pcg");
  EXPECT_EQ(again.solve_info.iterations, 0);
  EXPECT_EQ(again.solve_info.changed_dofs, 0);
  // All but the uncut cells' shared matrix (integrated once per solve for the first uncut cell).
  const bool uncut = std::any_of(m.elements.begin(), m.elements.end(), [](const xfem::GridElement& e) { return !e.subvolume; });
  EXPECT_EQ(again.cached_element_matrices, again.elements - again.reused_element_matrices - (uncut ? 1 : 0));
  EXPECT_EQ(solver.cholesky().factorizations, 1);
  EXPECT_EQ((again.u - r.u).cwiseAbs().maxCoeff(), 0.0);
  // Without reusing the factorization: factorized again, reusing the symbolic analysis.
  xfem::LinearXfemOptions fresh;
  fresh.reuse.factorization = false;
  const xfem::LinearXfemResult third = solver.solve(m.elements, m.adjacent, steel, b.clamp, b.load, fresh);
  EXPECT_EQ(third.solve_info.method, "cholesky");
  EXPECT_EQ(solver.cholesky().analyses, 1);
  EXPECT_EQ(solver.cholesky().factorizations, 2);
  EXPECT_LT((third.u - r.u).cwiseAbs().maxCoeff(), 1e-12 * r.u.cwiseAbs().maxCoeff());
}

}  // namespace
}  // namespace parafab::occ
