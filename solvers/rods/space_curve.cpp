#include "rods/space_curve.h"

#include <algorithm>
#include <cmath>

#include "common/error.h"
#include "common/gauss_legendre.h"

namespace parafab {

SpaceCurve::SpaceCurve(CurveDerivatives derivatives, double t0, double t1, int table_intervals)
    : derivatives_(std::move(derivatives)), t0_(t0), t1_(t1) {
  PARAFAB_VERIFY(derivatives_, "space curve: no derivative function given");
  if (!(t1 > t0) || !std::isfinite(t0) || !std::isfinite(t1))
    PARAFAB_INPUT_ERROR("space curve: parameter range must satisfy t0 < t1, got [" << t0 << ", "
                                                                                << t1 << "]");
  PARAFAB_VERIFY(table_intervals >= 1, "space curve: table_intervals must be >= 1, got "
                                           << table_intervals);
  table_t_.resize(table_intervals + 1);
  table_s_.assign(table_intervals + 1, 0.0);
  table_v_.assign(table_intervals + 1, 0.0);
  double vmin = INFINITY, vmax = 0, tmin = t0;
  for (int i = 0; i <= table_intervals; ++i) {
    table_t_[i] = t0 + (t1 - t0) * i / table_intervals;
    const auto d = derivatives_(table_t_[i]);
    for (const auto& v : d)
      if (!v.allFinite())
        PARAFAB_INPUT_ERROR("space curve: non-finite value at parameter t = " << table_t_[i]);
    const double v = d[1].norm();
    table_v_[i] = v;
    vmax = std::max(vmax, v);
    if (v < vmin) vmin = v, tmin = table_t_[i];
  }
  if (!(vmin > 1e-10 * vmax))
    PARAFAB_INPUT_ERROR("space curve: zero speed near parameter t = " << tmin
                                                                      << "; the curve must be regular");
  for (int i = 1; i <= table_intervals; ++i)
    table_s_[i] = table_s_[i - 1] + integrate_speed(table_t_[i - 1], table_t_[i]);
}

double SpaceCurve::integrate_speed(double a, double b) const {
  const double h = 0.5 * (b - a), m = 0.5 * (a + b);
  double sum = 0;
  for (int q = 0; q < 8; ++q) sum += kGauss8W[q] * speed(m + h * kGauss8X[q]);
  return sum * h;
}

double SpaceCurve::arc_length_at(double t) const {
  t = std::clamp(t, t0_, t1_);
  auto it = std::upper_bound(table_t_.begin(), table_t_.end(), t);
  const size_t i = it == table_t_.begin() ? 0 : size_t(it - table_t_.begin()) - 1;
  if (i + 1 >= table_t_.size()) return table_s_.back();
  return table_s_[i] + integrate_speed(table_t_[i], t);
}

double SpaceCurve::parameter_at(double s) const {
  s = std::clamp(s, 0.0, length());
  auto it = std::upper_bound(table_s_.begin(), table_s_.end(), s);
  size_t i = it == table_s_.begin() ? 0 : size_t(it - table_s_.begin()) - 1;
  if (i + 1 >= table_s_.size()) return t1_;
  const double ta = table_t_[i], tb = table_t_[i + 1], h = tb - ta;
  const double sa = table_s_[i], sb = table_s_[i + 1], va = table_v_[i], vb = table_v_[i + 1];
  // Initial guess: invert the cubic Hermite interpolant of s(t) on the table interval.
  auto hermite = [&](double x) {  // x ∈ [0, 1] → (s, ds/dx)
    const double x2 = x * x, x3 = x2 * x;
    const double s_ = (2 * x3 - 3 * x2 + 1) * sa + (x3 - 2 * x2 + x) * h * va + (-2 * x3 + 3 * x2) * sb +
                      (x3 - x2) * h * vb;
    const double d_ = (6 * x2 - 6 * x) * sa + (3 * x2 - 4 * x + 1) * h * va + (-6 * x2 + 6 * x) * sb +
                      (3 * x2 - 2 * x) * h * vb;
    return std::make_pair(s_, d_);
  };
  double x = (s - sa) / std::max(1e-300, sb - sa);
  for (int k = 0; k < 8; ++k) {
    const auto [sx, dx] = hermite(x);
    if (!(dx > 0)) break;
    const double xn = std::clamp(x - (sx - s) / dx, 0.0, 1.0);
    if (std::abs(xn - x) < 1e-15) { x = xn; break; }
    x = xn;
  }
  // Newton on the Gauss–Legendre arc length, safeguarded by bisection.
  double lo = ta, hi = tb, t = ta + x * h;
  for (int k = 0; k < 50; ++k) {
    const double f = sa + integrate_speed(ta, t) - s;
    if (f > 0) hi = t; else lo = t;
    double tn = t - f / speed(t);
    if (!(tn >= lo && tn <= hi)) tn = 0.5 * (lo + hi);
    const bool done = std::abs(tn - t) <= 1e-14 * (std::abs(t) + h);
    t = tn;
    if (done) break;
  }
  return t;
}

RodSample SpaceCurve::at_parameter(double t) const {
  RodSample p = frenet_at_parameter(t);
  p.s = arc_length_at(t);
  return p;
}

RodSample SpaceCurve::frenet_at_parameter(double t) const {
  const auto d = derivatives_(t);
  RodSample p;
  p.t = t;
  p.point = d[0];
  const double v = d[1].norm();
  p.tangent = d[1] / v;
  const Vec3 w = d[1].cross(d[2]);
  const double wn = w.norm();
  p.kappa = wn / (v * v * v);
  if (wn > 0) {
    p.binormal = w / wn;
    p.normal = p.binormal.cross(p.tangent);
    p.torsion = w.dot(d[3]) / (wn * wn);
  } else {
    // Inflection: no Frénet frame; any unit normal (rods reject such curves).
    Vec3 a = std::abs(p.tangent.x()) < 0.9 ? Vec3::UnitX() : Vec3::UnitY();
    p.normal = (a - a.dot(p.tangent) * p.tangent).normalized();
    p.binormal = p.tangent.cross(p.normal);
    p.torsion = 0;
  }
  return p;
}

std::vector<RodSample> sample_at(const SpaceCurve& curve, const std::vector<double>& s) {
  std::vector<RodSample> out;
  out.reserve(s.size());
  for (double si : s) {
    RodSample p = curve.frenet_at_parameter(curve.parameter_at(si));
    p.s = std::clamp(si, 0.0, curve.length());
    out.push_back(p);
  }
  return out;
}

std::vector<RodSample> sample_by_arc_length(const SpaceCurve& curve, int count) {
  PARAFAB_VERIFY(count >= 2, "sample_by_arc_length: count must be >= 2, got " << count);
  std::vector<double> s(count);
  for (int i = 0; i < count; ++i) s[i] = curve.length() * i / (count - 1);
  return sample_at(curve, s);
}

void require_frenet_curve(const SpaceCurve& curve, const std::vector<RodSample>& samples,
                          double min_kappa_length) {
  const double L = curve.length();
  auto fail = [&](double t, double k) {
    PARAFAB_INPUT_ERROR("curve: curvature vanishes at arc length s = "
                        << curve.arc_length_at(t) << " m (parameter t = " << t << ", kappa = " << k
                        << " 1/m); Kirchhoff rod design needs a Frenet curve (kappa > 0)");
  };
  for (const auto& p : samples)
    if (!(p.kappa * L >= min_kappa_length)) fail(p.t, p.kappa);
  // Local minima of κ between samples: golden-section search on [t_{i-1}, t_{i+1}].
  const double g = 0.5 * (std::sqrt(5.0) - 1);
  for (size_t i = 1; i + 1 < samples.size(); ++i) {
    if (!(samples[i].kappa <= samples[i - 1].kappa && samples[i].kappa <= samples[i + 1].kappa))
      continue;
    double lo = samples[i - 1].t, hi = samples[i + 1].t;
    auto k = [&](double t) { return curve.frenet_at_parameter(t).kappa; };
    double x1 = hi - g * (hi - lo), x2 = lo + g * (hi - lo), f1 = k(x1), f2 = k(x2);
    for (int it = 0; it < 80 && hi - lo > 1e-14 * (std::abs(lo) + 1); ++it) {
      if (f1 < f2) hi = x2, x2 = x1, f2 = f1, x1 = hi - g * (hi - lo), f1 = k(x1);
      else lo = x1, x1 = x2, f1 = f2, x2 = lo + g * (hi - lo), f2 = k(x2);
    }
    const double tm = 0.5 * (lo + hi), km = k(tm);
    if (!(km * L >= min_kappa_length)) fail(tm, km);
  }
}

}  // namespace parafab
