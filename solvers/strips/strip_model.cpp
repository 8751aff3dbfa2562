#include "strips/strip_model.h"

#include <algorithm>

#include "common/error.h"

namespace parafab {

Vec2 StripGravity::load() const {
  if (!enabled) return Vec2::Zero();
  return direction.normalized() / gravito_bending;
}

double gravito_bending_parameter(double E, double h, double rho, double g) {
  PARAFAB_VERIFY(std::isfinite(E) && E > 0, "material.E must be a positive modulus in Pa, got " << E);
  PARAFAB_VERIFY(std::isfinite(h) && h > 0, "material.thickness must be positive (metres), got " << h);
  PARAFAB_VERIFY(std::isfinite(rho) && rho > 0, "material.density must be positive (kg/m³), got " << rho);
  PARAFAB_VERIFY(std::isfinite(g) && g > 0, "gravity.g must be positive (m/s²), got " << g);
  return E * h * h / (12.0 * rho * g);
}

StripGravity StripGravity::from_material(double E, double h, double rho, double g, Vec2 direction) {
  StripGravity out;
  out.enabled = true;
  out.gravito_bending = gravito_bending_parameter(E, h, rho, g);
  PARAFAB_VERIFY(std::isfinite(direction.norm()) && direction.norm() > 0,
                 "gravity.direction must be a non-zero vector, got (" << direction.x() << ", "
                                                                      << direction.y() << ")");
  out.direction = direction;
  return out;
}

void MomentLaw::validate() const {
  PARAFAB_VERIFY(std::isfinite(cubic), "material.law.cubic must be finite, got " << cubic);
  PARAFAB_VERIFY(curvature_limit > 0, "material.law.curvature_limit must be positive (1/m), got "
                                          << curvature_limit);
  PARAFAB_VERIFY(std::isfinite(plastic_hardening) && plastic_hardening >= 0,
                 "material.law.plastic_hardening must be >= 0, got " << plastic_hardening);
  if (table_curvature.empty() && table_moment.empty()) return;
  PARAFAB_VERIFY(table_curvature.size() == table_moment.size() && table_curvature.size() >= 2,
                 "material.law.table_curvature and table_moment need the same length >= 2, got "
                     << table_curvature.size() << " and " << table_moment.size());
  PARAFAB_VERIFY(cubic == 0.0, "material.law: give either cubic or a table, not both (cubic = " << cubic << ")");
  PARAFAB_VERIFY(table_curvature[0] == 0.0 && table_moment[0] == 0.0,
                 "material.law.table must start at (0, 0), got (" << table_curvature[0] << ", "
                                                                 << table_moment[0] << ")");
  for (size_t i = 1; i < table_curvature.size(); ++i) {
    PARAFAB_VERIFY(std::isfinite(table_curvature[i]) && table_curvature[i] > table_curvature[i - 1],
                   "material.law.table_curvature[" << i << "] = " << table_curvature[i]
                       << " must be finite and greater than the previous entry");
    PARAFAB_VERIFY(std::isfinite(table_moment[i]),
                   "material.law.table_moment[" << i << "] is not finite");
  }
}

double MomentLaw::injective_limit() const {
  double lim = INFINITY;
  if (cubic < 0) lim = 1.0 / std::sqrt(-3.0 * cubic);
  for (size_t i = 1; i < table_moment.size(); ++i)
    if (table_moment[i] <= table_moment[i - 1]) { lim = std::min(lim, table_curvature[i - 1]); break; }
  if (plastic_hardening == 0.0) lim = std::min(lim, curvature_limit);
  return lim;
}

namespace {
// Segment of the table containing a ≥ 0 (the last one beyond the table).
size_t segment(const std::vector<double>& x, double a) {
  const size_t i = static_cast<size_t>(std::upper_bound(x.begin(), x.end(), a) - x.begin());
  return std::clamp<size_t>(i, 1, x.size() - 1);
}
}  // namespace

double MomentLaw::elastic_moment(double a) const {
  if (table_curvature.empty()) return a + cubic * a * a * a;
  const size_t i = segment(table_curvature, a);
  const double k0 = table_curvature[i - 1], m0 = table_moment[i - 1];
  return m0 + (table_moment[i] - m0) / (table_curvature[i] - k0) * (a - k0);
}

double MomentLaw::elastic_slope(double a) const {
  if (table_curvature.empty()) return 1.0 + 3.0 * cubic * a * a;
  const size_t i = segment(table_curvature, a);
  return (table_moment[i] - table_moment[i - 1]) / (table_curvature[i] - table_curvature[i - 1]);
}

double MomentLaw::elastic_energy(double a) const {
  if (table_curvature.empty()) return 0.5 * a * a + 0.25 * cubic * a * a * a * a;
  double e = 0;
  const size_t last = segment(table_curvature, a);
  for (size_t i = 1; i < last; ++i)
    e += 0.5 * (table_moment[i] + table_moment[i - 1]) * (table_curvature[i] - table_curvature[i - 1]);
  const double k0 = table_curvature[last - 1];
  return e + 0.5 * (table_moment[last - 1] + elastic_moment(a)) * (a - k0);
}

double MomentLaw::moment(double k) const {
  const double a = std::abs(k);
  const double m = a <= curvature_limit
                       ? elastic_moment(a)
                       : elastic_moment(curvature_limit) + plastic_hardening * (a - curvature_limit);
  return k >= 0 ? m : -m;
}

double MomentLaw::slope(double k) const {
  const double a = std::abs(k);
  return a <= curvature_limit ? elastic_slope(a) : plastic_hardening;
}

double MomentLaw::energy(double k) const {
  const double a = std::abs(k);
  if (a <= curvature_limit) return elastic_energy(a);
  const double d = a - curvature_limit;
  return elastic_energy(curvature_limit) + elastic_moment(curvature_limit) * d +
         0.5 * plastic_hardening * d * d;
}

}  // namespace parafab
