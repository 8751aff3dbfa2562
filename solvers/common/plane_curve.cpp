#include "common/plane_curve.h"

#include <algorithm>
#include <cmath>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "common/error.h"
#include "common/gauss_legendre.h"

namespace parafab {

namespace {
// Arc-length table: kMaxSubdivisionsPerSpan sub-intervals per knot span for curves with few
// spans (a 4-piece rational arc), fewer for many short spans (an interpolant of hundreds of
// points), at least kMinSubdivisionsPerSpan, about kTableIntervals in all. Each sub-interval
// is integrated by 8-point Gauss–Legendre.
constexpr int kMaxSubdivisionsPerSpan = 16, kMinSubdivisionsPerSpan = 2, kTableIntervals = 1024;
double cross(const Vec2& a, const Vec2& b) { return a.x() * b.y() - a.y() * b.x(); }
}  // namespace

PlaneCurve::PlaneCurve(BSplineCurve2 curve) : curve_(std::move(curve)) {
  const std::vector<double> bp = curve_.breakpoints();
  const int spans = static_cast<int>(bp.size()) - 1;
  const int sub = std::clamp((kTableIntervals + spans - 1) / std::max(spans, 1), kMinSubdivisionsPerSpan,
                             kMaxSubdivisionsPerSpan);
  table_u_.push_back(bp.front());
  for (size_t k = 0; k + 1 < bp.size(); ++k) {
    for (int j = 1; j < sub; ++j) table_u_.push_back(bp[k] + (bp[k + 1] - bp[k]) * j / sub);
    table_u_.push_back(bp[k + 1]);
  }
  const size_t m = table_u_.size();
  table_s_.assign(m, 0.0);
  table_v_.resize(m);
  // Speeds at the nodes and the integral over each interval (held in table_s_ until summed),
  // on TBB workers for long tables (about 9 curve evaluations per node); same bits as serial.
  tbb::parallel_for(tbb::blocked_range<size_t>(0, m, 128), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i != r.end(); ++i) {
      table_v_[i] = speed(table_u_[i]);
      if (i > 0) table_s_[i] = integrate_speed(table_u_[i - 1], table_u_[i]);
    }
  });
  double max_speed = 0.0, min_speed = INFINITY, u_min = table_u_.front();
  for (size_t i = 0; i < m; ++i) {
    const double v = table_v_[i];
    max_speed = std::max(max_speed, v);
    if (v < min_speed) min_speed = v, u_min = table_u_[i];
  }
  for (size_t i = 1; i < m; ++i) table_s_[i] += table_s_[i - 1];
  breakpoint_s_.reserve(bp.size());
  for (size_t i = 0; i < table_u_.size(); i += sub) breakpoint_s_.push_back(table_s_[i]);
  if (!(min_speed > 1e-10 * max_speed) || !(table_s_.back() > 0.0))
    PARAFAB_INPUT_ERROR("curve: the parametrization stops (zero speed, a cusp or collapsed poles) "
                        "near parameter u = " << u_min << "; the curve must be regular");
}

double PlaneCurve::speed(double u) const { return curve_.derivatives(u, 1)[1].norm(); }

double PlaneCurve::integrate_speed(double u0, double u1) const {
  const double h = 0.5 * (u1 - u0), m = 0.5 * (u1 + u0);
  double sum = 0.0;
  for (int q = 0; q < 8; ++q) sum += kGauss8W[q] * speed(m + h * kGauss8X[q]);
  return sum * h;
}

double PlaneCurve::arc_length_at(double u) const {
  u = std::clamp(u, table_u_.front(), table_u_.back());
  auto it = std::upper_bound(table_u_.begin(), table_u_.end(), u);
  const size_t i = (it == table_u_.begin()) ? 0 : static_cast<size_t>(it - table_u_.begin()) - 1;
  if (i + 1 >= table_u_.size()) return table_s_.back();
  return table_s_[i] + integrate_speed(table_u_[i], u);
}

double PlaneCurve::parameter_at(double s) const {
  s = std::clamp(s, 0.0, length());
  auto it = std::upper_bound(table_s_.begin(), table_s_.end(), s);
  size_t i = (it == table_s_.begin()) ? 0 : static_cast<size_t>(it - table_s_.begin()) - 1;
  if (i + 1 >= table_s_.size()) return table_u_.back();
  double lo = table_u_[i], hi = table_u_[i + 1];
  const double s_lo = table_s_[i];
  // Newton from the cubic Hermite guess of u(s) (du/ds = 1/|γ'| at the table nodes),
  // safeguarded by bisection inside [lo, hi].
  const double ds = table_s_[i + 1] - s_lo, t = (s - s_lo) / ds, t2 = t * t, t3 = t2 * t;
  double u = (2 * t3 - 3 * t2 + 1) * lo + (t3 - 2 * t2 + t) * ds / table_v_[i] +
             (-2 * t3 + 3 * t2) * hi + (t3 - t2) * ds / table_v_[i + 1];
  if (!(u > lo && u < hi)) u = lo + (hi - lo) * t;
  const double tolerance = 1e-15 * length(), interval = hi - lo;
  for (int iter = 0; iter < 60; ++iter) {
    const double f = s_lo + integrate_speed(table_u_[i], u) - s;
    if (std::abs(f) <= tolerance) break;
    if (f > 0) hi = u; else lo = u;
    const auto d = curve_.derivatives(u, 2);
    const double v = d[1].norm(), step = -f / v;
    double next = u + step;
    if (!(next > lo && next < hi)) {
      next = 0.5 * (lo + hi);
    } else if (std::abs(step) <= 1e-3 * interval &&
               0.5 * std::abs(d[1].dot(d[2]) / v) * step * step <= 0.1 * tolerance) {
      // The residual after this Newton step is ½ v′ step² + O(step³) (v′ = d|γ′|/du): a tenth
      // of the tolerance, so the step is taken without integrating again.
      return next;
    }
    if (std::abs(next - u) <= 1e-16 * std::max(1.0, std::abs(u))) { u = next; break; }
    u = next;
  }
  return u;
}

double PlaneCurve::curvature_at(double u) const {
  const auto d = curve_.derivatives(u, 2);
  const double v = d[1].norm();
  return cross(d[1], d[2]) / (v * v * v);
}

CurvePoint PlaneCurve::at_parameter(double u) const {
  CurvePoint c = geometry_at(u);
  c.s = arc_length_at(u);
  return c;
}

CurvePoint PlaneCurve::at_arc_length(double s) const {
  CurvePoint c = geometry_at(parameter_at(s));
  c.s = std::clamp(s, 0.0, length());
  return c;
}

CurvePoint PlaneCurve::geometry_at(double u) const {
  const auto d = curve_.derivatives(u);
  const double v = d[1].norm();
  CurvePoint c;
  c.u = u;
  c.s = NAN;
  c.point = d[0];
  c.tangent = d[1] / v;
  const double det12 = cross(d[1], d[2]);
  c.kappa = det12 / (v * v * v);
  const double dkappa_du =
      cross(d[1], d[3]) / (v * v * v) - 3.0 * det12 * d[1].dot(d[2]) / std::pow(v, 5);
  c.dkappa_ds = dkappa_du / v;
  return c;
}

}  // namespace parafab
