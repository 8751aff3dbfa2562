// Curves for the strip stability tests and benchmark (thesis §4.5): the strip test curves
// with every boundary variant, gravity, natural curvature and a hardening law, plus
// inflectional elastica (K ≡ 1), which are stable or unstable depending on the number of
// inflections and the amplitude (thesis Fig. 4.9: clamped S-curves snap).
#pragma once

#include <string>
#include <vector>

#include "strips/strip_design.h"
#include "strip_test_curves.h"

namespace parafab::test {

/// Inflectional elastica with K ≡ 1 under an end force along x: κ′ = −P sin α from α(0) = 0,
/// κ(0) = 2√P sin(amplitude/2), cut where α returns to 0 for the `half`-th time, so it has
/// `half` inflections (at α = ±amplitude), all on one horizontal line.
inline BSplineCurve2 elastica(double P, double amplitude, int half) {
  const double k0 = 2 * std::sqrt(P) * std::sin(amplitude / 2);
  auto f = [P](double, const State<4>& q) {
    return State<4>(std::cos(q(2)), std::sin(q(2)), q(3), -P * std::sin(q(2)));
  };
  const double ds = 2e-5;
  State<4> q(0, 0, 0, k0);
  double s = 0, end = 0;
  int crossings = 0;
  while (true) {
    const State<4> qn = rk4<4>(f, q, s, s + ds, 1, 1).back();
    if (s > 0 && (q(2) > 0) != (qn(2) > 0) && ++crossings == half) {
      end = s + ds * q(2) / (q(2) - qn(2));
      break;
    }
    q = qn;
    s += ds;
  }
  const auto st = rk4<4>(f, State<4>(0, 0, 0, k0), 0.0, end, 800 * 20, 20);
  std::vector<Vec2> pts;
  for (const auto& x : st) pts.emplace_back(x(0), x(1));
  return interpolate_points(pts, 5);
}

struct StabilityCurve {
  std::string name;
  BSplineCurve2 curve;
  StripDesignOptions options;
};

inline std::vector<StabilityCurve> stability_curves() {
  std::vector<StabilityCurve> v;
  const StripDesignOptions plain;
  v.push_back({"ellipse arc", ellipse_arc(), plain});
  v.push_back({"one inflection", one_inflection(), plain});
  v.push_back({"two inflections", two_inflections(), plain});
  v.push_back({"three inflections", three_inflections(), plain});
  v.push_back({"spiral", spiral(), plain});
  for (int half : {1, 2, 3, 4})
    for (double amp : {0.5, 2.0}) {
      char name[64];
      std::snprintf(name, sizeof name, "elastica %d infl. amp %.1f", half, amp);
      v.push_back({name, elastica(100, amp, half), plain});
    }
  StripDesignOptions g;
  g.gravity.enabled = true;
  v.push_back({"ellipse arc, gravity", ellipse_arc(), g});
  StripDesignOptions fx;
  fx.boundary.end.free_x = true;
  v.push_back({"ellipse arc, end free in x", ellipse_arc(), fx});
  StripDesignOptions fy;
  fy.boundary.start.free_y = true;
  v.push_back({"ellipse arc, start free in y", ellipse_arc(), fy});
  StripDesignOptions fyg = fy;
  fyg.gravity.enabled = true;
  v.push_back({"ellipse arc, start free in y, gravity", ellipse_arc(), fyg});
  const BSplineCurve2 pin = curve_from_curvature([](double s) { return 40 * s * (1.2 - s); }, 0.35, 0.3);
  StripDesignOptions pa;
  pa.boundary.start.free_angle = true;
  v.push_back({"pinned start", pin, pa});
  StripDesignOptions pag = pa;
  pag.gravity.enabled = true;
  v.push_back({"pinned start, gravity", pin, pag});
  StripDesignOptions kap;
  kap.natural_curvature = 8.0;
  v.push_back({"ellipse arc, natural curvature 8/m", ellipse_arc(0.2, 0.12, 0.3, M_PI - 0.3), kap});
  StripDesignOptions law;
  law.law.cubic = 2e-3;
  v.push_back({"ellipse arc, cubic hardening", ellipse_arc(), law});
  return v;
}

}  // namespace parafab::test
