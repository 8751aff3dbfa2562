// Forward-mode derivatives with exact gradients and Hessians (thesis §6.5.2, Eq. 6.29: the
// projection needs exact first and second derivatives of c_para). A Jet carries a value, its
// gradient and (Hessian = true) its Hessian over a small number of local variables; the
// constraint and shape-velocity formulas are templates on the scalar type.
#pragma once

#include <Eigen/Core>
#include <cmath>

namespace parafab::optimize {

template <bool Hessian>
struct JetT {
  double v = 0;
  Eigen::VectorXd g;  ///< ∂/∂x_k
  Eigen::MatrixXd h;  ///< ∂²/∂x_k∂x_l (empty unless Hessian)

  JetT() = default;
  /// A constant over n variables.
  JetT(double value, int n) : v(value), g(Eigen::VectorXd::Zero(n)) {
    if constexpr (Hessian) h = Eigen::MatrixXd::Zero(n, n);
  }
  /// Variable k of n with value `value`.
  static JetT variable(double value, int k, int n) {
    JetT j(value, n);
    j.g[k] = 1;
    return j;
  }
  int size() const { return static_cast<int>(g.size()); }
};

using Jet = JetT<true>;
using Dual = JetT<false>;

// Chain rule for a scalar function with f(v), f'(v), f''(v).
template <bool H>
JetT<H> chain(const JetT<H>& a, double f, double df, double d2f) {
  JetT<H> r;
  r.v = f;
  r.g = df * a.g;
  if constexpr (H) r.h = df * a.h + d2f * a.g * a.g.transpose();
  return r;
}

template <bool H>
JetT<H> operator+(const JetT<H>& a, const JetT<H>& b) {
  JetT<H> r;
  r.v = a.v + b.v;
  r.g = a.g + b.g;
  if constexpr (H) r.h = a.h + b.h;
  return r;
}
template <bool H>
JetT<H> operator-(const JetT<H>& a, const JetT<H>& b) {
  JetT<H> r;
  r.v = a.v - b.v;
  r.g = a.g - b.g;
  if constexpr (H) r.h = a.h - b.h;
  return r;
}
template <bool H>
JetT<H> operator-(const JetT<H>& a) {
  JetT<H> r;
  r.v = -a.v;
  r.g = -a.g;
  if constexpr (H) r.h = -a.h;
  return r;
}
template <bool H>
JetT<H> operator*(const JetT<H>& a, const JetT<H>& b) {
  JetT<H> r;
  r.v = a.v * b.v;
  r.g = a.v * b.g + b.v * a.g;
  if constexpr (H) r.h = a.v * b.h + b.v * a.h + a.g * b.g.transpose() + b.g * a.g.transpose();
  return r;
}
template <bool H>
JetT<H> operator*(double s, const JetT<H>& a) {
  JetT<H> r;
  r.v = s * a.v;
  r.g = s * a.g;
  if constexpr (H) r.h = s * a.h;
  return r;
}
template <bool H>
JetT<H> operator*(const JetT<H>& a, double s) { return s * a; }
template <bool H>
JetT<H> operator+(const JetT<H>& a, double s) {
  JetT<H> r = a;
  r.v += s;
  return r;
}
template <bool H>
JetT<H> operator+(double s, const JetT<H>& a) { return a + s; }
template <bool H>
JetT<H> operator-(const JetT<H>& a, double s) { return a + (-s); }
template <bool H>
JetT<H> operator-(double s, const JetT<H>& a) { return (-a) + s; }
template <bool H>
JetT<H> inverse(const JetT<H>& a) {
  const double i = 1.0 / a.v;
  return chain(a, i, -i * i, 2 * i * i * i);
}
template <bool H>
JetT<H> operator/(const JetT<H>& a, const JetT<H>& b) { return a * inverse(b); }
template <bool H>
JetT<H> operator/(const JetT<H>& a, double s) { return (1.0 / s) * a; }
template <bool H>
JetT<H> operator/(double s, const JetT<H>& a) { return s * inverse(a); }

template <bool H>
JetT<H> sqrt(const JetT<H>& a) {
  const double s = std::sqrt(a.v);
  return chain(a, s, 0.5 / s, -0.25 / (s * a.v));
}
template <bool H>
JetT<H> sin(const JetT<H>& a) { return chain(a, std::sin(a.v), std::cos(a.v), -std::sin(a.v)); }
template <bool H>
JetT<H> cos(const JetT<H>& a) { return chain(a, std::cos(a.v), -std::sin(a.v), -std::cos(a.v)); }
template <bool H>
JetT<H> tan(const JetT<H>& a) {
  const double t = std::tan(a.v), s2 = 1 + t * t;
  return chain(a, t, s2, 2 * t * s2);
}

inline double value_of(double x) { return x; }
template <bool H>
double value_of(const JetT<H>& x) { return x.v; }

/// A 3-vector of scalars (double or Jet) with the few operations the formulas need.
template <typename T>
struct V3 {
  T x, y, z;
  T operator[](int i) const { return i == 0 ? x : i == 1 ? y : z; }
};
template <typename T>
V3<T> operator+(const V3<T>& a, const V3<T>& b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
template <typename T>
V3<T> operator-(const V3<T>& a, const V3<T>& b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
template <typename T, typename S>
V3<T> operator*(const S& s, const V3<T>& a) { return {s * a.x, s * a.y, s * a.z}; }
template <typename T>
T dot(const V3<T>& a, const V3<T>& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
template <typename T>
V3<T> cross(const V3<T>& a, const V3<T>& b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
template <typename T>
T norm(const V3<T>& a) {
  using std::sqrt;
  return sqrt(dot(a, a));
}

}  // namespace parafab::optimize
