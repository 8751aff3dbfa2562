// The kept sparse factorization of the XFEM systems (solvers/xfem/sparse_cholesky.h) against
// dense factorizations of the same matrices.
#include "xfem/sparse_cholesky.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>

#include "common/error.h"

namespace parafab::xfem {
namespace {

// 7-point Laplacian on an n³ grid plus `shift`·I (SPD for shift > −λ_min).
Eigen::SparseMatrix<double> laplacian(int n, double shift) {
  std::vector<Eigen::Triplet<double>> t;
  auto id = [n](int i, int j, int k) { return (i * n + j) * n + k; };
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j)
      for (int k = 0; k < n; ++k) {
        t.emplace_back(id(i, j, k), id(i, j, k), 6 + shift);
        if (i + 1 < n) t.emplace_back(id(i, j, k), id(i + 1, j, k), -1), t.emplace_back(id(i + 1, j, k), id(i, j, k), -1);
        if (j + 1 < n) t.emplace_back(id(i, j, k), id(i, j + 1, k), -1), t.emplace_back(id(i, j + 1, k), id(i, j, k), -1);
        if (k + 1 < n) t.emplace_back(id(i, j, k), id(i, j, k + 1), -1), t.emplace_back(id(i, j, k + 1), id(i, j, k), -1);
      }
  Eigen::SparseMatrix<double> A(n * n * n, n * n * n);
  A.setFromTriplets(t.begin(), t.end());
  return A;
}

TEST(SparseCholesky, SolvesLikeADenseFactorizationAndReusesTheAnalysis) {
  const Eigen::SparseMatrix<double> A = laplacian(6, 0.01);
  const Eigen::VectorXd b = Eigen::VectorXd::LinSpaced(A.rows(), -1, 2);
  SparseCholesky chol;
  EXPECT_FALSE(chol.IsDone());
  EXPECT_THROW(chol.solve(b), Error);
  ASSERT_TRUE(chol.factorize(A));
  EXPECT_EQ(chol.status(), SparseCholesky::Status::Factorized);
  const Eigen::VectorXd ref = Eigen::MatrixXd(A).llt().solve(b);
  EXPECT_LT((chol.solve(b) - ref).norm(), 1e-13 * ref.norm());
  // Same pattern, other values: one analysis, two factorizations.
  const Eigen::SparseMatrix<double> A2 = 2.5 * A;
  ASSERT_TRUE(chol.factorize(A2));
  EXPECT_EQ(chol.analyses, 1);
  EXPECT_EQ(chol.factorizations, 2);
  EXPECT_LT((chol.solve(b) - ref / 2.5).norm(), 1e-13 * ref.norm());
  // Another pattern (another size): analyzed again.
  const Eigen::SparseMatrix<double> B = laplacian(5, 0.01);
  ASSERT_TRUE(chol.factorize(B));
  EXPECT_EQ(chol.analyses, 2);
  const Eigen::VectorXd c = Eigen::VectorXd::Ones(B.rows());
  EXPECT_LT((chol.solve(c) - Eigen::MatrixXd(B).llt().solve(c)).norm(), 1e-12 * c.norm());
  EXPECT_THROW(chol.solve(b), Error);  // wrong size
}

TEST(SparseCholesky, KnowsTheFactorSizeFromTheAnalysisAndRefusesWhatExceedsTheLimit) {
  // A dense SPD matrix is one supernode: its factor stores n × n values (the upper part as zeros)
  // and an LLᵀ of it costs about n³/3 multiply-adds.
  const int n = 40;
  Eigen::MatrixXd M = Eigen::MatrixXd::Random(n, n);
  M = M * M.transpose() + n * Eigen::MatrixXd::Identity(n, n);
  SparseCholesky dense;
  ASSERT_TRUE(dense.factorize(Eigen::SparseMatrix<double>(M.sparseView())));
  EXPECT_EQ(dense.factor_entries(), n * n);
  EXPECT_DOUBLE_EQ(dense.factor_mb(), 8.0 * n * n / 1e6);
  EXPECT_GT(dense.factor_flops(), n * n * n / 3.0);
  EXPECT_LT(dense.factor_flops(), n * n * n / 3.0 * 1.2);

  // The limit counts the factor plus what the process holds.
  const double held = SparseCholesky::resident_mb();
  EXPECT_GT(held, 1.0);  // this test binary alone holds more than a megabyte
  EXPECT_LT(held, SparseCholesky::default_memory_limit_mb());
  const Eigen::SparseMatrix<double> A = laplacian(12, 0.01);
  SparseCholesky tight;
  tight.memory_limit_mb = 1;
  try {
    tight.factorize(A);
    FAIL() << "a 1 MB limit was not refused";
  } catch (const Error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("1728 unknowns needs"), std::string::npos) << what;
    EXPECT_NE(what.find("more than the 1 MB allowed (memory_limit_mb"), std::string::npos) << what;
  }
  EXPECT_EQ(tight.status(), SparseCholesky::Status::Analyzed);  // analyzed, nothing factorized
  EXPECT_FALSE(tight.IsDone());
  EXPECT_GT(tight.factor_mb(), 0.0);
  tight.memory_limit_mb = SparseCholesky::resident_mb() + tight.factor_mb() + 64;
  EXPECT_TRUE(tight.factorize(A));
  const Eigen::VectorXd b = Eigen::VectorXd::Ones(A.rows());
  EXPECT_LT((tight.solve(b) - Eigen::MatrixXd(A).llt().solve(b)).norm(), 1e-12 * b.norm());
}

TEST(SparseCholesky, IndefiniteMatrixFallsBackToLU) {
  const Eigen::SparseMatrix<double> A = laplacian(4, -3.0);  // eigenvalues 6 − 2Σcos: some below 3
  const Eigen::VectorXd b = Eigen::VectorXd::LinSpaced(A.rows(), 1, 3);
  SparseCholesky chol;
  // CHOLMOD's warning goes to stderr: stdout carries the CLI's JSON.
  testing::internal::CaptureStdout();
  testing::internal::CaptureStderr();
  ASSERT_TRUE(chol.factorize(A)) << chol.message();
  const std::string out = testing::internal::GetCapturedStdout(), err = testing::internal::GetCapturedStderr();
  EXPECT_EQ(out.find("CHOLMOD"), std::string::npos) << out;
  EXPECT_NE(err.find("not positive definite"), std::string::npos) << err;
  EXPECT_EQ(chol.status(), SparseCholesky::Status::FactorizedByLU);
  const Eigen::VectorXd ref = Eigen::MatrixXd(A).partialPivLu().solve(b);
  EXPECT_LT((chol.solve(b, 0) - ref).norm(), 1e-12 * ref.norm());
}

TEST(SparseCholesky, SingularMatrixIsAStatusNotAnException) {
  Eigen::SparseMatrix<double> A = laplacian(3, 0.0);
  for (int k = 0; k < A.outerSize(); ++k)  // zero the first row and column
    for (Eigen::SparseMatrix<double>::InnerIterator it(A, k); it; ++it)
      if (it.row() == 0 || it.col() == 0) it.valueRef() = 0;
  SparseCholesky chol;
  EXPECT_FALSE(chol.factorize(A));
  EXPECT_EQ(chol.status(), SparseCholesky::Status::Failed);
  EXPECT_FALSE(chol.message().empty());
  EXPECT_THROW(chol.solve(Eigen::VectorXd::Ones(A.rows())), Error);
}

}  // namespace
}  // namespace parafab::xfem
