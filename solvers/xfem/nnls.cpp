// Lawson–Hanson active-set NNLS (Solving Least Squares Problems, 1974, Alg. NNLS §23.3).
#include "xfem/nnls.h"

#include <Eigen/QR>
#include <algorithm>
#include <limits>
#include <vector>

#include "common/error.h"

namespace parafab::xfem {

NnlsResult solve_nnls(const Eigen::MatrixXd& A, const Eigen::VectorXd& b, const NnlsOptions& o) {
  PARAFAB_VERIFY(A.rows() == b.size(),
                 "solve_nnls: A has " << A.rows() << " rows, b has " << b.size() << " entries");
  const int n = static_cast<int>(A.cols());
  const double eps = std::numeric_limits<double>::epsilon();
  const double tol = o.tolerance > 0 ? o.tolerance
                                     : 10 * eps * A.cwiseAbs().colwise().sum().maxCoeff() *
                                           std::max<double>(A.rows(), n) * b.cwiseAbs().maxCoeff();
  const int max_iterations = o.max_iterations > 0 ? o.max_iterations : 3 * n;

  NnlsResult r;
  r.x = Eigen::VectorXd::Zero(n);
  std::vector<bool> passive(n, false);
  Eigen::VectorXd dual = A.transpose() * b;
  // Solves the unconstrained least squares problem on the passive columns.
  auto passive_solution = [&](std::vector<int>& cols) {
    cols.clear();
    for (int j = 0; j < n; ++j)
      if (passive[j]) cols.push_back(j);
    Eigen::MatrixXd Ap(A.rows(), cols.size());
    for (int k = 0; k < static_cast<int>(cols.size()); ++k) Ap.col(k) = A.col(cols[k]);
    return Eigen::VectorXd(Ap.colPivHouseholderQr().solve(b));
  };
  std::vector<int> cols;
  // Columns whose entry failed (round-off: the dual said "grow", the solve dropped it again);
  // skipped until some other column enters, which prevents cycling.
  std::vector<bool> skip(n, false);
  while (true) {
    int enter = -1;
    for (int j = 0; j < n; ++j)
      if (!passive[j] && !skip[j] && dual[j] > tol && (enter < 0 || dual[j] > dual[enter]))
        enter = j;
    if (enter < 0) {
      r.converged = true;
      break;
    }
    passive[enter] = true;
    bool out_of_iterations = false;
    while (true) {
      if (++r.iterations > max_iterations) {
        out_of_iterations = true;
        break;
      }
      const Eigen::VectorXd z = passive_solution(cols);
      if (z.size() == 0 || z.minCoeff() > 0) {
        for (int k = 0; k < static_cast<int>(cols.size()); ++k) r.x[cols[k]] = z[k];
        break;
      }
      // Step from x towards z until the first passive variable reaches zero; drop it.
      double alpha = 1;
      int blocking = -1;
      for (int k = 0; k < static_cast<int>(cols.size()); ++k) {
        if (z[k] > 0) continue;
        const double xk = r.x[cols[k]];
        const double ratio = xk - z[k] > 0 ? xk / (xk - z[k]) : 0;
        if (blocking < 0 || ratio < alpha) alpha = ratio, blocking = k;
      }
      for (int k = 0; k < static_cast<int>(cols.size()); ++k) {
        double& xk = r.x[cols[k]];
        xk += alpha * (z[k] - xk);
        if (k == blocking || xk <= 0) {
          xk = 0;
          passive[cols[k]] = false;
        }
      }
    }
    if (out_of_iterations) break;
    if (passive[enter]) {
      std::fill(skip.begin(), skip.end(), false);
    } else {
      skip[enter] = true;
    }
    dual = A.transpose() * (b - A * r.x);
  }
  r.residual_norm = (A * r.x - b).norm();
  return r;
}

}  // namespace parafab::xfem
