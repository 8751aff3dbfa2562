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
  std::vector<CurvePoint> out;
  out.reserve(count);
  for (int k = 0; k < count; ++k) {
    const double s = l * k / (count - 1);
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
  double prev_R = -1;
  // Nested grids (count − 1 doubles): every refinement keeps the previous samples, so R
  // grows monotonically towards sup K.
  for (int n = options.initial_samples + 1;; n = std::min(2 * n - 1, options.max_samples)) {
    samples = sample_by_arc_length(curve, n, zeros.points);
    lp = solve_stiffness_lp(samples, zero_points, line_points, d.length, lpo);
    d.refinement.emplace_back(n, lp.ok() ? lp.R : NAN);
    if (!lp.ok()) break;
    if (prev_R > 0 && std::abs(lp.R - prev_R) <= options.tolerance * lp.R) {
      d.converged = true;
      break;
    }
    if (n >= options.max_samples) break;
    prev_R = lp.R;
  }
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
