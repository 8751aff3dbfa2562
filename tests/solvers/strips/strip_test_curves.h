// Test curves for the strip solvers: RK4 integration of curvature laws, and the plane curves
// used across the strip tests (no, one, two, three inflections, a spiral), all about 0.3–0.5 m
// long so that the thesis' cardboard (βl³ = 8.86e-4 m³) sags visibly.
#pragma once

#include <cmath>
#include <functional>
#include <vector>

#include "common/bspline.h"

namespace parafab::test {

// State (x, y, α, extra...) integrated with classical RK4.
template <int D>
using State = Eigen::Matrix<double, D, 1>;

template <int D>
std::vector<State<D>> rk4(const std::function<State<D>(double, const State<D>&)>& f, State<D> y,
                          double s0, double s1, int steps, int stride) {
  const double h = (s1 - s0) / steps;
  std::vector<State<D>> out{y};
  for (int i = 0; i < steps; ++i) {
    const double s = s0 + i * h;
    const State<D> k1 = f(s, y), k2 = f(s + h / 2, y + h / 2 * k1), k3 = f(s + h / 2, y + h / 2 * k2),
                   k4 = f(s + h, y + h * k3);
    y += h / 6 * (k1 + 2 * k2 + 2 * k3 + k4);
    if ((i + 1) % stride == 0) out.push_back(y);
  }
  return out;
}

// Curve with curvature κ(s) on [0, l] from the origin with tangent angle α0.
inline BSplineCurve2 curve_from_curvature(const std::function<double(double)>& kappa, double l,
                                          double alpha0 = 0.0, int points = 801) {
  const int stride = 20;
  auto f = [&](double s, const State<3>& q) {
    return State<3>(std::cos(q(2)), std::sin(q(2)), kappa(s));
  };
  const auto st = rk4<3>(f, State<3>(0, 0, alpha0), 0.0, l, (points - 1) * stride, stride);
  std::vector<Vec2> pts;
  for (const auto& q : st) pts.emplace_back(q(0), q(1));
  return interpolate_points(pts, 5);
}

inline BSplineCurve2 graph_curve(const std::function<double(double)>& y, double x0, double x1,
                                 int points = 601) {
  std::vector<Vec2> pts;
  for (int i = 0; i < points; ++i) {
    const double x = x0 + (x1 - x0) * i / (points - 1);
    pts.emplace_back(x, y(x));
  }
  return interpolate_points(pts, 5);
}

/// Ellipse segment (no inflection): semi-axes 0.2 × 0.12 m, angles 0.2 … 2.9 rad.
inline BSplineCurve2 ellipse_arc(double ax = 0.2, double ay = 0.12, double t0 = 0.2, double t1 = 2.9) {
  std::vector<Vec2> pts;
  for (int i = 0; i <= 600; ++i) {
    const double t = t0 + (t1 - t0) * i / 600;
    pts.emplace_back(ax * std::cos(t), ay * std::sin(t));
  }
  return interpolate_points(pts, 5);
}
/// One inflection at the origin: y = 0.15 (u³ − u) / 0.4, u = x/0.15 … scaled cubic.
inline BSplineCurve2 one_inflection() {
  return graph_curve([](double x) { const double u = x / 0.15; return 0.06 * (u * u * u - u); }, -0.135, 0.135);
}
/// Two inflections: y = x⁴ − x² on [−0.8, 0.8], scaled by 0.25.
inline BSplineCurve2 two_inflections() {
  return graph_curve([](double x) { const double u = x / 0.25; return 0.25 * (u * u * u * u - u * u); }, -0.2, 0.2);
}
/// Three inflections on y = 0: y = 0.03 sin(x/0.05) for x/0.05 ∈ [−1, 7.3].
inline BSplineCurve2 three_inflections() {
  return graph_curve([](double x) { return 0.03 * std::sin(x / 0.05); }, -0.05, 0.365, 801);
}
/// Spiral without inflection turning by about 1.6 turns: κ = 1/(0.03 + 0.12 s), l = 0.5 m.
inline BSplineCurve2 spiral() {
  return curve_from_curvature([](double s) { return 1.0 / (0.03 + 0.12 * s); }, 0.5, 0.0, 1201);
}

// K ≡ 1 under the weight e per length: κ' = ⟨b + (l − s) Re, γ'⟩ (differentiated Eq. 4.5),
// integrated with RK4 from κ(0) = kappa0.
inline BSplineCurve2 gravity_elastica(const Vec2& e, const Vec2& b, double kappa0, double alpha0, double l) {
  const Vec2 Re(-e.y(), e.x());
  auto f = [&](double s, const State<4>& q) {
    const Vec2 t(std::cos(q(2)), std::sin(q(2)));
    return State<4>(t.x(), t.y(), q(3), (b + (l - s) * Re).dot(t));
  };
  const auto st = rk4<4>(f, State<4>(0, 0, alpha0, kappa0), 0.0, l, 16000, 20);
  std::vector<Vec2> pts;
  for (const auto& q : st) pts.emplace_back(q(0), q(1));
  return interpolate_points(pts, 5);
}

}  // namespace parafab::test
