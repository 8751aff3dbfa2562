// Surfaces of revolution tiled by strips of constant thickness without gaps (thesis §4.8.4):
// the strip width, hence K, must be proportional to the distance ⟨e₁, γ⟩ from the axis (e₂),
// so Eq. 4.3 becomes ⟨e₁, γ⟩ κ = a + ⟨b, γ⟩. Meridians are integrated from γ(0), α(0) with
// SUNDIALS CVODE (Adams, fixed-point iteration) in the state (x, y, α):
//   x′ = cos α,  y′ = sin α,  α′ = (a + b₁ x + b₂ y) / x,
// stopping (by CVODE's root finding) if the meridian reaches the axis. The n strips that
// tile the surface are flat planks tangent along the meridians whose edges meet their
// neighbours': width w(s) = 2 x(s) tan(π/n).
#pragma once

#include <string>
#include <vector>

#include "common/bspline.h"

namespace parafab {

struct RevolutionMeridianOptions {
  double a = 0;                 ///< [1/m · m] = dimensionless
  Vec2 b{0, 0};                 ///< [1/m]
  Vec2 start{1, 0};             ///< γ(0) = (x, y), x > 0 the distance from the axis [m]
  double start_angle = M_PI / 2;  ///< α(0) [rad]
  double length = 1;            ///< arc length to integrate [m]
  int output_points = 401;      ///< equally spaced in s
  double relative_tolerance = 1e-10;
  double absolute_tolerance = 1e-13;  ///< times the length
  double min_radius = 1e-6;     ///< stop when x < min_radius · length
};

struct RevolutionMeridian {
  bool complete = false;        ///< reached `length` without meeting the axis
  std::vector<double> s;
  std::vector<Vec2> points;
  std::vector<double> angle, kappa;
  double reached_length = 0;
  double residual = 0;          ///< max |x κ − (a + ⟨b, γ⟩)| / max |a + ⟨b, γ⟩| at the outputs
  long steps = 0;               ///< CVODE internal steps
  double seconds = 0;
  std::string message;
};

/// Throws parafab::Error for x(0) ≤ 0, non-positive length, fewer than 2 output points.
RevolutionMeridian integrate_revolution_meridian(const RevolutionMeridianOptions& options);

struct RevolutionStripsOptions {
  int strips = 12;              ///< n around the axis
  double youngs_modulus = 3e9;  ///< [Pa]
  double thickness = 0.5e-3;    ///< [m]
};

struct RevolutionStrips {
  int count = 0;
  std::vector<double> s, width, bending_stiffness;  ///< w = 2 x tan(π/n), K = E w h³/12
  double R = 1;                 ///< max w / min w
  std::vector<Vec2> outline;    ///< flat strip, centreline on +x, CCW polygon
};

RevolutionStrips revolution_strips(const RevolutionMeridian& meridian,
                                   const RevolutionStripsOptions& options = {});

}  // namespace parafab
