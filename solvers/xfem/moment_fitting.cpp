// Prefactorized moment-fitting systems of thesis Eq. 6.11 and their weight solves.
#include "xfem/moment_fitting.h"

#include <Eigen/QR>
#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <mutex>
#include <tuple>

#include "common/error.h"
#include "xfem/nnls.h"
#include "xfem/quadrature_rule.h"

namespace parafab::xfem {

void legendre_basis(double x, int n, double* values, double* integrals) {
  const double y = 2 * x - 1;
  double pm = 0, p = 1;  // P_{k−1}, P_k
  for (int k = 0; k < n; ++k) {
    const double pp = k == 0 ? y : ((2 * k + 1) * y * p - k * pm) / (k + 1);  // P_{k+1}
    const double s = std::sqrt(2.0 * k + 1);
    values[k] = s * p;
    // ∫₀ˣ P_k(2s − 1) ds = (P_{k+1} − P_{k−1})(y) / (2(2k + 1)), and x for k = 0.
    integrals[k] = k == 0 ? x : (pp - pm) / (2 * s);
    pm = p;
    p = pp;
  }
}

void legendre_basis_rows(const double* x, int count, int stride, int n, double* values,
                         double* integrals, double* work) {
  if (n <= 0) return;
  double* y = work;            // 2x − 1
  double* pm = work + stride;  // P_{k−1}
  double* p = pm + stride;     // P_k
  for (int j = 0; j < count; ++j) {
    y[j] = 2 * x[j] - 1;
    values[j] = 1;
    integrals[j] = x[j];
    pm[j] = 1;
    p[j] = y[j];
  }
  // The recurrence of legendre_basis, row by row (divisions as products: equal up to round-off).
  for (int k = 1; k < n; ++k) {
    const double a = 2 * k + 1, b = k, inv_c = 1.0 / (k + 1);
    const double s = std::sqrt(2.0 * k + 1), inv_s2 = 1 / (2 * s);
    double* v = values + static_cast<size_t>(k) * stride;
    double* in = integrals + static_cast<size_t>(k) * stride;
    for (int j = 0; j < count; ++j) {
      const double pk = p[j], pk1 = pm[j];
      const double pp = (a * y[j] * pk - b * pk1) * inv_c;
      v[j] = s * pk;
      in[j] = (pp - pk1) * inv_s2;
      pm[j] = pk;
      p[j] = pp;
    }
  }
}

namespace {

FittingSystem build_system(int dimension, int degree, int q, int cap) {
  // Largest exponent of one coordinate: the degree, or the cap when it is lower.
  const int top = cap >= 0 ? std::min(degree, cap) : degree;
  PARAFAB_VERIFY(degree >= 0 && q >= top + 1 && q <= kMaxGaussPoints,
                 "moment fitting: need 0 ≤ degree and min(degree, cap) + 1 ≤ points per direction ≤ "
                     << kMaxGaussPoints << ", got degree " << degree << ", cap " << cap << ", " << q << " points");
  FittingSystem s;
  for (int a = 0; a <= top; ++a)
    for (int b = 0; b <= top; ++b)
      if (dimension == 2) {
        s.exponents.push_back({a, b, 0});
      } else {
        for (int c = 0; a + b + c <= degree && c <= top; ++c) s.exponents.push_back({a, b, c});
      }
  degree = top;  // Legendre values up to the largest exponent
  const QuadratureRule1& g = gauss_legendre(q);
  const int n = dimension == 2 ? q * q : q * q * q;
  s.points.resize(dimension, n);
  for (int j = 0; j < n; ++j) {
    s.points(0, j) = g.points[dimension == 2 ? j / q : j / (q * q)];
    s.points(1, j) = g.points[dimension == 2 ? j % q : (j / q) % q];
    if (dimension == 3) s.points(2, j) = g.points[j % q];
  }
  const int m = static_cast<int>(s.exponents.size());
  s.A.resize(m, n);
  std::vector<double> L(3 * (degree + 1)), I(3 * (degree + 1));
  for (int j = 0; j < n; ++j) {
    for (int d = 0; d < dimension; ++d)
      legendre_basis(s.points(d, j), degree + 1, &L[d * (degree + 1)], &I[d * (degree + 1)]);
    for (int i = 0; i < m; ++i) {
      const auto& e = s.exponents[i];
      s.A(i, j) =
          L[e[0]] * L[degree + 1 + e[1]] * (dimension == 3 ? L[2 * (degree + 1) + e[2]] : 1.0);
    }
  }
  // Aᵀ = Q R  ⇒  Aᵀ(AAᵀ)⁻¹ = Q R⁻ᵀ, without forming AAᵀ.
  const Eigen::HouseholderQR<Eigen::MatrixXd> qr(s.A.transpose());
  const Eigen::MatrixXd Q = qr.householderQ() * Eigen::MatrixXd::Identity(n, m);
  const Eigen::MatrixXd R = qr.matrixQR().topRows(m).triangularView<Eigen::Upper>();
  s.pseudo_inverse =
      Q * R.transpose().triangularView<Eigen::Lower>().solve(Eigen::MatrixXd::Identity(m, m));
  return s;
}

const FittingSystem& cached_system(int dimension, int degree, int q, int cap = -1) {
  static std::mutex mutex;
  static std::map<std::tuple<int, int, int, int>, std::unique_ptr<const FittingSystem>> cache;
  const std::lock_guard<std::mutex> lock(mutex);
  if (cap >= degree) cap = -1;  // no effect
  auto& slot = cache[{dimension, degree, q, cap}];
  if (!slot) slot = std::make_unique<const FittingSystem>(build_system(dimension, degree, q, cap));
  return *slot;
}

}  // namespace

const FittingSystem& square_fitting_system(int degree, int points_per_direction) {
  return cached_system(2, degree, points_per_direction);
}

const FittingSystem& cube_fitting_system(int degree, int points_per_direction, int max_exponent) {
  return cached_system(3, degree, points_per_direction, max_exponent);
}

WeightFitResult fit_weights(const FittingSystem& system, const Eigen::VectorXd& moments,
                            WeightFit fit) {
  PARAFAB_VERIFY(moments.size() == system.A.rows(),
                 "fit_weights: " << moments.size() << " moments for " << system.A.rows()
                                 << " basis functions");
  WeightFitResult r;
  if (fit == WeightFit::MinimalNorm) {
    r.weights = system.pseudo_inverse * moments;
  } else {
    r.weights = solve_nnls(system.A, moments).x;
  }
  r.residual = (system.A * r.weights - moments).cwiseAbs().maxCoeff();
  return r;
}

}  // namespace parafab::xfem
