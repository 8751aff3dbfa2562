#include "rods/bspline_curve3.h"

#include <Eigen/SparseCore>
#include <Eigen/SparseLU>
#include <algorithm>
#include <cmath>

#include "common/error.h"

namespace parafab {

std::vector<Vec2> BSplineCurve3::split(const std::vector<Vec3>& p, bool xy) {
  std::vector<Vec2> out;
  out.reserve(p.size());
  for (const auto& v : p) out.emplace_back(xy ? v.x() : v.z(), xy ? v.y() : 0.0);
  return out;
}

BSplineCurve3::BSplineCurve3(int degree, std::vector<double> knots, std::vector<Vec3> poles,
                             std::vector<double> weights)
    : poles_(poles),
      xy_(degree, knots, split(poles, true), weights),
      z_(degree, std::move(knots), split(poles, false), std::move(weights)) {}

std::array<Vec3, 4> BSplineCurve3::derivatives(double u) const {
  const auto a = xy_.derivatives(u), b = z_.derivatives(u);
  std::array<Vec3, 4> d;
  for (int k = 0; k < 4; ++k) d[k] = Vec3(a[k].x(), a[k].y(), b[k].x());
  return d;
}

SpaceCurve BSplineCurve3::space_curve(int table_intervals) const {
  const BSplineCurve3 copy = *this;
  return SpaceCurve([copy](double u) { return copy.derivatives(u); }, first_parameter(),
                    last_parameter(), table_intervals);
}

namespace {
// Values of the p + 1 basis functions N_{span−p..span, p}(u) (Piegl & Tiller A2.2).
void basis_values(int span, double u, int p, const std::vector<double>& U, double* N) {
  double left[8], right[8];
  N[0] = 1.0;
  for (int j = 1; j <= p; ++j) {
    left[j] = u - U[span + 1 - j];
    right[j] = U[span + j] - u;
    double saved = 0.0;
    for (int r = 0; r < j; ++r) {
      const double temp = N[r] / (right[r + 1] + left[j - r]);
      N[r] = saved + right[r + 1] * temp;
      saved = left[j - r] * temp;
    }
    N[j] = saved;
  }
}
}  // namespace

BSplineCurve3 interpolate_points3(const std::vector<Vec3>& points, int degree) {
  const int n = static_cast<int>(points.size());
  if (n < 2) PARAFAB_INPUT_ERROR("curve.points: need at least 2 points to define a curve, got " << n);
  for (int i = 0; i < n; ++i)
    if (!points[i].allFinite())
      PARAFAB_INPUT_ERROR("curve.points[" << i << "] is not finite (" << points[i].transpose() << ")");
  if (degree < 1 || degree > 7) PARAFAB_INPUT_ERROR("curve.degree must be 1..7, got " << degree);
  std::vector<double> chord(n, 0.0);
  double total = 0.0;
  for (int i = 1; i < n; ++i) total += chord[i] = (points[i] - points[i - 1]).norm();
  for (int i = 1; i < n; ++i)
    if (chord[i] <= 1e-12 * total)
      PARAFAB_INPUT_ERROR("curve.points[" << i << "] repeats curve.points[" << i - 1 << "] ("
                                          << points[i].transpose() << ")");
  const int p = std::min(degree, n - 1);
  std::vector<double> t(n, 0.0);
  for (int i = 1; i < n; ++i) t[i] = t[i - 1] + chord[i] / total;
  t[n - 1] = 1.0;
  std::vector<double> U(n + p + 1, 0.0);
  for (int i = n; i < n + p + 1; ++i) U[i] = 1.0;
  for (int j = 1; j < n - p; ++j) {
    double s = 0.0;
    for (int i = j; i < j + p; ++i) s += t[i];
    U[j + p] = s / p;
  }
  std::vector<Eigen::Triplet<double>> trip;
  trip.reserve(size_t(n) * (p + 1));
  for (int i = 0; i < n; ++i) {
    // Span: U[span] ≤ t < U[span + 1], the last span for t = 1.
    int span = int(std::upper_bound(U.begin() + p, U.begin() + n, t[i]) - U.begin()) - 1;
    span = std::clamp(span, p, n - 1);
    double N[8];
    basis_values(span, t[i], p, U, N);
    for (int j = 0; j <= p; ++j)
      if (N[j] != 0.0) trip.emplace_back(i, span - p + j, N[j]);
  }
  Eigen::SparseMatrix<double> M(n, n);
  M.setFromTriplets(trip.begin(), trip.end());
  Eigen::SparseLU<Eigen::SparseMatrix<double>> lu;
  lu.compute(M);
  PARAFAB_VERIFY(lu.info() == Eigen::Success, "curve.points: interpolation matrix is singular");
  Eigen::MatrixXd rhs(n, 3);
  for (int i = 0; i < n; ++i) rhs.row(i) = points[i].transpose();
  const Eigen::MatrixXd P = lu.solve(rhs);
  std::vector<Vec3> poles(n);
  for (int i = 0; i < n; ++i) poles[i] = P.row(i).transpose();
  return BSplineCurve3(p, std::move(U), std::move(poles));
}

}  // namespace parafab
