#include "strips/strip_design.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <sstream>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include "common/error.h"
#include "strips/stiffness_lp.h"

namespace parafab {

// Samples this close to a zero-curvature point (relative to the length) are left out: there
// K is a 0/0 ratio, represented exactly by the l'Hôpital row of the zero itself, and a line
// fitted within the collinearity tolerance may pass the zero on the wrong side.
constexpr double kZeroExclusion = 1e-6;

namespace {
using Clock = std::chrono::steady_clock;
// Seconds since `t`, and `t` moved to now (phase timers of StripDesign::phases).
double lap(Clock::time_point& t) {
  const Clock::time_point now = Clock::now();
  const double dt = std::chrono::duration<double>(now - t).count();
  t = now;
  return dt;
}
}  // namespace

std::vector<CurvePoint> sample_by_arc_length(const PlaneCurve& curve, int count,
                                             const std::vector<ZeroCurvaturePoint>& zeros,
                                             ArcLengthSampleCache* cache) {
  PARAFAB_VERIFY(count >= 2, "need at least 2 samples, got " << count);
  const double l = curve.length();
  ArcLengthSampleCache local;
  ArcLengthSampleCache& c = cache ? *cache : local;
  PARAFAB_VERIFY(c.curve == nullptr || c.curve == &curve, "sample_by_arc_length: the cache belongs to another curve");
  // The interior knots, where K may have a kink (κ' jumps on a cubic) or a jump (κ jumps on
  // a quadratic): there sup K is attained exactly. Their parameters are known: no inversion.
  if (c.curve == nullptr) {
    c.curve = &curve;
    const std::vector<double> bp = curve.bspline().breakpoints();
    const std::vector<double>& bs = curve.breakpoint_arc_lengths();
    for (size_t k = 1; k + 1 < bp.size(); ++k) {
      CurvePoint p = curve.geometry_at(bp[k]);
      p.s = bs[k];
      c.knots.push_back(p);
    }
  }
  // Equally spaced points; those of the previous grid are reused when it is nested in this one.
  const int previous = static_cast<int>(c.spaced.size());
  const int step = previous >= 2 && (count - 1) % (previous - 1) == 0 ? (count - 1) / (previous - 1) : 0;
  std::vector<CurvePoint> spaced(static_cast<size_t>(count));
  tbb::parallel_for(tbb::blocked_range<int>(0, count, 128), [&](const tbb::blocked_range<int>& r) {
    for (int k = r.begin(); k != r.end(); ++k)
      spaced[k] = step > 0 && k % step == 0 ? c.spaced[k / step] : curve.at_arc_length(l * k / (count - 1));
  });
  // Merge both in order of s, dropping near-duplicates and points next to a zero.
  std::vector<CurvePoint> out;
  out.reserve(spaced.size() + c.knots.size());
  double last_s = -INFINITY;
  auto take = [&](const CurvePoint& p) {
    if (p.s - last_s <= 1e-12 * l) return;
    last_s = p.s;
    for (const auto& z : zeros)
      if (std::abs(z.at.s - p.s) <= kZeroExclusion * l) return;
    out.push_back(p);
  };
  size_t a = 0, b = 0;
  while (a < spaced.size() || b < c.knots.size())
    take(b == c.knots.size() || (a < spaced.size() && spaced[a].s <= c.knots[b].s) ? spaced[a++] : c.knots[b++]);
  c.spaced = std::move(spaced);
  return out;
}

namespace {

void validate(const StripDesignOptions& o) {
  PARAFAB_VERIFY(std::isfinite(o.youngs_modulus) && o.youngs_modulus > 0,
                 "material.E must be a positive modulus in Pa, got " << o.youngs_modulus);
  PARAFAB_VERIFY(std::isfinite(o.thickness) && o.thickness > 0,
                 "material.thickness must be positive (metres), got " << o.thickness);
  PARAFAB_VERIFY(o.yield_strain > 0, "material.yield_strain must be positive, got " << o.yield_strain);
  PARAFAB_VERIFY(std::isfinite(o.strain_thickness) && o.strain_thickness >= 0,
                 "strain_thickness must be >= 0 (metres), got " << o.strain_thickness);
  PARAFAB_VERIFY(std::isfinite(o.min_width) && o.min_width > 0,
                 "min_width must be positive (metres), got " << o.min_width);
  PARAFAB_VERIFY(std::isfinite(o.tolerance) && o.tolerance > 0 && o.tolerance < 1,
                 "tolerance must be in (0, 1), got " << o.tolerance);
  PARAFAB_VERIFY(o.initial_samples >= 4 && o.max_samples >= o.initial_samples,
                 "samples: need 4 <= initial_samples <= max_samples, got "
                     << o.initial_samples << " and " << o.max_samples);
}

struct ContinuousRatio {
  double ratio = NAN;  ///< max K / min K of the line (a, b) on the continuous curve
};

// Estimate of the continuous ratio: refines the largest local maxima and smallest minima of
// K among the samples by golden-section search on the continuous curve between the
// neighbouring samples (intervals touching a zero-curvature
// point keep the zero's exact l'Hôpital value instead).
ContinuousRatio continuous_ratio(const PlaneCurve& curve, const std::vector<CurvePoint>& samples,
                                 const std::vector<CurvePoint>& zeros, double a, const Vec2& b) {
  const double l = curve.length();
  double kmax = -INFINITY, kmin = INFINITY;
  std::vector<double> K(samples.size());
  for (size_t i = 0; i < samples.size(); ++i) {
    K[i] = stiffness_at(samples[i], a, b, false);
    kmax = std::max(kmax, K[i]);
    kmin = std::min(kmin, K[i]);
  }
  for (const auto& z : zeros) {
    const double kz = stiffness_at(z, a, b, true);
    kmax = std::max(kmax, kz);
    kmin = std::min(kmin, kz);
  }
  auto K_at = [&](double u) { return stiffness_at(curve.geometry_at(u), a, b, false); };
  auto has_zero = [&](double s0, double s1) {
    for (const auto& z : zeros)
      if (z.s >= s0 - 2 * kZeroExclusion * l && z.s <= s1 + 2 * kZeroExclusion * l) return true;
    return false;
  };
  // Candidates: local maxima and minima among the samples; only the kMaxRefined largest
  // maxima and smallest minima can move the ratio (a flat K has extrema everywhere).
  constexpr size_t kMaxRefined = 16;
  std::vector<size_t> maxima, minima;
  for (size_t i = 0; i < samples.size(); ++i) {
    const size_t lo_i = i == 0 ? 0 : i - 1, hi_i = std::min(i + 1, samples.size() - 1);
    if (K[i] >= K[lo_i] && K[i] >= K[hi_i]) maxima.push_back(i);
    if (K[i] <= K[lo_i] && K[i] <= K[hi_i]) minima.push_back(i);
  }
  auto keep_best = [&](std::vector<size_t>& idx, double sign) {
    if (idx.size() <= kMaxRefined) return;
    std::partial_sort(idx.begin(), idx.begin() + kMaxRefined, idx.end(),
                      [&](size_t x, size_t y) { return sign * K[x] > sign * K[y]; });
    idx.resize(kMaxRefined);
  };
  keep_best(maxima, 1.0);
  keep_best(minima, -1.0);
  const double g = 0.5 * (std::sqrt(5.0) - 1.0);
  for (const double sign : {1.0, -1.0}) {  // maximize sign·K around each candidate
    for (size_t i : sign > 0 ? maxima : minima) {
      const CurvePoint& p_lo = samples[i == 0 ? 0 : i - 1];
      const CurvePoint& p_hi = samples[std::min(i + 1, samples.size() - 1)];
      const double lo = p_lo.s, hi = p_hi.s;
      if (hi <= lo || has_zero(lo, hi)) continue;
      const double du_tol = 1e-13 * (p_hi.u - p_lo.u) * l / (hi - lo);  // ≈ 1e-13·l in s
      double x0 = p_lo.u, x3 = p_hi.u, x1 = x3 - g * (x3 - x0), x2 = x0 + g * (x3 - x0);
      double f1 = sign * K_at(x1), f2 = sign * K_at(x2);
      for (int it = 0; it < 80 && x3 - x0 > du_tol; ++it) {
        if (f1 > f2) x3 = x2, x2 = x1, f2 = f1, x1 = x3 - g * (x3 - x0), f1 = sign * K_at(x1);
        else x0 = x1, x1 = x2, f1 = f2, x2 = x0 + g * (x3 - x0), f2 = sign * K_at(x2);
      }
      const double best = std::max(f1, f2) * sign;
      kmax = std::max(kmax, best);
      kmin = std::min(kmin, best);
    }
  }
  ContinuousRatio r;
  r.ratio = kmax / kmin;
  return r;
}

// Bending strain h·|κ − κ₀|/2 (each fibre at distance h/2 from the neutral axis): its maximum
// over the curve, from the zero finder's scan refined by golden-section search between the
// neighbouring scan points. Refuses a design that yields (strain above o.yield_strain) with an
// elastic moment law.
void bending_strain(const PlaneCurve& curve, const ZeroCurvatureResult& zeros,
                    const StripDesignOptions& o, StripDesign& d) {
  const std::vector<double>& u = zeros.scan_parameters;
  const std::vector<double>& k = zeros.scan_kappa;
  if (u.empty()) return;
  size_t best = 0;
  for (size_t i = 1; i < k.size(); ++i)
    if (std::abs(k[i]) > std::abs(k[best])) best = i;
  const double k0 = o.natural_curvature;
  auto f = [&](double uu) { return std::abs(curve.curvature_at(uu) - k0); };
  double lo = u[best == 0 ? 0 : best - 1], hi = u[std::min(best + 1, u.size() - 1)];
  double u_best = u[best], f_best = std::abs(k[best]);
  const double g = 0.5 * (std::sqrt(5.0) - 1.0);
  double x1 = hi - g * (hi - lo), x2 = lo + g * (hi - lo), f1 = f(x1), f2 = f(x2);
  for (int it = 0; it < 100 && hi - lo > 1e-14 * (u.back() - u.front()); ++it) {
    if (f1 > f2) hi = x2, x2 = x1, f2 = f1, x1 = hi - g * (hi - lo), f1 = f(x1);
    else lo = x1, x1 = x2, f1 = f2, x2 = lo + g * (hi - lo), f2 = f(x2);
  }
  if (std::max(f1, f2) > f_best) f_best = std::max(f1, f2), u_best = f1 > f2 ? x1 : x2;
  const double h = o.strain_thickness > 0 ? o.strain_thickness : o.thickness;
  d.max_strain = 0.5 * h * f_best;
  d.max_strain_s = curve.arc_length_at(u_best);
  if (!std::isfinite(o.yield_strain)) return;
  d.yield_ratio = d.max_strain / o.yield_strain;
  if (d.yield_ratio > 1 && !std::isfinite(o.law.curvature_limit))
    PARAFAB_INPUT_ERROR("material " << (o.material_name.empty() ? std::string("(unnamed)") : "\"" + o.material_name + "\"")
                        << " yields: the bending strain h·|κ|/2 = " << d.max_strain << " at s = "
                        << d.max_strain_s << " m (h = " << h << " m, |κ| = " << f_best
                        << " 1/m) exceeds its yield strain " << o.yield_strain << " ("
                        << d.yield_ratio << "×); choose a thinner or more ductile material, a "
                        "gentler curve, or a moment law with material.law.curvature_limit "
                        "(plasticity)");
}

// Ends that the equilibrium check found on the inflection line with vanishing curvature are
// zeros at the ends (kind end).
// With fewer than two zeros the LP chooses the line (§4.3.2), and the equilibrium check cannot
// say whether it will pass through an end. When it does, at an end where κ − κ₀ vanishes too
// (both to end_zero_tolerance of their largest values along the curve: a curve from points
// whose curvature vanishes at the end up to the interpolation error, e.g. y = sin x from
// x = 0), that end is a zero at the end (kind end), as check_equilibrium reports it for lines
// fixed by two or more zeros.
void report_line_end_zeros(const PlaneCurve& curve, const ZeroCurvatureResult& zeros,
                           const StripDesignOptions& o, StripDesign& d) {
  if (zeros.points.size() >= 2 || d.b.norm() == 0) return;
  double m_max = 0;  // the largest moment K κ = a + <b, γ> along the curve
  for (const auto& p : d.samples) m_max = std::max(m_max, std::abs(d.a + d.b.dot(p.point)));
  const double l = d.length;
  bool added = false;
  for (int e = 0; e < 2; ++e) {
    const double se = e == 0 ? 0.0 : l;
    bool listed = false;
    for (const auto& z : d.zeros) listed |= std::abs(z.at.s - se) <= 1e-3 * l;
    if (listed) continue;
    ZeroCurvaturePoint z;
    z.at = curve.at_parameter(e == 0 ? curve.first_parameter() : curve.last_parameter());
    z.at.kappa -= o.natural_curvature;
    z.kind = ZeroKind::AtEnd;
    const double tol = o.check.end_zero_tolerance;
    if (std::abs(d.a + d.b.dot(z.at.point)) <= tol * m_max && std::abs(z.at.kappa) <= tol * zeros.kappa_scale) {
      d.zeros.push_back(z);
      added = true;
    }
  }
  if (added)
    std::sort(d.zeros.begin(), d.zeros.end(),
              [](const ZeroCurvaturePoint& x, const ZeroCurvaturePoint& y) { return x.at.s < y.at.s; });
}

void add_end_zeros(const EquilibriumCheck& check, ZeroCurvatureResult& zeros, StripDesign& d) {
  if (check.end_zeros.empty()) return;
  zeros.points.insert(zeros.points.end(), check.end_zeros.begin(), check.end_zeros.end());
  std::sort(zeros.points.begin(), zeros.points.end(),
            [](const ZeroCurvaturePoint& x, const ZeroCurvaturePoint& y) { return x.at.s < y.at.s; });
  d.zeros = zeros.points;
}

void finish_outputs(const StripDesignOptions& o, StripDesign& d) {
  const double h3 = o.thickness * o.thickness * o.thickness;
  d.width.resize(d.samples.size());
  d.bending_stiffness.resize(d.samples.size());
  for (size_t i = 0; i < d.samples.size(); ++i) {
    d.width[i] = o.min_width * d.samples[i].K;
    d.bending_stiffness[i] = o.youngs_modulus * d.width[i] * h3 / 12.0;
  }
  d.outline.clear();
  for (size_t i = 0; i < d.samples.size(); ++i)
    d.outline.emplace_back(d.samples[i].s, -0.5 * d.width[i]);
  for (size_t i = d.samples.size(); i-- > 0;)
    d.outline.emplace_back(d.samples[i].s, 0.5 * d.width[i]);
}

}  // namespace

std::vector<double> composite_inner_width(const std::vector<double>& K,
                                          const StripDesignOptions::Composite& c) {
  const double h1 = c.outer_thickness, h2 = c.inner_thickness, w1 = c.outer_width;
  const double P1 = h1 * h1 * h1, P12 = std::pow(h1 + h2, 3), P2 = P12 - P1;
  const double kmax = *std::max_element(K.begin(), K.end());
  const double scale = P12 * w1 / kmax;
  std::vector<double> w2(K.size());
  for (size_t i = 0; i < K.size(); ++i) w2[i] = std::clamp((scale * K[i] - P1 * w1) / P2, 0.0, w1);
  return w2;
}

namespace {

bool needs_general_lp(const StripDesignOptions& o) {
  return o.gravity.enabled || !o.boundary.kinematic() || !o.law.linear() ||
         o.natural_curvature != 0.0 || o.fixed_samples > 0;
}

void validate_general(const StripDesignOptions& o) {
  o.law.validate();
  PARAFAB_VERIFY(std::isfinite(o.natural_curvature),
                 "natural_curvature must be finite, got " << o.natural_curvature);
  if (o.gravity.enabled) {
    PARAFAB_VERIFY(std::isfinite(o.gravity.gravito_bending) && o.gravity.gravito_bending > 0,
                   "gravity.gravito_bending (βl³, m³) must be positive, got "
                       << o.gravity.gravito_bending);
    PARAFAB_VERIFY(std::isfinite(o.gravity.direction.norm()) && o.gravity.direction.norm() > 0,
                   "gravity.direction must be a non-zero vector, got (" << o.gravity.direction.x()
                       << ", " << o.gravity.direction.y() << ")");
  }
  PARAFAB_VERIFY(std::isfinite(o.load_tolerance) && o.load_tolerance > 0,
                 "load_tolerance must be positive, got " << o.load_tolerance);
  PARAFAB_VERIFY(o.fixed_samples == 0 || o.fixed_samples >= 4,
                 "fixed_samples must be 0 or >= 4, got " << o.fixed_samples);
}

// Gravity, boundary variants, nonlinear laws and natural curvature: the LP of Eq. 4.6 on
// samples carrying the effective curvature μ = m(κ − κ₀).
void design_general(const PlaneCurve& curve, const StripDesignOptions& o, StripDesign& d) {
  validate_general(o);
  d.general_lp = true;
  const double l = d.length;
  Clock::time_point tp = Clock::now();
  ZeroCurvatureOptions zo = o.zeros;
  zo.natural_curvature = o.natural_curvature;
  ZeroCurvatureResult zeros = find_zero_curvature(curve, zo);
  bending_strain(curve, zeros, o, d);
  const Vec2 load = o.gravity.load();
  auto fail = [&](const std::string& code, const std::string& why, double s) {
    d.reason_code = code;
    d.reason = why;
    d.reason_s = s;
  };

  // A free end angle needs zero moment there, hence κ = κ₀ at that end (§4.3.3). An end
  // whose |κ − κ₀|·l is below free_angle_tolerance counts as such a zero.
  for (int end = 0; end < 2; ++end) {
    const StripEnd& e = end == 0 ? o.boundary.start : o.boundary.end;
    if (!e.free_angle || zeros.straight) continue;
    const double s_end = end == 0 ? 0.0 : l;
    bool has_zero = false;
    for (const auto& z : zeros.points)
      has_zero |= z.kind == ZeroKind::AtEnd && std::abs(z.at.s - s_end) <= 1e-9 * l;
    if (has_zero) continue;
    CurvePoint p = curve.at_arc_length(s_end);
    if (std::abs(p.kappa - o.natural_curvature) * l <= o.free_angle_tolerance) {
      p.kappa -= o.natural_curvature;
      zeros.points.insert(end == 0 ? zeros.points.begin() : zeros.points.end(), {p, ZeroKind::AtEnd});
      continue;
    }
    PARAFAB_INPUT_ERROR("boundary." << (end == 0 ? "start" : "end")
                        << ".free_angle: a free end angle carries no moment, so κ must equal κ₀ = "
                        << o.natural_curvature << " 1/m at the " << (end == 0 ? "start" : "end")
                        << " (s = " << s_end << "), but κ = " << p.kappa
                        << " 1/m there; clamp the angle or end the curve with zero curvature");
  }
  d.zeros = zeros.points;
  // The moment law must be injective on the curvature range the curve uses (Appendix A.5).
  double used = 0, used_s = 0;
  {
    for (size_t i = 0; i < zeros.scan_kappa.size(); ++i) {
      const double k = std::abs(zeros.scan_kappa[i]);  // |κ − κ₀|
      if (k > used) used = k, used_s = zeros.scan_parameters[i];
    }
    used_s = curve.arc_length_at(used_s);
    // Ideal plasticity (H = 0, App. A.5) keeps m(κ) = m(κ_lim) beyond the limit: the design
    // replaces κ by κ_eff = min(|κ|, κ_lim)·sign κ and the excess becomes a permanent set, so
    // only the elastic part up to the limit must be injective.
    MomentLaw elastic = o.law;
    elastic.curvature_limit = INFINITY;
    const double lim = elastic.injective_limit();
    const double used_elastic = std::min(used, o.law.curvature_limit);
    if (used_elastic >= lim) {
      if (o.law.cubic < 0 && std::abs(lim - 1.0 / std::sqrt(-3.0 * o.law.cubic)) <= 1e-12 * lim)
        PARAFAB_INPUT_ERROR("material.law.cubic = " << o.law.cubic << " makes m(κ) = κ + cκ³ decrease "
                            "beyond |κ − κ₀| = " << lim << " 1/m, but the curve reaches |κ − κ₀| = "
                            << used << " 1/m at s = " << used_s
                            << ": the moment law is not injective on the used range");
      for (size_t i = 1; i < o.law.table_moment.size(); ++i)
        if (o.law.table_curvature[i - 1] == lim && o.law.table_moment[i] <= o.law.table_moment[i - 1])
          PARAFAB_INPUT_ERROR("material.law.table_moment[" << i << "] = " << o.law.table_moment[i]
                              << " does not exceed table_moment[" << i - 1 << "] = "
                              << o.law.table_moment[i - 1] << ": m(κ) stops increasing at |κ − κ₀| = "
                              << lim << " 1/m, but the curve reaches " << used << " 1/m at s = "
                              << used_s << ": the moment law is not injective on the used range");
    }
    if (used > o.law.curvature_limit) d.max_plastic_curvature = used;
  }

  if (zeros.straight) {
    const Vec2 t = curve.at_arc_length(0).tangent;
    const bool along = load.norm() == 0 || std::abs(t.x() * load.y() - t.y() * load.x()) <= 1e-12 * load.norm();
    if (!along) {
      fail("straight_under_gravity", "the curve is straight (κ = κ₀ everywhere) but gravity is not "
           "along it: any strip sags under its weight", -1);
      return;
    }
    d.feasible = true;
    d.converged = true;
    for (const auto& p : sample_by_arc_length(curve, o.initial_samples, {}))
      d.samples.push_back({p.s, p.point, p.kappa, 1.0});
    d.lp_samples = static_cast<int>(d.samples.size());
    d.R = 1;
    d.R_first = 1;
    return;
  }
  d.phases.zeros = lap(tp);
  const EquilibriumCheck check = check_equilibrium(curve, zeros, o.check);
  add_end_zeros(check, zeros, d);
  d.phases.check = lap(tp);
  const bool line_reason = check.reason == Infeasibility::NotCollinear ||
                           check.reason == Infeasibility::LineTangentAtInflection ||
                           check.reason == Infeasibility::LineCrossesCurve;
  // Under gravity there is no straight inflection line: only conditions on κ itself apply,
  // and the LP decides the rest.
  if (!check.feasible() && !(line_reason && o.gravity.enabled)) {
    fail(to_code(check.reason), check.message, check.where_s);
    return;
  }
  d.collinearity_error = check.collinearity_error;

  ArcLengthSampleCache cache;
  auto lp_samples = [&](int count) {
    std::vector<StripLpSample> out;
    for (const auto& p : sample_by_arc_length(curve, count, zeros.points, &cache)) {
      StripLpSample q;
      q.s = p.s, q.point = p.point, q.tangent = p.tangent, q.kappa = p.kappa;
      q.mu = o.law.moment(p.kappa - o.natural_curvature);
      q.dmu_ds = o.law.slope(p.kappa - o.natural_curvature) * p.dkappa_ds;
      out.push_back(q);
    }
    for (const auto& z : zeros.points) {
      StripLpSample q;
      q.s = z.at.s, q.point = z.at.point, q.tangent = z.at.tangent;
      q.kappa = o.natural_curvature;
      q.mu = 0;
      q.dmu_ds = o.law.slope(0.0) * z.at.dkappa_ds;
      q.zero = true;
      out.push_back(q);
    }
    std::sort(out.begin(), out.end(), [](const StripLpSample& x, const StripLpSample& y) { return x.s < y.s; });
    return out;
  };
  GravityLpOptions go;
  go.load = load;
  go.boundary = o.boundary;
  go.smooth = o.smooth && o.gravity.enabled;
  go.smoothing_margin = o.smoothing_margin;
  go.inflection_rows = o.inflection_rows;
  go.form = o.lp_form;
  // Composite strips under gravity: weight ratio λ_i = (weight per length)/(K_i e) of both
  // layers, λ = h²(h₁w₁ + r h₂w₂)/(cK), iterated with the LP to a fixed point.
  const bool composite_weight = o.composite.enabled && o.gravity.enabled;
  const double h1 = o.composite.outer_thickness, h2 = o.composite.inner_thickness;
  const double w1 = o.composite.outer_width;
  auto composite_ratios = [&](std::vector<StripLpSample>& smp, const std::vector<double>& K) {
    const std::vector<double> w2 = composite_inner_width(K, o.composite);
    const double kmax = *std::max_element(K.begin(), K.end());
    const double c = std::pow(h1 + h2, 3) * w1 / kmax;
    double change = 0;
    for (size_t i = 0; i < smp.size(); ++i) {
      const double lam = o.thickness * o.thickness *
                         (h1 * w1 + o.composite.inner_density_ratio * h2 * w2[i]) / (c * K[i]);
      change = std::max(change, std::abs(lam / smp[i].weight - 1));
      smp[i].weight = lam;
    }
    return change;
  };
  auto solve = [&](std::vector<StripLpSample>& smp, const GravityLpOptions& opt) {
    GravityLpResult r = solve_gravity_lp(smp, l, opt);
    if (!composite_weight) return r;
    for (int it = 0; it < 100 && r.ok(); ++it) {
      d.weight_change = composite_ratios(smp, r.K);
      d.weight_iterations = it + 1;
      if (d.weight_change <= 1e-12) break;
      r = solve_gravity_lp(smp, l, opt);
    }
    return r;
  };
  if (composite_weight) {
    PARAFAB_VERIFY(h1 > 0 && h2 > 0 && w1 > 0, "composite: h1, h2 and outer_width must be positive, got "
                                                   << h1 << ", " << h2 << ", " << w1);
    PARAFAB_VERIFY(o.inflection_rows, "composite strips under gravity need inflection_rows");
  }
  GravityLpResult lp;
  std::vector<StripLpSample> smp;
  double R_prev = NAN;
  const int n0 = o.fixed_samples > 0 ? o.fixed_samples : o.initial_samples + 1;
  // Refine with phase one only; phase two (smoothing) runs once, on the final grid.
  const bool smooth = go.smooth;
  go.smooth = false;
  for (int n = n0;; n = std::min(2 * n - 1, o.max_samples)) {
    lap(tp);
    smp = lp_samples(n);
    d.phases.sampling += lap(tp);
    lp = solve(smp, go);
    d.phases.lp += lap(tp);
    if (o.warm_start && lp.ok()) go.warm_rows = lp.active_rows;
    d.refinement.push_back({n, lp.ok() ? lp.R_first : NAN, NAN});
    if (!lp.ok() || o.fixed_samples > 0) { d.converged = lp.ok(); break; }
    if (std::isfinite(R_prev) && std::abs(lp.R_first / R_prev - 1) <= o.load_tolerance) {
      d.converged = true;
      break;
    }
    R_prev = lp.R_first;
    if (n >= o.max_samples) break;
  }
  if (lp.ok() && smooth) {
    go.smooth = true;
    // Phase one on the final grid was solved by the last refinement step: reused (a composite
    // strip's weights change with every solve, so it solves again).
    GravityLpResult last = lp;
    if (!composite_weight) go.phase_one = &last.phase_one_lp;
    lap(tp);
    lp = solve(smp, go);
    d.phases.lp += lap(tp);
  }
  d.lp_samples = static_cast<int>(smp.size());
  d.lp_iterations = lp.iterations_first + lp.iterations_second;
  d.lp_seconds = lp.seconds_first;
  d.lp_seconds_second = lp.seconds_second;
  d.lp_message = lp.message;
  d.zero_consistency = lp.zero_consistency;
  if (!lp.ok()) {
    std::ostringstream os;
    os << "no stiffness profile keeps K positive along the curve";
    if (o.gravity.enabled) os << " under gravity (LP Eq. 4.6 ";
    else os << " (LP Eq. 4.4 ";
    os << to_string(lp.status) << ")";
    if (!o.boundary.kinematic()) os << " with the given free end directions";
    if (!lp.message.empty()) os << ": " << lp.message;
    fail(lp.zero_consistency > go.zero_consistency_tolerance ? "zeros_inconsistent"
                                                              : to_code(Infeasibility::NoLineAvoidsCurve),
         os.str(), zeros.points.size() == 1 ? zeros.points[0].at.s : -1);
    return;
  }
  const std::vector<StripLpSample>& used_smp = smp;
  size_t j = 0;
  for (const auto& p : used_smp) {
    if (!o.inflection_rows && p.zero) continue;
    d.samples.push_back({p.s, p.point, p.kappa, lp.K[j++]});
    if (composite_weight) d.weight_ratio.push_back(p.weight);
  }
  if (o.gravity.enabled) {  // weight per length [N/m]; ρg = E h²/(12 βl³)
    const double rho_g = o.youngs_modulus * o.thickness * o.thickness / (12 * o.gravity.gravito_bending);
    std::vector<double> K;
    for (const auto& p : d.samples) K.push_back(p.K);
    std::vector<double> w2;
    if (composite_weight) w2 = composite_inner_width(K, o.composite);
    for (size_t i = 0; i < K.size(); ++i)
      d.weight_per_length.push_back(
          composite_weight ? rho_g * (h1 * w1 + o.composite.inner_density_ratio * h2 * w2[i])
                           : rho_g * o.thickness * o.min_width * K[i]);
  }
  d.a = lp.a;
  d.b = lp.b;
  d.R = lp.R;
  d.R_first = lp.R_first;
  d.smoothed = lp.smoothed;
  d.tv_first = lp.tv_first;
  d.tv = lp.tv;
  d.start_force = lp.start_force;
  d.end_force = lp.end_force;
  d.feasible = true;
}

}  // namespace

StripDesign design_strip(const BSplineCurve2& bspline, const StripDesignOptions& options) {
  const auto t0 = std::chrono::steady_clock::now();
  validate(options);
  const PlaneCurve curve(bspline);
  StripDesign d;
  d.length = curve.length();
  d.phases.curve = std::chrono::duration<double>(Clock::now() - t0).count();
  auto elapsed = [&] {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  };
  if (needs_general_lp(options)) {
    design_general(curve, options, d);
    Clock::time_point tp = Clock::now();
    if (d.feasible) finish_outputs(options, d);
    d.phases.outputs = lap(tp);
    d.total_seconds = elapsed();
    return d;
  }
  Clock::time_point tp = Clock::now();
  ZeroCurvatureResult zeros = find_zero_curvature(curve, options.zeros);
  bending_strain(curve, zeros, options, d);
  d.zeros = zeros.points;
  d.phases.zeros = lap(tp);

  if (zeros.straight) {  // a line segment: any constant K, no bending
    d.feasible = true;
    d.converged = true;
    for (const auto& p : sample_by_arc_length(curve, options.initial_samples, {}))
      d.samples.push_back({p.s, p.point, 0.0, 1.0});
    d.lp_samples = static_cast<int>(d.samples.size());
    finish_outputs(options, d);
    d.total_seconds = elapsed();
    return d;
  }
  const EquilibriumCheck check = check_equilibrium(curve, zeros, options.check);
  add_end_zeros(check, zeros, d);
  d.phases.check = lap(tp);
  if (!check.feasible()) {
    d.reason_code = to_code(check.reason);
    d.reason = check.message;
    d.reason_s = check.where_s;
    d.total_seconds = elapsed();
    return d;
  }

  std::vector<CurvePoint> zero_points;
  std::vector<Vec2> line_points;
  for (const auto& z : zeros.points) zero_points.push_back(z.at), line_points.push_back(z.at.point);
  if (check.line_known) {  // ≥ 2 zeros: the fitted line (exact through two, within tolerance of more)
    line_points = {check.line_point, check.line_point + d.length * check.line_direction};
    d.collinearity_error = check.collinearity_error;
  }
  StiffnessLpOptions lpo;
  lpo.form = options.lp_form;
  StiffnessLpResult lp;
  std::vector<CurvePoint> samples;
  // Nested grids (count − 1 doubles): every refinement keeps the previous samples. The LP
  // optimum R_n on the samples is a lower bound of the optimal R*, and the ratio of the
  // LP's own line on the continuous curve, R_c ≥ R*, an upper bound: refine until
  // R_c / R_n − 1 ≤ tolerance. R_c is estimated (the largest sampled extrema refined by
  // golden-section search), so the gap is an estimate of the error of R, not a certificate.
  ContinuousRatio cont;
  ArcLengthSampleCache cache;
  for (int n = options.initial_samples + 1;; n = std::min(2 * n - 1, options.max_samples)) {
    lap(tp);
    samples = sample_by_arc_length(curve, n, zeros.points, &cache);
    d.phases.sampling += lap(tp);
    lp = solve_stiffness_lp(samples, zero_points, line_points, d.length, lpo);
    d.phases.lp += lap(tp);
    if (options.warm_start_eq44 && lp.ok()) lpo.warm_samples = lp.active_samples, lpo.warm_other = lp.active_other;
    if (!lp.ok()) {
      d.refinement.push_back({n, NAN, NAN});
      break;
    }
    cont = continuous_ratio(curve, samples, zero_points, lp.a, lp.b);
    d.phases.ratio += lap(tp);
    d.refinement.push_back({n, lp.R, cont.ratio});
    if (cont.ratio / lp.R - 1 <= options.tolerance) {
      d.converged = true;
      break;
    }
    if (n >= options.max_samples) break;
  }
  d.R_continuous = cont.ratio;
  d.lp_samples = static_cast<int>(samples.size());
  d.lp_iterations = lp.iterations;
  d.lp_seconds = lp.seconds;
  d.lp_message = lp.message;
  if (!lp.ok()) {
    std::ostringstream os;
    d.reason_code = to_code(Infeasibility::NoLineAvoidsCurve);
    if (zeros.points.size() == 1) {
      d.reason_s = zeros.points[0].at.s;
      os << "every line through the inflection at s = " << d.reason_s
         << " meets the curve at another point, so K would change sign (LP Eq. 4.4 "
         << to_string(lp.status) << ")";
    } else {
      os << "no line a + <b, x> = 0 keeps K = (a + <b, γ>)/κ positive along the curve (LP Eq. 4.4 "
         << to_string(lp.status) << ")";
    }
    d.reason = os.str();
    d.total_seconds = elapsed();
    return d;
  }

  lap(tp);
  // Normalize K so that min K = 1 exactly, over samples and zeros alike.
  std::vector<StripSample> all;
  all.reserve(samples.size() + zero_points.size());
  for (const auto& p : samples)
    all.push_back({p.s, p.point, p.kappa, stiffness_at(p, lp.a, lp.b, false)});
  for (const auto& z : zero_points) all.push_back({z.s, z.point, 0.0, stiffness_at(z, lp.a, lp.b, true)});
  // Both runs are in order of s already (sample_by_arc_length, the zero finder).
  std::inplace_merge(all.begin(), all.begin() + static_cast<std::ptrdiff_t>(samples.size()), all.end(),
                     [](const StripSample& x, const StripSample& y) { return x.s < y.s; });
  double kmin = INFINITY, kmax = 0;
  for (const auto& p : all) kmin = std::min(kmin, p.K), kmax = std::max(kmax, p.K);
  PARAFAB_VERIFY(kmin > 0, "stiffness LP returned a non-positive stiffness " << kmin
                               << " (LP violation " << lp.max_violation << ")");
  for (auto& p : all) p.K /= kmin;
  d.samples = std::move(all);
  d.a = lp.a / kmin;
  d.b = lp.b / kmin;
  d.R = kmax / kmin;
  d.feasible = true;
  report_line_end_zeros(curve, zeros, options, d);
  finish_outputs(options, d);
  d.phases.outputs = lap(tp);
  d.total_seconds = elapsed();
  return d;
}

std::vector<StripDesign> design_strips(const std::vector<BSplineCurve2>& curves,
                                       const StripDesignOptions& options, int threads) {
  PARAFAB_VERIFY(threads >= 0, "design_strips: threads must be >= 0 (0: default), got " << threads);
  std::vector<StripDesign> out(curves.size());
  std::vector<std::string> errors(curves.size());
  auto one = [&](size_t i) {
    try {
      out[i] = design_strip(curves[i], options);
    } catch (const std::exception& e) {
      errors[i] = e.what();
    }
  };
  if (threads == 1) {
    for (size_t i = 0; i < curves.size(); ++i) one(i);
  } else {
    tbb::task_arena arena(threads == 0 ? tbb::task_arena::automatic : threads);
    arena.execute([&] {
      tbb::parallel_for(size_t(0), curves.size(), [&](size_t i) { one(i); });
    });
  }
  for (size_t i = 0; i < errors.size(); ++i)
    if (!errors[i].empty()) PARAFAB_INPUT_ERROR("strip " << i << ": " << errors[i]);
  return out;
}

}  // namespace parafab
