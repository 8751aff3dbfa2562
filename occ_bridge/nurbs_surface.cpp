// Evaluation of projective NURBS patches (thesis §6.2.1, Eq. 6.1): tensor-product B-spline
// basis (Piegl & Tiller A2.1, A2.3) on homogeneous poles, then perspective division.
#include "nurbs_surface.h"

#include <algorithm>
#include <cmath>

#include "common/error.h"

namespace parafab::occ {

namespace {

void check(const NurbsSurface& s) {
  PARAFAB_VERIFY(s.degree_u >= 1 && s.degree_v >= 1,
                 "NURBS degrees must be >= 1, got " << s.degree_u << ", " << s.degree_v);
  PARAFAB_VERIFY(s.count_u > s.degree_u && s.count_v > s.degree_v,
                 "NURBS needs more poles than its degree, got " << s.count_u << "x" << s.count_v);
  PARAFAB_VERIFY(static_cast<int>(s.knots_u.size()) == s.count_u + s.degree_u + 1 &&
                     static_cast<int>(s.knots_v.size()) == s.count_v + s.degree_v + 1,
                 "NURBS knot vectors must have count + degree + 1 entries");
  PARAFAB_VERIFY(static_cast<int>(s.poles.size()) == s.count_u * s.count_v,
                 "NURBS has " << s.poles.size() << " poles, expected " << s.count_u * s.count_v);
}

// Basis functions N_{span-p..span} and their first derivatives at t (t clamped to the range).
struct Basis {
  int span = 0;
  std::vector<double> value, derivative;
};

Basis basis(const std::vector<double>& U, int p, int count, double t, bool periodic) {
  if (periodic) {  // into [U[p], U[count]) by whole periods
    const double period = U[count] - U[p];
    t -= std::floor((t - U[p]) / period) * period;
    if (t >= U[count]) t -= period;
  }
  t = std::clamp(t, U[p], U[count]);
  Basis b;
  b.span = t >= U[count]
               ? count - 1
               : static_cast<int>(std::upper_bound(U.begin() + p, U.begin() + count, t) - U.begin()) - 1;
  // Triangular table of degree-(p-1) and degree-p functions (A2.2), derivatives from the former.
  std::vector<double> left(p + 1), right(p + 1), N(p + 1, 0.0), lower(p, 0.0);
  N[0] = 1.0;
  for (int j = 1; j <= p; ++j) {
    left[j] = t - U[b.span + 1 - j];
    right[j] = U[b.span + j] - t;
    double saved = 0.0;
    for (int r = 0; r < j; ++r) {
      const double denom = right[r + 1] + left[j - r];
      const double temp = denom != 0.0 ? N[r] / denom : 0.0;
      N[r] = saved + right[r + 1] * temp;
      saved = left[j - r] * temp;
    }
    N[j] = saved;
    if (j == p - 1) std::copy(N.begin(), N.begin() + p, lower.begin());
  }
  if (p == 1) lower = {1.0};
  b.value = N;
  b.derivative.assign(p + 1, 0.0);
  for (int r = 0; r <= p; ++r) {  // N'_{i,p} = p (N_{i,p-1}/(u_{i+p}-u_i) - N_{i+1,p-1}/(u_{i+p+1}-u_{i+1}))
    const int i = b.span - p + r;
    const double a = r >= 1 ? lower[r - 1] : 0.0, c = r < p ? lower[r] : 0.0;
    const double d1 = U[i + p] - U[i], d2 = U[i + p + 1] - U[i + 1];
    b.derivative[r] = p * ((d1 != 0.0 ? a / d1 : 0.0) - (d2 != 0.0 ? c / d2 : 0.0));
  }
  return b;
}

}  // namespace

Eigen::Vector4d evaluate_projective(const NurbsSurface& s, double u, double v) {
  check(s);
  const Basis bu = basis(s.knots_u, s.degree_u, s.count_u, u, s.periodic_u),
              bv = basis(s.knots_v, s.degree_v, s.count_v, v, s.periodic_v);
  Eigen::Vector4d q = Eigen::Vector4d::Zero();
  for (int a = 0; a <= s.degree_u; ++a)
    for (int b = 0; b <= s.degree_v; ++b)
      q += bu.value[a] * bv.value[b] * s.pole(bu.span - s.degree_u + a, bv.span - s.degree_v + b);
  return q;
}

void evaluate(const NurbsSurface& s, double u, double v, Eigen::Vector3d& X, Eigen::Vector3d& Xu,
              Eigen::Vector3d& Xv) {
  check(s);
  const Basis bu = basis(s.knots_u, s.degree_u, s.count_u, u, s.periodic_u),
              bv = basis(s.knots_v, s.degree_v, s.count_v, v, s.periodic_v);
  Eigen::Vector4d q = Eigen::Vector4d::Zero(), qu = q, qv = q;
  for (int a = 0; a <= s.degree_u; ++a)
    for (int b = 0; b <= s.degree_v; ++b) {
      const Eigen::Vector4d& P = s.pole(bu.span - s.degree_u + a, bv.span - s.degree_v + b);
      q += bu.value[a] * bv.value[b] * P;
      qu += bu.derivative[a] * bv.value[b] * P;
      qv += bu.value[a] * bv.derivative[b] * P;
    }
  // X = A / w, X' = (A' - w' X) / w.
  X = q.head<3>() / q[3];
  Xu = (qu.head<3>() - qu[3] * X) / q[3];
  Xv = (qv.head<3>() - qv[3] * X) / q[3];
}

std::vector<PoleInfluence> pole_influence(const NurbsSurface& s, double u, double v) {
  check(s);
  const Basis bu = basis(s.knots_u, s.degree_u, s.count_u, u, s.periodic_u),
              bv = basis(s.knots_v, s.degree_v, s.count_v, v, s.periodic_v);
  std::vector<PoleInfluence> r;
  r.reserve((s.degree_u + 1) * (s.degree_v + 1));
  double W = 0;
  const int nu = s.distinct_u(), nv = s.distinct_v();
  for (int a = 0; a <= s.degree_u; ++a)
    for (int b = 0; b <= s.degree_v; ++b) {
      const int i = bu.span - s.degree_u + a, j = bv.span - s.degree_v + b;
      const double wN = s.pole(i, j)[3] * bu.value[a] * bv.value[b];
      W += wN;
      const int index = (i % nu) * nv + j % nv;  // a periodic copy is its distinct pole
      auto same = r.end();  // only a periodic surface repeats poles
      if (s.periodic_u || s.periodic_v)
        same = std::find_if(r.begin(), r.end(), [&](const PoleInfluence& x) { return x.index == index; });
      if (same != r.end()) same->value += wN;
      else r.push_back({index, wN});
    }
  for (PoleInfluence& x : r) x.value /= W;
  return r;
}

}  // namespace parafab::occ
