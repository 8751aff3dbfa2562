// Loads, supports and material laws of a bending-active strip (thesis §4.3.3 boundary
// variants and natural curvature, §4.4.1 gravito-bending parameter βl³, Appendix A.5
// nonlinear moment laws and ideal plasticity). Shared by the design LPs and the simulator.
#pragma once

#include <cmath>
#include <string>
#include <vector>

#include "common/bspline.h"

namespace parafab {

/// Gravity on a strip of constant thickness: the weight per length is K/(βl³) along
/// `direction`, with βl³ = E h² / (12 ρ g) (thesis §4.4.1; β is the gravito-bending
/// parameter). The weight is proportional to the width, so K may carry any scale.
struct StripGravity {
  bool enabled = false;
  /// βl³ [m³]. Default: the thesis' fit for 200 gsm cardboard (8.86e-4 m³).
  double gravito_bending = 8.86e-4;
  /// Direction of gravity in the plane of the curve (normalized internally).
  Vec2 direction{0.0, -1.0};
  /// e = direction / βl³ [1/m³], zero when disabled: weight per length = K·e.
  Vec2 load() const;
  /// Enabled gravity with βl³ = gravito_bending_parameter(E, h, ρ, g).
  static StripGravity from_material(double youngs_modulus, double thickness, double density,
                                    double g = 9.81, Vec2 direction = Vec2(0.0, -1.0));
};

/// βl³ = E h² / (12 ρ g) [m³] from Young's modulus E [Pa], thickness h [m], density ρ
/// [kg/m³] and gravitational acceleration g [m/s²]. Throws parafab::Error naming the input.
double gravito_bending_parameter(double youngs_modulus, double thickness, double density,
                                 double g = 9.81);

/// Which constraints of one end are removed (thesis §4.3.3). Default: kinematic (clamped).
struct StripEnd {
  bool free_x = false;      ///< the end may slide along x: its reaction has no x component
  bool free_y = false;      ///< the end may slide along y
  bool free_angle = false;  ///< the end may rotate (pin): the moment, hence κ, vanishes there
};

struct StripBoundary {
  StripEnd start, end;
  bool kinematic() const {
    return !(start.free_x || start.free_y || start.free_angle || end.free_x || end.free_y ||
             end.free_angle);
  }
};

/// Moment per unit of linear-equivalent stiffness, m(κ) = M / K (thesis Appendix A.5):
/// m(κ) = κ + c κ³ for |κ| ≤ κ_lim (c > 0 hardening, c < 0 softening) and, beyond the
/// curvature limit (ideal plasticity), m = m(κ_lim) + H (|κ| − κ_lim) with sign(κ), where H
/// is `plastic_hardening` (0: ideally plastic). The linear law is the default (m = κ).
/// Alternatively a measured law: a table of (|κ|, m) pairs, piecewise linear, starting at
/// (0, 0), extended beyond its last entry with its last slope, odd in κ (replaces κ + c κ³;
/// slope 1 at κ = 0 makes K the linear-equivalent stiffness).
struct MomentLaw {
  double cubic = 0.0;                ///< c [m²]
  double curvature_limit = INFINITY; ///< κ_lim [1/m], > 0
  double plastic_hardening = 0.0;    ///< H ≥ 0 (slope beyond κ_lim, relative to the elastic 1)
  std::vector<double> table_curvature;  ///< |κ| [1/m], strictly increasing, first 0
  std::vector<double> table_moment;     ///< m(|κ|) [1/m], first 0
  bool linear() const {
    return cubic == 0.0 && !std::isfinite(curvature_limit) && table_curvature.empty();
  }
  double moment(double kappa) const;  ///< m(κ), odd
  double slope(double kappa) const;   ///< m'(κ)
  double energy(double kappa) const;  ///< ψ(κ) = ∫₀^κ m, even
  /// Throws parafab::Error naming the offending field for c, κ_lim, H or the table.
  void validate() const;
  /// Smallest |κ| ≥ 0 at which m stops increasing (+∞ if m is injective everywhere):
  /// 1/√(−3c) for softening, the start of the first non-increasing table segment, κ_lim for
  /// ideal plasticity (H = 0).
  double injective_limit() const;

 private:
  double elastic_moment(double a) const;  ///< for a = |κ| ≤ κ_lim
  double elastic_slope(double a) const;
  double elastic_energy(double a) const;
};

}  // namespace parafab
