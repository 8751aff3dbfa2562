// The shape-derivative density of an element's bulk bilinear form (xfem::bulk_shape_density,
// thesis Eq. 6.31): at the rule's points it must be the derivative of vₑᵀKₑ(w)uₑ with respect to
// each weight, the points fixed. Checked against central differences of element_system's
// stiffness in every weight, for plain hex8, hex8 with condensed incompatible modes (whose
// zero-mean shift moves with the weights) and hex27, on an irregular rule of a part cell
// (measured 4.5e-11, 6.6e-11, 6.3e-11 relative; without the shift term the modes case fails).
// The Nitsche and traction densities (xfem::boundary_term_density) integrated over a patch must
// give element_system's boundary terms.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

#include "xfem/area_rules.h"
#include "xfem/linear_xfem.h"
#include "surface_maps.h"

namespace parafab::xfem {
namespace {

// A rule of 30 points scattered in the cell with positive weights summing to 40 % of the
// cell's volume (a cut cell's rule is not a tensor rule).
GridElement irregular_element() {
  GridElement el;
  el.box.min = Vec3(1, -2, 0.5);
  el.box.max = Vec3(3, 1, 2);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> unit(0, 1);
  const int n = 30;
  double sum = 0;
  for (int j = 0; j < n; ++j) {
    el.rule.points.push_back(el.box.min + el.box.size().cwiseProduct(Vec3(unit(rng), unit(rng), unit(rng))));
    el.rule.weights.push_back(0.5 + unit(rng));
    sum += el.rule.weights.back();
  }
  for (double& w : el.rule.weights) w *= 0.4 * el.box.volume() / sum;
  return el;
}

double bilinear(const GridElement& el, const Eigen::VectorXd& v, const Eigen::VectorXd& u, const ElasticMaterial& m,
                const LinearXfemOptions& o) {
  const ElementSystem s = element_system(el, m, {}, {}, o);
  return v.dot(s.K * u);
}

void check(ElementType type, bool modes, double tolerance) {
  LinearXfemOptions o;
  o.element = type;
  o.incompatible_modes = modes;
  ElasticMaterial m{210000, 0.3, 0};
  const GridElement el = irregular_element();
  const int n = 3 * nodes_per_element(type);
  std::mt19937 rng(11);
  std::normal_distribution<double> normal(0, 1e-3);
  Eigen::VectorXd u(n), v(n);
  for (int i = 0; i < n; ++i) u[i] = normal(rng), v[i] = normal(rng);
  const std::vector<double> psi = bulk_shape_density(el, v, u, m, o, el.rule.points);
  const std::vector<double> psi_uu = bulk_shape_density(el, u, u, m, o, el.rule.points);
  double worst = 0, scale = 0;
  for (size_t j = 0; j < el.rule.points.size(); ++j) {
    const double h = 1e-4 * el.rule.weights[j];
    GridElement plus = el, minus = el;
    plus.rule.weights[j] += h;
    minus.rule.weights[j] -= h;
    const double fd = (bilinear(plus, v, u, m, o) - bilinear(minus, v, u, m, o)) / (2 * h);
    const double fd_uu = (bilinear(plus, u, u, m, o) - bilinear(minus, u, u, m, o)) / (2 * h);
    worst = std::max({worst, std::abs(psi[j] - fd), std::abs(psi_uu[j] - fd_uu)});
    scale = std::max({scale, std::abs(fd), std::abs(fd_uu)});
  }
  std::printf("%s%s: largest |ψ − FD| / largest |FD| = %.2e\n", element_type_name(type),
              type == ElementType::Hex8 ? (modes ? " with incompatible modes" : " plain") : "", worst / scale);
  EXPECT_LE(worst, tolerance * scale);
}

TEST(BulkShapeDensity, IsTheWeightGradientOfPlainHex8) { check(ElementType::Hex8, false, 2e-10); }
TEST(BulkShapeDensity, IsTheWeightGradientOfHex8WithCondensedIncompatibleModes) { check(ElementType::Hex8, true, 2e-10); }
TEST(BulkShapeDensity, IsTheWeightGradientOfHex27) { check(ElementType::Hex27, false, 2e-10); }

using testing::PlaneMap;

void check_boundary(ElementType type) {
  LinearXfemOptions o;
  o.element = type;
  o.nitsche_beta = 50;
  ElasticMaterial m{210000, 0.3, 0};
  GridElement el;
  el.box.min = Vec3(1, -2, 0.5);
  el.box.max = Vec3(3, 1, 2);
  // A tilted plane through the cell, its region a quadrilateral in uv (counter-clockwise).
  Subvolume sv;
  sv.cell = el.box;
  CutPatch patch;
  patch.surface = std::make_shared<PlaneMap>(Vec3(1.2, -1.8, 0.7), Vec3(1.5, 0.2, 0.1), Vec3(-0.1, 2.4, 0.9));
  patch.loops.push_back({{Vec2(0, 0), Vec2(1, 0.1), Vec2(0.9, 0.8), Vec2(0.1, 1), Vec2(0, 0)}, 1});
  patch.source_face = 4;
  sv.patches.push_back(patch);
  el.subvolume = &sv;
  DirichletCondition dc;
  dc.face = 4;
  dc.components = Vec3(1, 0, 1);
  dc.offset = Vec3(1e-3, -2e-3, 5e-4);
  dc.gradient << 1e-4, 0, 2e-4, 0, -1e-4, 0, 3e-4, 0, 1e-4;
  TractionCondition tc{4, Vec3(3, -1, 2)};
  const int n = 3 * nodes_per_element(type);
  std::mt19937 rng(5);
  std::normal_distribution<double> normal(0, 1e-3);
  Eigen::VectorXd u(n);
  for (int i = 0; i < n; ++i) u[i] = normal(rng);
  const ElementSystem s = element_system(el, m, {dc}, {tc}, o, false);
  SurfaceRuleOptions so;
  so.area.degree = patch_rule_degree(o, patch, true);  // the solver's rule on the patch (face 4 is clamped)
  const SurfaceRule sr = surface_rule(patch, so);
  double stiffness = 0, load = 0;
  for (size_t q = 0; q < sr.points.size(); ++q) {
    const BoundaryTermDensity d = boundary_term_density(el, u, m, o, &dc, &tc, sr.points[q], sr.normals[q]);
    stiffness += sr.weights[q] * d.stiffness;
    load += sr.weights[q] * d.load;
  }
  const double K = u.dot(s.K * u), f = u.dot(s.f);
  std::printf("%s: uᵀK_Γu %.12g, densities %.12g; uᵀf_Γ %.12g, densities %.12g\n", element_type_name(type), K,
              stiffness, f, load);
  EXPECT_NEAR(stiffness, K, 1e-12 * std::abs(K));
  EXPECT_NEAR(load, f, 1e-12 * std::abs(f));
}

TEST(BoundaryTermDensity, IntegratesToTheNitscheAndTractionTermsOfHex8) { check_boundary(ElementType::Hex8); }
TEST(BoundaryTermDensity, IntegratesToTheNitscheAndTractionTermsOfHex27) { check_boundary(ElementType::Hex27); }


// The derivatives a support's own motion needs (∇_X with n held, ∂/∂n with X held) against
// central differences of the densities themselves, at points inside the cell, for a tilted
// normal, a partial Dirichlet condition with a prescribed linear field and a traction.
void check_boundary_derivatives(ElementType type, double tolerance) {
  LinearXfemOptions o;
  o.element = type;
  o.nitsche_beta = 50;
  ElasticMaterial m{210000, 0.3, 0};
  GridElement el;
  el.box.min = Vec3(1, -2, 0.5);
  el.box.max = Vec3(3, 1, 2);
  DirichletCondition dc;
  dc.face = 4;
  dc.components = Vec3(1, 0, 1);
  dc.offset = Vec3(1e-3, -2e-3, 5e-4);
  dc.gradient << 1e-4, 0, 2e-4, 0, -1e-4, 0, 3e-4, 0, 1e-4;
  TractionCondition tc{4, Vec3(3, -1, 2)};
  const int n = 3 * nodes_per_element(type);
  std::mt19937 rng(5);
  std::normal_distribution<double> normal(0, 1e-3);
  std::uniform_real_distribution<double> unit(0, 1);
  Eigen::VectorXd u(n);
  for (int i = 0; i < n; ++i) u[i] = normal(rng);
  double worst = 0;
  for (int trial = 0; trial < 5; ++trial) {
    const Vec3 X = el.box.min + el.box.size().cwiseProduct(Vec3(unit(rng), unit(rng), unit(rng)));
    const Vec3 nrm = Vec3(normal(rng), normal(rng), normal(rng)).normalized();
    const BoundaryTermDensity d = boundary_term_density(el, u, m, o, &dc, &tc, X, nrm);
    const double h = 1e-5;
    for (int c = 0; c < 3; ++c) {
      const Vec3 e = Vec3::Unit(c);
      const BoundaryTermDensity xp = boundary_term_density(el, u, m, o, &dc, &tc, X + h * e, nrm);
      const BoundaryTermDensity xm = boundary_term_density(el, u, m, o, &dc, &tc, X - h * e, nrm);
      const BoundaryTermDensity np = boundary_term_density(el, u, m, o, &dc, &tc, X, nrm + h * e);
      const BoundaryTermDensity nm = boundary_term_density(el, u, m, o, &dc, &tc, X, nrm - h * e);
      const auto rel = [](double exact, double plus, double minus, double h, double scale) {
        return std::abs(exact - (plus - minus) / (2 * h)) / scale;
      };
      const double ks = d.stiffness_gradient.norm() + d.stiffness_normal.norm(), ls = d.load_gradient.norm() + d.load_normal.norm(),
                   fs = d.flux_gradient.norm() + d.flux_normal.norm();
      ASSERT_GT(ks * ls * fs, 0);
      worst = std::max({worst, rel(d.stiffness_gradient[c], xp.stiffness, xm.stiffness, h, ks),
                        rel(d.load_gradient[c], xp.load, xm.load, h, ls), rel(d.flux_gradient[c], xp.flux, xm.flux, h, fs),
                        rel(d.stiffness_normal[c], np.stiffness, nm.stiffness, h, ks),
                        rel(d.load_normal[c], np.load, nm.load, h, ls), rel(d.flux_normal[c], np.flux, nm.flux, h, fs)});
    }
  }
  std::printf("%s: largest relative difference of the boundary densities' derivatives from central differences %.2e\n",
              element_type_name(type), worst);
  EXPECT_LE(worst, tolerance);
}

TEST(BoundaryTermDensity, SpatialAndNormalDerivativesOfHex8) { check_boundary_derivatives(ElementType::Hex8, 1e-10); }
TEST(BoundaryTermDensity, SpatialAndNormalDerivativesOfHex27) { check_boundary_derivatives(ElementType::Hex27, 5e-9); }

}  // namespace
}  // namespace parafab::xfem
