#include "common/bspline.h"

#include <sstream>

#include <algorithm>
#include <cmath>

#include "common/error.h"

namespace parafab {

namespace {
// Basis functions and their derivatives up to order n at u on span i (Piegl & Tiller A2.3).
// ders[k][j] = d^k N_{i-p+j,p}(u), n < R.
template <size_t R>
void basis_derivatives(int span, double u, int p, const std::vector<double>& U, int n,
                       std::array<std::array<double, 8>, R>& ders) {
  double ndu[8][8], left[8], right[8], a[2][8];
  ndu[0][0] = 1.0;
  for (int j = 1; j <= p; ++j) {
    left[j] = u - U[span + 1 - j];
    right[j] = U[span + j] - u;
    double saved = 0.0;
    for (int r = 0; r < j; ++r) {
      ndu[j][r] = right[r + 1] + left[j - r];
      const double temp = ndu[r][j - 1] / ndu[j][r];
      ndu[r][j] = saved + right[r + 1] * temp;
      saved = left[j - r] * temp;
    }
    ndu[j][j] = saved;
  }
  for (int j = 0; j <= p; ++j) ders[0][j] = ndu[j][p];
  for (int k = 1; k <= n; ++k)
    for (int j = 0; j <= p; ++j) ders[k][j] = 0.0;
  for (int r = 0; r <= p; ++r) {
    int s1 = 0, s2 = 1;
    a[0][0] = 1.0;
    for (int k = 1; k <= std::min(n, p); ++k) {
      double d = 0.0;
      const int rk = r - k, pk = p - k;
      if (r >= k) {
        a[s2][0] = a[s1][0] / ndu[pk + 1][rk];
        d = a[s2][0] * ndu[rk][pk];
      }
      const int j1 = (rk >= -1) ? 1 : -rk;
      const int j2 = (r - 1 <= pk) ? k - 1 : p - r;
      for (int j = j1; j <= j2; ++j) {
        a[s2][j] = (a[s1][j] - a[s1][j - 1]) / ndu[pk + 1][rk + j];
        d += a[s2][j] * ndu[rk + j][pk];
      }
      if (r <= pk) {
        a[s2][k] = -a[s1][k - 1] / ndu[pk + 1][r];
        d += a[s2][k] * ndu[r][pk];
      }
      ders[k][r] = d;
      std::swap(s1, s2);
    }
  }
  double factor = p;
  for (int k = 1; k <= std::min(n, p); ++k) {
    for (int j = 0; j <= p; ++j) ders[k][j] *= factor;
    factor *= (p - k);
  }
}

// C^(k)(u) for k ≤ ND from the span's Taylor form at t = u − centre:
// X^(k)(u) = Σ_{m=0}^{P−k} X^(k+m)(centre) t^m / m!, summed by Horner; a rational curve
// divides by W with the quotient rule (C W = A differentiated k times), whose C''' is not
// zero for a rational quadratic although A''' and W''' are.
constexpr double kInverse[8] = {0.0, 1.0, 1.0 / 2, 1.0 / 3, 1.0 / 4, 1.0 / 5, 1.0 / 6, 1.0 / 7};

template <int P, int ND, class Taylor>
std::array<Vec2, 4> evaluate_taylor(const Taylor& T, double u, bool rational) {
  const double t = u - T.center;
  std::array<Vec2, 4> A;
  for (auto& x : A) x.setZero();
  constexpr int K = ND < P ? ND : P;  // A^(k) = W^(k) = 0 above the degree
  for (int k = 0; k <= K; ++k) {
    Vec2 a = T.A[P];
    for (int m = P - 1; m >= k; --m) a = T.A[m] + (t * kInverse[m - k + 1]) * a;
    A[k] = a;
  }
  if (!rational) return A;
  std::array<double, 4> W{0, 0, 0, 0};
  for (int k = 0; k <= K; ++k) {
    double w = T.W[P];
    for (int m = P - 1; m >= k; --m) w = T.W[m] + (t * kInverse[m - k + 1]) * w;
    W[k] = w;
  }
  std::array<Vec2, 4> C;
  for (auto& x : C) x.setZero();
  C[0] = A[0] / W[0];
  if (ND >= 1) C[1] = (A[1] - W[1] * C[0]) / W[0];
  if (ND >= 2) C[2] = (A[2] - 2 * W[1] * C[1] - W[2] * C[0]) / W[0];
  if (ND >= 3) C[3] = (A[3] - 3 * W[1] * C[2] - 3 * W[2] * C[1] - W[3] * C[0]) / W[0];
  return C;
}

template <int P, class Taylor>
std::array<Vec2, 4> evaluate_degree(int nd, const Taylor& T, double u, bool rational) {
  switch (nd) {
    case 0: return evaluate_taylor<P, 0>(T, u, rational);
    case 1: return evaluate_taylor<P, 1>(T, u, rational);
    case 2: return evaluate_taylor<P, 2>(T, u, rational);
    default: return evaluate_taylor<P, 3>(T, u, rational);
  }
}
}  // namespace

BSplineCurve2::BSplineCurve2(int degree, std::vector<double> knots, std::vector<Vec2> poles,
                             std::vector<double> weights)
    : degree_(degree), knots_(std::move(knots)), poles_(std::move(poles)),
      weights_(std::move(weights)) {
  PARAFAB_VERIFY(degree_ >= 1 && degree_ <= 7,
                 "curve.bspline.degree must be between 1 and 7, got " << degree_);
  PARAFAB_VERIFY(poles_.size() >= static_cast<size_t>(degree_) + 1,
                 "curve.bspline.poles: degree " << degree_ << " needs at least " << degree_ + 1
                                                << " poles, got " << poles_.size());
  PARAFAB_VERIFY(knots_.size() == poles_.size() + degree_ + 1,
                 "curve.bspline.knots: expected " << poles_.size() + degree_ + 1
                     << " knots (poles + degree + 1, multiplicities repeated), got "
                     << knots_.size());
  for (size_t i = 0; i < knots_.size(); ++i) {
    PARAFAB_VERIFY(std::isfinite(knots_[i]), "curve.bspline.knots[" << i << "] is not finite");
    PARAFAB_VERIFY(i == 0 || knots_[i] >= knots_[i - 1],
                   "curve.bspline.knots[" << i << "] = " << knots_[i]
                                          << " decreases (previous " << knots_[i - 1] << ")");
  }
  for (size_t i = 0; i < poles_.size(); ++i)
    PARAFAB_VERIFY(poles_[i].allFinite(), "curve.bspline.poles[" << i << "] is not finite");
  if (!weights_.empty()) {
    PARAFAB_VERIFY(weights_.size() == poles_.size(),
                   "curve.bspline.weights: expected " << poles_.size() << " weights, got "
                                                      << weights_.size());
    for (size_t i = 0; i < weights_.size(); ++i)
      PARAFAB_VERIFY(std::isfinite(weights_[i]) && weights_[i] > 0,
                     "curve.bspline.weights[" << i << "] must be positive, got " << weights_[i]);
  }
  PARAFAB_VERIFY(last_parameter() > first_parameter(),
                 "curve.bspline.knots: empty parameter range [" << first_parameter() << ", "
                                                                << last_parameter() << "]");
  build_span_index();
  build_taylor_forms();
}

void BSplineCurve2::build_taylor_forms() {
  const int p = degree_, n = static_cast<int>(poles_.size()) - 1;
  taylor_.assign(n - p + 1, SpanTaylor{});
  for (int span = p; span <= n; ++span) {
    SpanTaylor& T = taylor_[span - p];
    for (auto& a : T.A) a.setZero();
    if (!(knots_[span + 1] > knots_[span])) continue;  // empty span: find_span never returns it
    T.center = 0.5 * (knots_[span] + knots_[span + 1]);
    std::array<std::array<double, 8>, 8> N{};
    basis_derivatives(span, T.center, p, knots_, p, N);
    for (int k = 0; k <= p; ++k)
      for (int j = 0; j <= p; ++j) {
        const double w = weights_.empty() ? 1.0 : weights_[span - p + j];
        T.A[k] += N[k][j] * w * poles_[span - p + j];
        T.W[k] += N[k][j] * w;
      }
  }
}

std::vector<double> BSplineCurve2::breakpoints() const {
  std::vector<double> b;
  const double a = first_parameter(), e = last_parameter();
  for (double k : knots_)
    if (k >= a && k <= e && (b.empty() || k > b.back())) b.push_back(k);
  return b;
}

int BSplineCurve2::find_span(double u) const {
  // The span s with knots[s] ≤ u < knots[s + 1] (the last non-empty span for u at the end).
  if (!(u > knots_[degree_])) return first_span_;
  if (u >= knots_[last_span_ + 1]) return last_span_;
  const double x = (u - knots_[degree_]) * bucket_scale_;  // compared before the cast: never UB
  const size_t last = span_of_bucket_.size() - 1;
  const size_t b = x < static_cast<double>(last) ? static_cast<size_t>(x) : last;
  int s = span_of_bucket_[b];
  while (knots_[s] > u) --s;  // only where rounding put u just before its bucket's start
  while (knots_[s + 1] <= u) ++s;
  return s;
}

void BSplineCurve2::build_span_index() {
  const int n = static_cast<int>(poles_.size()) - 1;
  first_span_ = degree_;
  while (!(knots_[first_span_ + 1] > knots_[first_span_])) ++first_span_;
  last_span_ = n;
  while (!(knots_[last_span_ + 1] > knots_[last_span_])) --last_span_;
  const double a = first_parameter(), range = last_parameter() - a;
  const size_t buckets = 2 * static_cast<size_t>(n - degree_ + 1);
  bucket_scale_ = buckets / range;
  span_of_bucket_.assign(buckets, first_span_);
  int s = first_span_;
  for (size_t b = 0; b < buckets; ++b) {
    // The span holding the bucket's start (find_span scans from it in either direction).
    const double start = a + b / bucket_scale_;
    while (s < last_span_ && knots_[s + 1] <= start) ++s;
    span_of_bucket_[b] = s;
  }
}

std::array<Vec2, 4> BSplineCurve2::derivatives(double u, int order) const {
  u = std::clamp(u, first_parameter(), last_parameter());
  const SpanTaylor& T = taylor_[find_span(u) - degree_];
  const bool r = rational();
  // A polynomial's derivatives vanish above the degree; a rational curve's do not.
  const int nd = r ? std::clamp(order, 0, 3) : std::min(std::clamp(order, 0, 3), degree_);
  switch (degree_) {
    case 1: return evaluate_degree<1>(nd, T, u, r);
    case 2: return evaluate_degree<2>(nd, T, u, r);
    case 3: return evaluate_degree<3>(nd, T, u, r);
    case 4: return evaluate_degree<4>(nd, T, u, r);
    case 5: return evaluate_degree<5>(nd, T, u, r);
    case 6: return evaluate_degree<6>(nd, T, u, r);
    default: return evaluate_degree<7>(nd, T, u, r);
  }
}

void BSplineCurve2::set_poles(std::vector<Vec2> poles) {
  PARAFAB_VERIFY(poles.size() == poles_.size(), "curve.bspline.poles: expected " << poles_.size()
                     << " poles (the curve's count), got " << poles.size());
  for (size_t i = 0; i < poles.size(); ++i)
    PARAFAB_VERIFY(poles[i].allFinite(), "curve.bspline.poles[" << i << "] is not finite");
  poles_ = std::move(poles);
  build_taylor_forms();
}

BSplineCurve2::Basis BSplineCurve2::basis(double u) const {
  u = std::clamp(u, first_parameter(), last_parameter());
  const int span = find_span(u);
  Basis b;
  basis_derivatives(span, u, degree_, knots_, std::min(3, degree_), b.N);
  b.first = span - degree_;
  return b;
}

PoleJet pole_jet(const BSplineCurve2& curve, double u) {
  PARAFAB_VERIFY(!curve.rational(), "pole derivatives need a non-rational B-spline (weights given)");
  PoleJet J;
  J.u = u;
  J.basis = curve.basis(u);
  const int p = curve.degree();
  J.count = p + 1;
  const auto& P = curve.poles();
  for (auto& v : J.d) v.setZero();
  for (int k = 0; k < 4; ++k)
    for (int j = 0; j <= p; ++j) J.d[k] += J.basis.N[k][j] * P[J.basis.first + j];
  const Vec2 &c1 = J.d[1], &c2 = J.d[2], &c3 = J.d[3];
  auto det = [](const Vec2& a, const Vec2& b) { return a.x() * b.y() - a.y() * b.x(); };
  const double v = c1.norm();
  PARAFAB_VERIFY(v > 0, "curve has zero speed at u = " << u);
  const double D2 = det(c1, c2), D3 = det(c1, c3), w = c1.dot(c2);
  const double v2 = v * v, v3 = v2 * v, v4 = v2 * v2;
  J.speed = v;
  J.tangent = c1 / v;
  J.kappa = D2 / v3;
  J.dkappa_du = D3 / v3 - 3 * D2 * w / (v3 * v2);
  J.dkappa_ds = J.dkappa_du / v;
  for (int j = 0; j <= p; ++j) {
    const double n1 = J.basis.N[1][j], n2 = J.basis.N[2][j], n3 = J.basis.N[3][j];
    for (int c = 0; c < 2; ++c) {
      Vec2 e = Vec2::Zero();
      e(c) = 1.0;
      const Vec2 d1 = n1 * e, d2 = n2 * e, d3 = n3 * e;  // δC', δC'', δC'''
      const double dv = c1.dot(d1) / v;
      const double dD2 = det(d1, c2) + det(c1, d2), dD3 = det(d1, c3) + det(c1, d3);
      const double dw = d1.dot(c2) + c1.dot(d2);
      J.dspeed[j](c) = dv;
      J.dtangent[j].col(c) = (d1 - J.tangent * J.tangent.dot(d1)) / v;
      J.dkappa[j](c) = dD2 / v3 - 3 * D2 * dv / v4;
      // κ_s = D3 v⁻⁴ − 3 D2 w v⁻⁶
      J.ddkappa_ds[j](c) = dD3 / v4 - 4 * D3 * dv / (v4 * v) - 3 * (dD2 * w + D2 * dw) / (v4 * v2) +
                           18 * D2 * w * dv / (v4 * v3);
    }
  }
  return J;
}

namespace {
std::string row_text(const Eigen::MatrixXd& P, int i) {
  std::ostringstream os;
  os << "(";
  for (int c = 0; c < P.cols(); ++c) os << (c ? ", " : "") << P(i, c);
  os << ")";
  return os.str();
}
}  // namespace

InterpolatedBSpline interpolate_rows(const Eigen::MatrixXd& points, int degree) {
  const int n = static_cast<int>(points.rows());
  if (n < 2)
    PARAFAB_INPUT_ERROR("curve.points: need at least 2 points to define a curve, got " << n);
  for (int i = 0; i < n; ++i)
    if (!points.row(i).allFinite())
      PARAFAB_INPUT_ERROR("curve.points[" << i << "] is not finite " << row_text(points, i));
  std::vector<double> chord(n, 0.0);
  double total = 0.0;
  for (int i = 1; i < n; ++i) total += chord[i] = (points.row(i) - points.row(i - 1)).norm();
  if (!std::isfinite(total)) PARAFAB_INPUT_ERROR("curve.points are too far apart: their chord length overflows");
  for (int i = 1; i < n; ++i) {
    if (chord[i] == 0)
      PARAFAB_INPUT_ERROR("curve.points[" << i << "] repeats curve.points[" << i - 1 << "] " << row_text(points, i));
    if (chord[i] <= 1e-12 * total)  // distinct, but closer than the interpolation can tell apart
      PARAFAB_INPUT_ERROR("curve.points[" << i << "] lies " << chord[i] << " from curve.points[" << i - 1
                                          << "], less than 1e-12 of the polygon's length " << total << " "
                                          << row_text(points, i));
  }
  PARAFAB_VERIFY(degree >= 1, "interpolation degree must be >= 1, got " << degree);
  const int p = std::min(degree, n - 1);
  // Chord-length parameters on [0, 1].
  std::vector<double> t(n, 0.0);
  for (int i = 1; i < n; ++i) t[i] = t[i - 1] + chord[i] / total;
  t[n - 1] = 1.0;
  // Averaged knots.
  std::vector<double> U(n + p + 1, 0.0);
  for (int i = n; i < n + p + 1; ++i) U[i] = 1.0;
  for (int j = 1; j < n - p; ++j) {
    double s = 0.0;
    for (int i = j; i < j + p; ++i) s += t[i];
    U[j + p] = s / p;
  }
  // Collocation matrix, banded: row i holds N_{span−p..span}(t_i), so A(i, j) ≠ 0 only for
  // |i − j| ≤ p; stored as band(i, j − i + p). It is totally positive (B-splines at increasing
  // sites) and non-singular (Schoenberg–Whitney holds for averaged knots), so Gaussian
  // elimination without pivoting is stable (de Boor & Pinkus 1977) and stays in the band.
  const int w = 2 * p + 1;
  Eigen::MatrixXd band = Eigen::MatrixXd::Zero(n, w);
  for (int i = 0; i < n; ++i) {
    // Span: U[span] ≤ t < U[span + 1], the last span for t = 1.
    const int span = std::clamp(static_cast<int>(std::upper_bound(U.begin() + p, U.begin() + n, t[i]) - U.begin()) - 1,
                                p, n - 1);
    std::array<std::array<double, 8>, 1> N{};
    basis_derivatives(span, t[i], p, U, 0, N);
    for (int j = 0; j <= p; ++j) {
      const int col = span - p + j;
      PARAFAB_VERIFY(std::abs(col - i) <= p, "interpolation: collocation entry (" << i << ", " << col
                                                 << ") outside the band of width " << p);
      band(i, col - i + p) = N[0][j];
    }
  }
  Eigen::MatrixXd X = points;
  for (int k = 0; k < n; ++k) {
    const double pivot = band(k, p);
    PARAFAB_VERIFY(std::abs(pivot) > 1e-14, "curve.points: interpolation matrix is singular (pivot "
                                                << pivot << " at point " << k << ")");
    for (int i = k + 1; i <= std::min(k + p, n - 1); ++i) {
      const double f = band(i, k - i + p) / pivot;
      if (f == 0.0) continue;
      for (int j = k + 1; j <= std::min(k + p, n - 1); ++j) band(i, j - i + p) -= f * band(k, j - k + p);
      X.row(i) -= f * X.row(k);
    }
  }
  for (int k = n - 1; k >= 0; --k) {
    for (int j = k + 1; j <= std::min(k + p, n - 1); ++j) X.row(k) -= band(k, j - k + p) * X.row(j);
    X.row(k) /= band(k, p);
  }
  InterpolatedBSpline out;
  out.degree = p;
  out.knots = std::move(U);
  out.poles = std::move(X);
  return out;
}

BSplineCurve2 interpolate_points(const std::vector<Vec2>& points, int degree) {
  Eigen::MatrixXd P(points.size(), 2);
  for (size_t i = 0; i < points.size(); ++i) P.row(static_cast<Eigen::Index>(i)) = points[i].transpose();
  InterpolatedBSpline s = interpolate_rows(P, degree);
  std::vector<Vec2> poles(points.size());
  for (size_t i = 0; i < poles.size(); ++i) poles[i] = s.poles.row(static_cast<Eigen::Index>(i)).transpose();
  return BSplineCurve2(s.degree, std::move(s.knots), std::move(poles));
}

}  // namespace parafab
