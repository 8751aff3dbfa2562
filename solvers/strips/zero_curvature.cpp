#include "strips/zero_curvature.h"

#include <algorithm>
#include <cmath>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

namespace parafab {

const char* to_string(ZeroKind kind) {
  switch (kind) {
    case ZeroKind::Inflection: return "inflection";
    case ZeroKind::AtEnd: return "end";
    case ZeroKind::Touch: return "touch";
  }
  return "unknown";
}

namespace {
int sign_of(double k, double eps) { return k > eps ? 1 : (k < -eps ? -1 : 0); }

// κ(u) − κ₀ (κ₀ = 0 unless the rod has a natural curvature).
double offset_curvature(const PlaneCurve& c, double u, double k0) { return c.curvature_at(u) - k0; }

// Bisection on κ(u) inside a bracket [lo, hi] with κ(lo)·κ(hi) < 0.
double refine_root(const PlaneCurve& c, double lo, double hi, double k0) {
  double klo = offset_curvature(c, lo, k0);
  for (int it = 0; it < 200 && hi - lo > 1e-15 * (c.last_parameter() - c.first_parameter());
       ++it) {
    const double mid = 0.5 * (lo + hi);
    const double km = offset_curvature(c, mid, k0);
    if (km == 0.0) return mid;
    if ((km < 0) == (klo < 0)) lo = mid, klo = km;
    else hi = mid;
  }
  return 0.5 * (lo + hi);
}

// Golden-section minimization of |κ| on [lo, hi].
double minimize_abs_curvature(const PlaneCurve& c, double lo, double hi, double k0) {
  const double g = 0.5 * (std::sqrt(5.0) - 1.0);
  double x1 = hi - g * (hi - lo), x2 = lo + g * (hi - lo);
  double f1 = std::abs(offset_curvature(c, x1, k0)), f2 = std::abs(offset_curvature(c, x2, k0));
  for (int it = 0; it < 200 && hi - lo > 1e-14 * (c.last_parameter() - c.first_parameter());
       ++it) {
    if (f1 < f2) hi = x2, x2 = x1, f2 = f1, x1 = hi - g * (hi - lo), f1 = std::abs(offset_curvature(c, x1, k0));
    else lo = x1, x1 = x2, f1 = f2, x2 = lo + g * (hi - lo), f2 = std::abs(offset_curvature(c, x2, k0));
  }
  return 0.5 * (lo + hi);
}
}  // namespace

ZeroCurvatureResult find_zero_curvature(const PlaneCurve& curve,
                                        const ZeroCurvatureOptions& options) {
  ZeroCurvatureResult r;
  const double k0 = options.natural_curvature;
  r.natural_curvature = k0;
  const std::vector<double> bp = curve.bspline().breakpoints();
  std::vector<double>& u = r.scan_parameters;
  // scan_per_span points per span, but about kMaxScanPoints in all for curves of many
  // spans (an interpolant of hundreds of points), and at least kMinScanPerSpan per span.
  constexpr int kMaxScanPoints = 8192, kMinScanPerSpan = 16;
  const int spans = static_cast<int>(bp.size()) - 1;
  const int per_span = std::max(std::min(options.scan_per_span, kMaxScanPoints / std::max(spans, 1)),
                                std::min(kMinScanPerSpan, options.scan_per_span));
  u.push_back(bp.front());
  for (size_t k = 0; k + 1 < bp.size(); ++k)
    for (int j = 1; j <= per_span; ++j) u.push_back(bp[k] + (bp[k + 1] - bp[k]) * j / per_span);
  const size_t n = u.size();
  std::vector<double>& kappa = r.scan_kappa;
  kappa.resize(n);
  tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 1024), [&](const tbb::blocked_range<size_t>& b) {
    for (size_t i = b.begin(); i != b.end(); ++i) kappa[i] = offset_curvature(curve, u[i], k0);
  });
  for (size_t i = 0; i < n; ++i) r.kappa_scale = std::max(r.kappa_scale, std::abs(kappa[i]));
  const double l = curve.length();
  if (r.kappa_scale * l <= options.zero_tolerance) {
    r.straight = true;
    return r;
  }
  const double eps = options.zero_tolerance / l;
  std::vector<int> sg(n);
  for (size_t i = 0; i < n; ++i) sg[i] = sign_of(kappa[i], eps);

  auto add = [&](double uu, ZeroKind kind) {
    ZeroCurvaturePoint z;
    z.at = curve.at_parameter(uu);
    z.at.kappa -= options.natural_curvature;
    z.kind = kind;
    r.points.push_back(z);
  };
  // Runs of scan points with κ ≈ 0. A run where κ vanishes to round-off over more than one
  // scan point is a straight piece; otherwise the run is one zero (e.g. κ ∝ (s − s0)³).
  for (size_t i = 0; i < n;) {
    if (sg[i] != 0) { ++i; continue; }
    size_t j = i;
    double run_max = std::abs(kappa[i]);
    while (j + 1 < n && sg[j + 1] == 0) run_max = std::max(run_max, std::abs(kappa[++j]));
    if (j > i && run_max <= 1e-12 * r.kappa_scale) {
      r.flat_piece = true;
      r.flat_from_s = curve.arc_length_at(u[i]);
      r.flat_to_s = curve.arc_length_at(u[j]);
      return r;
    }
    if (i == 0) add(u[0], ZeroKind::AtEnd);
    else if (j == n - 1) add(u[n - 1], ZeroKind::AtEnd);
    else if (sg[i - 1] * sg[j + 1] < 0) add(refine_root(curve, u[i - 1], u[j + 1], k0), ZeroKind::Inflection);
    else add(minimize_abs_curvature(curve, u[i - 1], u[j + 1], k0), ZeroKind::Touch);
    i = j + 1;
  }
  for (size_t i = 0; i + 1 < n; ++i)
    if (sg[i] * sg[i + 1] < 0) add(refine_root(curve, u[i], u[i + 1], k0), ZeroKind::Inflection);
  // Dips of |κ| towards zero between scan points without a sign change (double roots).
  for (size_t i = 1; i + 1 < n; ++i) {
    if (sg[i] == 0 || sg[i - 1] != sg[i] || sg[i + 1] != sg[i]) continue;
    const double a = std::abs(kappa[i]);
    if (a > std::abs(kappa[i - 1]) || a > std::abs(kappa[i + 1]) || a > 1e-2 * r.kappa_scale)
      continue;
    const double um = minimize_abs_curvature(curve, u[i - 1], u[i + 1], k0);
    if (std::abs(offset_curvature(curve, um, k0)) <= eps) add(um, ZeroKind::Touch);
  }
  std::sort(r.points.begin(), r.points.end(),
            [](const ZeroCurvaturePoint& x, const ZeroCurvaturePoint& y) { return x.at.s < y.at.s; });
  return r;
}

}  // namespace parafab
