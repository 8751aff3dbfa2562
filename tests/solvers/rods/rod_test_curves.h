// Test curves for the rod suites: circular helix, the thesis's closed light-sculpture curve
// (§5.9.5), a Fourier curve, and plane B-splines lifted to R³, with exact derivatives.
#pragma once

#include <cmath>

#include "common/bspline.h"
#include "rods/space_curve.h"

namespace parafab::rod_test {

// (r cos t, r sin t, p t), t ∈ [0, t1].
inline SpaceCurve helix(double r, double p, double t1) {
  return SpaceCurve(
      [=](double t) {
        return std::array<Vec3, 4>{Vec3(r * std::cos(t), r * std::sin(t), p * t),
                                   Vec3(-r * std::sin(t), r * std::cos(t), p),
                                   Vec3(-r * std::cos(t), -r * std::sin(t), 0),
                                   Vec3(r * std::sin(t), -r * std::cos(t), 0)};
      },
      0.0, t1);
}

// γ(t) = scale·(r1 cos t + r2 cos(t/2 + p), r1 sin t + r2 sin(t/2 + p), a cos(3t/2)),
// r1 = 1, r2 = 1/4, p = 9/20, a = 2/5 (thesis §5.9.5), t ∈ [ta, tb].
inline SpaceCurve light_sculpture(double scale, double ta, double tb) {
  const double r1 = 1, r2 = 0.25, p = 0.45, a = 0.4;
  return SpaceCurve(
      [=](double t) {
        const double u = t / 2 + p, cu = std::cos(u), su = std::sin(u);
        const double c = std::cos(t), s = std::sin(t), c3 = std::cos(1.5 * t), s3 = std::sin(1.5 * t);
        std::array<Vec3, 4> d;
        d[0] = scale * Vec3(r1 * c + r2 * cu, r1 * s + r2 * su, a * c3);
        d[1] = scale * Vec3(-r1 * s - r2 / 2 * su, r1 * c + r2 / 2 * cu, -1.5 * a * s3);
        d[2] = scale * Vec3(-r1 * c - r2 / 4 * cu, -r1 * s - r2 / 4 * su, -2.25 * a * c3);
        d[3] = scale * Vec3(r1 * s + r2 / 8 * su, -r1 * c - r2 / 8 * cu, 3.375 * a * s3);
        return d;
      },
      ta, tb);
}

// Σ_k a_ck cos(kt) + b_ck sin(kt), k = 1..4, per coordinate c; t ∈ [0, t1].
struct FourierCoefficients {
  double a[3][4], b[3][4];
};
inline SpaceCurve fourier_curve(const FourierCoefficients& f, double t1) {
  return SpaceCurve(
      [f](double t) {
        std::array<Vec3, 4> d;
        for (auto& v : d) v.setZero();
        for (int c = 0; c < 3; ++c)
          for (int k = 1; k <= 4; ++k) {
            const double ck = std::cos(k * t), sk = std::sin(k * t), A = f.a[c][k - 1], B = f.b[c][k - 1];
            d[0](c) += A * ck + B * sk;
            d[1](c) += k * (-A * sk + B * ck);
            d[2](c) += k * k * (-A * ck - B * sk);
            d[3](c) += k * k * k * (A * sk - B * ck);
          }
        return d;
      },
      0.0, t1);
}

// A plane B-spline in the plane z = 0.
inline SpaceCurve lift(const BSplineCurve2& c) {
  return SpaceCurve(
      [c](double u) {
        const auto d = c.derivatives(u);
        std::array<Vec3, 4> out;
        for (int k = 0; k < 4; ++k) out[k] = Vec3(d[k].x(), d[k].y(), 0.0);
        return out;
      },
      c.first_parameter(), c.last_parameter(), 1024);
}

}  // namespace parafab::rod_test
