// Gauss–Legendre rules on [0, 1] by Newton's method on the Legendre polynomials (thesis §6.3.1)
// and tensor Gauss rules on boxes.
#include "xfem/quadrature_rule.h"

#include <array>
#include <cmath>

#include "common/error.h"

namespace parafab::xfem {

const char* to_string(RuleStatus status) {
  switch (status) {
    case RuleStatus::Ok: return "ok";
    case RuleStatus::EmptyDomain: return "empty domain";
    case RuleStatus::NegativeMeasure: return "negative measure";
    case RuleStatus::ResidualAboveTolerance: return "moment residual above tolerance";
    case RuleStatus::NotConverged: return "refinement not converged";
  }
  return "unknown";
}

RuleStatus worse_status(RuleStatus a, RuleStatus b) {
  auto rank = [](RuleStatus s) {
    switch (s) {
      case RuleStatus::NegativeMeasure: return 3;
      case RuleStatus::ResidualAboveTolerance: return 2;
      case RuleStatus::NotConverged: return 1;
      default: return 0;
    }
  };
  return rank(b) > rank(a) ? b : a;
}

namespace {

// P_n(x) and P_n'(x) by the three-term recurrence (n ≥ 1, |x| < 1).
void legendre(int n, double x, double& p, double& dp) {
  double p0 = 1, p1 = x;  // P_{k−1}, P_k
  for (int k = 1; k < n; ++k) {
    const double p2 = ((2 * k + 1) * x * p1 - k * p0) / (k + 1);
    p0 = p1;
    p1 = p2;
  }
  p = p1;
  dp = n * (x * p1 - p0) / (x * x - 1);
}

// n-point rule on [−1, 1] mapped to [0, 1]. Roots of P_n by Newton from the Tricomi guess,
// computed for one half and mirrored so the rule is exactly symmetric.
QuadratureRule1 compute_gauss_legendre(int n) {
  QuadratureRule1 r;
  r.points.assign(n, 0.5);
  r.weights.assign(n, 0.0);
  const double pi = std::acos(-1.0);
  for (int i = 0; i < (n + 1) / 2; ++i) {
    double x = std::cos(pi * (i + 0.75) / (n + 0.5));  // descending roots of P_n
    double p = 0, dp = 1;
    for (int it = 0; it < 100; ++it) {
      legendre(n, x, p, dp);
      const double dx = p / dp;
      x -= dx;
      if (std::abs(dx) < 1e-16) break;
    }
    legendre(n, x, p, dp);
    const double w = 1.0 / ((1 - x * x) * dp * dp);  // 2/((1−x²)P'²), halved for [0, 1]
    if (2 * i + 1 != n) {
      r.points[i] = 0.5 * (1 - x);
      r.points[n - 1 - i] = 0.5 * (1 + x);
    }
    r.weights[i] = r.weights[n - 1 - i] = w;
  }
  return r;
}

}  // namespace

const QuadratureRule1& gauss_legendre(int n) {
  PARAFAB_VERIFY(n >= 1 && n <= kMaxGaussPoints, "gauss_legendre: number of points must be in [1, "
                                                     << kMaxGaussPoints << "], got " << n);
  static const std::array<QuadratureRule1, kMaxGaussPoints> rules = [] {
    std::array<QuadratureRule1, kMaxGaussPoints> all;
    for (int k = 1; k <= kMaxGaussPoints; ++k) all[k - 1] = compute_gauss_legendre(k);
    return all;
  }();
  return rules[n - 1];
}

QuadratureRule2 tensor_gauss_rule(const Vec2& lo, const Vec2& hi, int n) {
  PARAFAB_VERIFY((hi.array() >= lo.array()).all(), "tensor_gauss_rule: box max " << hi.transpose()
                                                                                 << " below min "
                                                                                 << lo.transpose());
  const QuadratureRule1& g = gauss_legendre(n);
  const Vec2 size = hi - lo;
  QuadratureRule2 r;
  r.points.reserve(n * n);
  r.weights.reserve(n * n);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      r.points.push_back(lo + Vec2(g.points[i] * size.x(), g.points[j] * size.y()));
      r.weights.push_back(g.weights[i] * g.weights[j] * size.prod());
    }
  return r;
}

QuadratureRule3 tensor_gauss_rule(const Box3& box, int n) {
  PARAFAB_VERIFY(
      (box.max.array() >= box.min.array()).all(),
      "tensor_gauss_rule: box max " << box.max.transpose() << " below min " << box.min.transpose());
  const QuadratureRule1& g = gauss_legendre(n);
  const Vec3 size = box.size();
  QuadratureRule3 r;
  r.points.reserve(n * n * n);
  r.weights.reserve(n * n * n);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j)
      for (int k = 0; k < n; ++k) {
        r.points.push_back(box.min +
                           Vec3(g.points[i], g.points[j], g.points[k]).cwiseProduct(size));
        r.weights.push_back(g.weights[i] * g.weights[j] * g.weights[k] * box.volume());
      }
  return r;
}

}  // namespace parafab::xfem
