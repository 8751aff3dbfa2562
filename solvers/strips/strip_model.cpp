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
}

double MomentLaw::injective_limit() const {
  double lim = INFINITY;
  if (cubic < 0) lim = 1.0 / std::sqrt(-3.0 * cubic);
  if (plastic_hardening == 0.0) lim = std::min(lim, curvature_limit);
  return lim;
}

namespace {
double elastic_m(double c, double k) { return k + c * k * k * k; }
double elastic_psi(double c, double k) { return 0.5 * k * k + 0.25 * c * k * k * k * k; }
}  // namespace

double MomentLaw::moment(double k) const {
  const double a = std::abs(k);
  if (a <= curvature_limit) return elastic_m(cubic, k);
  const double m = elastic_m(cubic, curvature_limit) + plastic_hardening * (a - curvature_limit);
  return k > 0 ? m : -m;
}

double MomentLaw::slope(double k) const {
  const double a = std::abs(k);
  if (a <= curvature_limit) return 1.0 + 3.0 * cubic * k * k;
  return plastic_hardening;
}

double MomentLaw::energy(double k) const {
  const double a = std::abs(k);
  if (a <= curvature_limit) return elastic_psi(cubic, k);
  const double d = a - curvature_limit;
  return elastic_psi(cubic, curvature_limit) + elastic_m(cubic, curvature_limit) * d +
         0.5 * plastic_hardening * d * d;
}

}  // namespace parafab
