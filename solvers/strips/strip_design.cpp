#include "strips/strip_design.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <sstream>

#include "common/error.h"
#include "strips/stiffness_lp.h"

namespace parafab {

// Samples this close to a zero-curvature point (relative to the length) are left out: there
// K is a 0/0 ratio, represented exactly by the l'Hôpital row of the zero itself, and a line
// fitted within the collinearity tolerance may pass the zero on the wrong side.
constexpr double kZeroExclusion = 1e-6;

std::vector<CurvePoint> sample_by_arc_length(const PlaneCurve& curve, int count,
                                             const std::vector<ZeroCurvaturePoint>& zeros) {
  PARAFAB_VERIFY(count >= 2, "need at least 2 samples, got " << count);
  const double l = curve.length();
  // Equally spaced arc lengths plus the interior knots, where K may have a kink (κ' jumps on
  // a cubic) or a jump (κ jumps on a quadratic): there sup K is attained exactly.
  std::vector<double> at;
  at.reserve(count + curve.bspline().knots().size());
  for (int k = 0; k < count; ++k) at.push_back(l * k / (count - 1));
  const std::vector<double> bp = curve.bspline().breakpoints();
  for (size_t i = 1; i + 1 < bp.size(); ++i) at.push_back(curve.arc_length_at(bp[i]));
  std::sort(at.begin(), at.end());
  std::vector<CurvePoint> out;
  out.reserve(at.size());
  for (size_t k = 0; k < at.size(); ++k) {
    const double s = at[k];
    if (k > 0 && s - at[k - 1] <= 1e-12 * l) continue;
    bool near_zero = false;
    for (const auto& z : zeros) near_zero |= std::abs(z.at.s - s) <= kZeroExclusion * l;
    if (!near_zero) out.push_back(curve.at_arc_length(s));
  }
  return out;
}

namespace {

void validate(const StripDesignOptions& o) {
  PARAFAB_VERIFY(std::isfinite(o.youngs_modulus) && o.youngs_modulus > 0,
                 "material.E must be a positive modulus in Pa, got " << o.youngs_modulus);
  PARAFAB_VERIFY(std::isfinite(o.thickness) && o.thickness > 0,
                 "material.thickness must be positive (metres), got " << o.thickness);
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

// Refines every local extremum of K among the samples by golden-section search on the
// continuous curve between the neighbouring samples (intervals touching a zero-curvature
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
  auto K_at = [&](double s) { return stiffness_at(curve.at_arc_length(s), a, b, false); };
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
      const double lo = samples[i == 0 ? 0 : i - 1].s, hi = samples[std::min(i + 1, samples.size() - 1)].s;
      if (hi <= lo || has_zero(lo, hi)) continue;
      double x0 = lo, x3 = hi, x1 = x3 - g * (x3 - x0), x2 = x0 + g * (x3 - x0);
      double f1 = sign * K_at(x1), f2 = sign * K_at(x2);
      for (int it = 0; it < 80 && x3 - x0 > 1e-13 * l; ++it) {
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

StripDesign design_strip(const BSplineCurve2& bspline, const StripDesignOptions& options) {
  const auto t0 = std::chrono::steady_clock::now();
  validate(options);
  const PlaneCurve curve(bspline);
  StripDesign d;
  d.length = curve.length();
  const ZeroCurvatureResult zeros = find_zero_curvature(curve, options.zeros);
  d.zeros = zeros.points;
  auto elapsed = [&] {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  };

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
  // R_c / R_n − 1 ≤ tolerance, a certified bound on the error of R.
  ContinuousRatio cont;
  for (int n = options.initial_samples + 1;; n = std::min(2 * n - 1, options.max_samples)) {
    samples = sample_by_arc_length(curve, n, zeros.points);
    lp = solve_stiffness_lp(samples, zero_points, line_points, d.length, lpo);
    if (!lp.ok()) {
      d.refinement.push_back({n, NAN, NAN});
      break;
    }
    cont = continuous_ratio(curve, samples, zero_points, lp.a, lp.b);
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

  // Normalize K so that min K = 1 exactly, over samples and zeros alike.
  std::vector<StripSample> all;
  for (const auto& p : samples)
    all.push_back({p.s, p.point, p.kappa, stiffness_at(p, lp.a, lp.b, false)});
  for (const auto& z : zero_points) all.push_back({z.s, z.point, 0.0, stiffness_at(z, lp.a, lp.b, true)});
  std::sort(all.begin(), all.end(), [](const StripSample& x, const StripSample& y) { return x.s < y.s; });
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
  finish_outputs(options, d);
  d.total_seconds = elapsed();
  return d;
}

}  // namespace parafab
