// Kirchhoff rod design (thesis ch. 5) against closed forms: helices are parallel equilibrium
// curves with constant circular sections; plane curves reproduce the strip stiffness of
// Eq. 4.4; designed sections satisfy the equilibrium equation Eq. 5.11 pointwise; κ = 0 is
// rejected with its location; a curve whose binormal lines no complex avoids is infeasible,
// with a conflict set checked by an independent Farkas certificate (NNLS).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "common/error.h"
#include "rod_test_curves.h"
#include "rods/rod_design.h"
#include "strips/strip_design.h"
#include "xfem/nnls.h"

namespace parafab {
namespace {

using rod_test::helix;

TEST(RodDesign, HelixIsParallelWithConstantCircularSections) {
  const double r = 0.1, p = 0.03;
  const SpaceCurve curve = helix(r, p, 3 * M_PI);
  RodDesignOptions o;
  const RodDesign d = design_rod(curve, 400, o);
  ASSERT_TRUE(d.ok()) << d.message;
  EXPECT_TRUE(d.lp.parallel);
  // The complex of the helix: c ∥ e3, c̄ = −(r²/p) c (all tangent lines in it).
  EXPECT_LT(std::hypot(d.c.x(), d.c.y()), 1e-9 * std::abs(d.c.z()));
  EXPECT_NEAR(d.c_bar.z() / d.c.z(), -r * r / p, 1e-9 * r * r / p);
  double tmax = 0, amin = INFINITY, amax = 0, ecc = 0;
  for (const auto& s : d.sections) {
    tmax = std::max(tmax, std::abs(s.twist) * curve.length());
    amin = std::min(amin, s.ellipse.a), amax = std::max(amax, s.ellipse.a);
    ecc = std::max(ecc, s.ellipse.a / s.ellipse.b - 1);
  }
  std::printf("[helix] max |twist|*L %.2e, max a/b-1 %.2e, a spread %.2e\n", tmax, ecc, amax / amin - 1);
  EXPECT_LT(tmax, 1e-9);
  EXPECT_LT(ecc, 1e-9);
  EXPECT_LT(amax / amin - 1, 1e-9);
  EXPECT_NEAR(amax, o.max_radius, 1e-12);
  // Bending stiffness of a circle: E·π a⁴/4 · κ = |moment|.
  const double kappa = r / (r * r + p * p);
  EXPECT_NEAR(o.material.youngs_modulus * M_PI * std::pow(amax, 4) / 4 * kappa, d.moment[0].norm(),
              1e-9 * d.moment[0].norm());
}

// Rational quadratic NURBS of the elliptic arc t ∈ [0.3, π − 0.3], semi-axes 0.30 and 0.15 m.
BSplineCurve2 elliptic_arc() {
  const double A = 0.30, B = 0.15, t0 = 0.3, t1 = M_PI - 0.3;
  const int pieces = 4;
  const double dt = (t1 - t0) / pieces;
  std::vector<Vec2> poles;
  std::vector<double> weights, knots{0, 0, 0};
  for (int i = 0; i < pieces; ++i) {
    const double ta = t0 + i * dt, tm = ta + dt / 2, tb = ta + dt, w = std::cos(dt / 2);
    if (i == 0) poles.emplace_back(A * std::cos(ta), B * std::sin(ta)), weights.push_back(1);
    poles.emplace_back(A * std::cos(tm) / w, B * std::sin(tm) / w);
    weights.push_back(w);
    poles.emplace_back(A * std::cos(tb), B * std::sin(tb));
    weights.push_back(1);
    if (i + 1 < pieces) knots.push_back(i + 1), knots.push_back(i + 1);
  }
  knots.insert(knots.end(), {double(pieces), double(pieces), double(pieces)});
  return BSplineCurve2(2, knots, poles, weights);
}

TEST(RodDesign, PlaneCurveGivesTheStripStiffnessProfile) {
  const BSplineCurve2 arc = elliptic_arc();
  const StripDesign strip = design_strip(arc);
  ASSERT_TRUE(strip.feasible) << strip.reason;
  ASSERT_GT(strip.R, 1.05);  // a non-trivial profile
  const SpaceCurve curve = rod_test::lift(arc);
  ASSERT_NEAR(curve.length(), strip.length, 1e-10);
  // The rod LP on the strip's own samples (both LPs then see the same points).
  std::vector<double> s;
  for (const auto& p : strip.samples) s.push_back(p.s);
  const std::vector<RodSample> at = sample_at(curve, s);
  const RodDesign d = design_rod(at);
  ASSERT_TRUE(d.ok()) << d.message;
  EXPECT_TRUE(d.lp.parallel);
  // Effective bending stiffness of the rod, K = ⟨γ'×γ'', h⟩/κ², against the strip's K.
  double qmin = INFINITY, qmax = 0, tw = 0;
  for (size_t i = 0; i < at.size(); ++i) {
    const Vec3 h = d.c.cross(at[i].point) + d.c_bar;
    const double K = at[i].omega_n().dot(h) / (at[i].kappa * at[i].kappa);
    const double q = K / strip.samples[i].K;
    qmin = std::min(qmin, q), qmax = std::max(qmax, q);
    tw = std::max(tw, std::abs(at[i].tangent.dot(h)) / h.norm());
  }
  std::printf("[plane] strip R %.6f, rod K ratio %.6f, K_rod/K_strip spread %.2e over %zu samples\n",
              strip.R, d.lp.stiffness_ratio, qmax / qmin - 1, at.size());
  EXPECT_LT(qmax / qmin - 1, 1e-7);
  EXPECT_NEAR(d.lp.stiffness_ratio, strip.R, 1e-7 * strip.R);
  EXPECT_LT(tw, 1e-9);  // plane: no twist
  for (const auto& sec : d.sections) EXPECT_LT(std::abs(sec.twist) * curve.length(), 1e-8);
}

// Eq. 5.11 at every sample, in the material frame Fβ: E·I·kn = Fnᵀh and μ·J·τβ = ⟨γ', h⟩.
TEST(RodDesign, SectionsSolveTheEquilibriumEquation) {
  const SpaceCurve curve = rod_test::light_sculpture(0.2, 0, 4 * M_PI / 3);
  RodDesignOptions o;
  o.lp.regularization_weight = 0.5;
  const RodDesign d = design_rod(curve, 400, o);
  ASSERT_TRUE(d.ok()) << d.message;
  EXPECT_FALSE(d.lp.parallel);
  const double E = o.material.youngs_modulus, mu = o.material.shear_modulus();
  double err = 0, terr = 0, ellipse_err = 0, twist_max = 0;
  for (size_t i = 0; i < d.samples.size(); ++i) {
    const RodSample& p = d.samples[i];
    const RodSection& sec = d.sections[i];
    const Vec3& h = d.moment[i];
    const Eigen::Vector2d kn(p.omega_n().dot(sec.n1), p.omega_n().dot(sec.n2));
    const Eigen::Vector2d f(sec.n1.dot(h), sec.n2.dot(h));
    err = std::max(err, (E * sec.I_material * kn - f).norm() / h.norm());
    terr = std::max(terr, std::abs(mu * sec.J * sec.twist - p.tangent.dot(h)) / h.norm());
    ellipse_err = std::max(ellipse_err, (sec.ellipse.area_moment() - sec.I_material).norm() / sec.I_material.norm());
    EXPECT_NEAR(sec.J, 4 * psi(sec.I_material), 1e-12 * sec.J);
    twist_max = std::max(twist_max, std::abs(sec.twist));
  }
  EXPECT_LT(err, 1e-12);
  EXPECT_LT(terr, 1e-12);
  EXPECT_LT(ellipse_err, 1e-12);
  EXPECT_GT(twist_max, 0.1);  // a general (twisted) design
  // The frame: n1 ⟂ γ', twist of Fβ = τβ (finite differences of the frame angle).
  for (size_t i = 1; i + 1 < d.samples.size(); i += 37) {
    const double ds = d.samples[i + 1].s - d.samples[i - 1].s;
    const double dtheta = d.sections[i + 1].frame_angle - d.sections[i - 1].frame_angle;
    EXPECT_NEAR(dtheta / ds + d.samples[i].torsion, d.sections[i].twist, 1e-3 * twist_max);
    EXPECT_LT(std::abs(d.sections[i].n1.dot(d.samples[i].tangent)), 1e-12);
  }
}

TEST(RodDesign, MostCircularEllipseAtTStar) {
  const SpaceCurve curve = rod_test::light_sculpture(0.2, 4 * M_PI / 3, 8 * M_PI / 3);
  std::vector<RodSample> samples = sample_by_arc_length(curve, 200);
  const LineComplexLpResult lp = solve_line_complex_lp(samples);
  ASSERT_TRUE(lp.ok());
  const auto h = complex_field(samples, lp.c, lp.c_bar);
  std::vector<std::vector<RodSection>> by_factor;
  for (double f : {0.8, 1.0, 1.25, 4.0}) {
    RodGeometryOptions go;
    go.circularity_factor = f;
    const auto g = generate_rod_geometry(samples, h, RodMaterial::smooth_sil_960(), go);
    ASSERT_TRUE(g.ok());
    by_factor.push_back(g.sections);
  }
  for (size_t i = 0; i < samples.size(); ++i) {
    auto ratio = [&](int k) { return by_factor[k][i].ellipse.a / by_factor[k][i].ellipse.b; };
    EXPECT_LE(ratio(1), ratio(0) * (1 + 1e-12));
    EXPECT_LE(ratio(1), ratio(2) * (1 + 1e-12));
    // t → ∞ elongates the ellipse along the bending axis kn (= B in Frénet coordinates).
    const RodSection& s = by_factor[3][i];
    const Vec3 major = std::cos(s.ellipse.angle) * s.n1 + std::sin(s.ellipse.angle) * s.n2;
    EXPECT_GT(std::abs(major.dot(samples[i].binormal)), 0.9);
  }
}

TEST(RodDesign, ZeroCurvatureIsRejectedWithItsLocation) {
  // γ(t) = (t, t³, t⁵) on [−0.7, 1]: κ = 0 exactly at t = 0 (between samples).
  const SpaceCurve curve(
      [](double t) {
        return std::array<Vec3, 4>{Vec3(t, t * t * t, std::pow(t, 5)), Vec3(1, 3 * t * t, 5 * std::pow(t, 4)),
                                   Vec3(0, 6 * t, 20 * t * t * t), Vec3(0, 6, 60 * t * t)};
      },
      -0.7, 1.0);
  const double s0 = curve.arc_length_at(0.0);
  try {
    design_rod(curve, 400);
    FAIL() << "a curve with kappa = 0 was accepted";
  } catch (const Error& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("curvature vanishes"), std::string::npos) << msg;
    const size_t at = msg.find("s = ");
    ASSERT_NE(at, std::string::npos) << msg;
    const double s = std::stod(msg.substr(at + 4));
    std::printf("[kappa=0] %s\n", msg.c_str());
    EXPECT_NEAR(s, s0, 1e-4 * curve.length());
  }
}

TEST(RodDesign, InvalidOptionsThrow) {
  const SpaceCurve curve = helix(0.1, 0.03, 3.0);
  RodDesignOptions o;
  o.max_radius = -1;
  EXPECT_THROW(design_rod(curve, 50, o), Error);
  o = {};
  o.material.poisson_ratio = 0.7;
  EXPECT_THROW(design_rod(curve, 50, o), Error);
  o = {};
  o.lp.regularization_weight = -0.1;
  EXPECT_THROW(design_rod(curve, 50, o), Error);
  o = {};
  o.geometry.circularity_factor = 0;
  EXPECT_THROW(design_rod(curve, 50, o), Error);
}

// A Fourier curve found by random search whose binormal lines no linear complex avoids.
rod_test::FourierCoefficients infeasible_coefficients() {
  return {{{-0.7, -0.0, -0.1, -0.0}, {0.0, -0.1, 0.2, 0.1}, {0.6, 0.2, 0.1, 0.0}},
          {{-1.1, 0.1, -0.1, -0.1}, {-0.3, 0.2, -0.1, 0.1}, {-0.2, -0.2, -0.1, -0.0}}};
}

TEST(RodDesign, InfeasibleCurveReportsBindingSamples) {
  const SpaceCurve curve = rod_test::fourier_curve(infeasible_coefficients(), 2 * M_PI * 0.9);
  for (int count : {200, 400, 800}) {
    const std::vector<RodSample> samples = sample_by_arc_length(curve, count);
    require_frenet_curve(curve, samples, 1e-2);  // a genuine Frénet curve
    const RodDesign d = design_rod(samples);
    ASSERT_EQ(d.status, RodDesignStatus::Infeasible) << count << " samples";
    const auto& b = d.lp.binding_samples;
    ASSERT_GE(b.size(), 2u);
    ASSERT_LE(b.size(), 7u);  // Carathéodory/Helly in R⁶
    EXPECT_NE(d.message.find("binding samples at s ="), std::string::npos);
    // Independent certificate (Farkas): y ≥ 0, Σy = 1, Σ y_i (ω_i, γ_i × ω_i) = 0, found by
    // NNLS, proves that no (c, c̄) has ⟨ω_i, c×γ_i + c̄⟩ > 0 on the binding samples.
    Eigen::MatrixXd A(7, b.size());
    for (size_t k = 0; k < b.size(); ++k) {
      const RodSample& p = samples[b[k]];
      const Vec3 w = p.omega_n().normalized();
      A.col(k) << w, p.point.cross(w), 1.0;
    }
    Eigen::VectorXd rhs = Eigen::VectorXd::Zero(7);
    rhs(6) = 1;
    const auto nn = xfem::solve_nnls(A, rhs);
    std::printf("[infeasible] %d samples: %zu binding samples, Farkas residual %.2e\n", count, b.size(),
                nn.residual_norm);
    EXPECT_LT(nn.residual_norm, 1e-9);
    EXPECT_GT(nn.x.minCoeff(), 0);  // every binding sample takes part (minimal set)
    for (size_t k = 0; k < b.size(); ++k) EXPECT_DOUBLE_EQ(d.lp.binding_s[k], samples[b[k]].s);
  }
}

TEST(RodDesign, DualAndPrimalLpFormsAgree) {
  const SpaceCurve curve = rod_test::light_sculpture(0.2, 8 * M_PI / 3, 4 * M_PI);
  const auto samples = sample_by_arc_length(curve, 300);
  LineComplexLpOptions a, b;
  b.form = LpForm::Primal;
  const auto ra = solve_line_complex_lp(samples, a), rb = solve_line_complex_lp(samples, b);
  ASSERT_TRUE(ra.ok() && rb.ok());
  EXPECT_NEAR(ra.R, rb.R, 1e-8);
  EXPECT_NEAR(ra.stiffness_ratio, rb.stiffness_ratio, 1e-6 * ra.stiffness_ratio);
}

}  // namespace
}  // namespace parafab

namespace parafab {
namespace {

// Eq. 5.19: each w_reg's solution is optimal against the others' (no other complex has a
// smaller max(|⟨T, h⟩|, w·|⟨N, h⟩|)), so w = 0 has the least twist couple.
TEST(RodDesign, RegularizationTradesTwistForSmoothness) {
  const SpaceCurve curve = rod_test::light_sculpture(0.2, 4 * M_PI / 3, 8 * M_PI / 3);
  const auto samples = sample_by_arc_length(curve, 300);
  const std::vector<double> weights{0.0, 0.3, 1.0, 3.0};
  std::vector<double> tw(weights.size(), 0), nm(weights.size(), 0), R(weights.size());
  const double L = curve.length();
  for (size_t k = 0; k < weights.size(); ++k) {
    LineComplexLpOptions o;
    o.regularization_weight = weights[k];
    const auto r = solve_line_complex_lp(samples, o);
    ASSERT_TRUE(r.ok());
    double mn = INFINITY;
    for (const auto& p : samples) {
      const Vec3 h = r.c.cross(p.point) + r.c_bar;
      mn = std::min(mn, p.omega_n().dot(h));
      tw[k] = std::max(tw[k], std::abs(p.tangent.dot(h)) / L);
      nm[k] = std::max(nm[k], std::abs(p.normal.dot(h)) / L);
    }
    EXPECT_NEAR(mn, 1.0, 1e-9);  // normalization min ⟨ωn, h⟩ = 1
    EXPECT_NEAR(r.twist_ratio, tw[k], 1e-9);
    EXPECT_NEAR(r.R, std::max(tw[k], weights[k] * nm[k]), 1e-9);
    R[k] = r.R;
    std::printf("[w_reg %.1f] R %.4f, max|<T,h>|/L %.4f, max|<N,h>|/L %.4f\n", weights[k], r.R, tw[k], nm[k]);
  }
  for (size_t k = 0; k < weights.size(); ++k)
    for (size_t j = 0; j < weights.size(); ++j)
      EXPECT_LE(R[k], std::max(tw[j], weights[k] * nm[j]) * (1 + 1e-6)) << k << " vs " << j;
  EXPECT_LT(tw[0], tw.back());  // regularization costs twist on this curve
  EXPECT_LT(nm.back(), nm[0]);  // and buys a smoother twist couple
}

}  // namespace
}  // namespace parafab
