// The local Nitsche penalty (LinearXfemOptions::NitschePenalty::Local, thesis Eq. 6.22): on a cut
// element with a clamped patch, p = κ·Λ with Λ the smallest constant of ‖M σ(v)n‖²_Γ ≤ Λ â(v, v).
// Checked here against an independent computation: the flux matrix B built in the test from the
// displacement gradient (σ = λ tr ε I + 2μ ε, t = σn), Λ as the largest eigenvalue of B on the
// range of â (eigendecomposition of â; the code shifts the rigid modes and uses Cholesky); then the
// coercivity it promises, vᵀKv ≥ a(v, v) − â(v, v)/κ for every v, as the smallest eigenvalue of
// the pencil (K − A, Â); and the default fixed penalty β = 100 on a thin piece (K indefinite),
// which is what made Newton fail on the turned rubber block at 12 cells.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <cstdio>
#include <memory>
#include <random>

#include "xfem/area_rules.h"
#include "xfem/linear_xfem.h"
#include "surface_maps.h"

namespace parafab::xfem {
namespace {

using testing::PlaneMap;

const Box3 kBox{Vec3(1, -2, 0.5), Vec3(3, 1, 2)};

// A cut element: `fraction` of the cell's volume in a scattered rule (positive weights), and a
// clamped tilted plane through the cell as its patch (face 4, components x and z prescribed).
struct CutElement {
  Subvolume sv;
  GridElement el;
  DirichletCondition dc;
};

std::unique_ptr<CutElement> cut_element(double fraction) {
  auto c = std::make_unique<CutElement>();
  c->el.box = kBox;
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> unit(0, 1);
  double sum = 0;
  for (int j = 0; j < 40; ++j) {
    c->el.rule.points.push_back(kBox.min + kBox.size().cwiseProduct(Vec3(unit(rng), unit(rng), unit(rng))));
    c->el.rule.weights.push_back(0.5 + unit(rng));
    sum += c->el.rule.weights.back();
  }
  for (double& w : c->el.rule.weights) w *= fraction * kBox.volume() / sum;
  c->sv.cell = kBox;
  CutPatch patch;
  patch.surface = std::make_shared<PlaneMap>(Vec3(1.2, -1.8, 0.7), Vec3(1.5, 0.2, 0.1), Vec3(-0.1, 2.4, 0.9));
  patch.loops.push_back({{Vec2(0, 0), Vec2(1, 0.1), Vec2(0.9, 0.8), Vec2(0.1, 1), Vec2(0, 0)}, 1});
  patch.source_face = 4;
  c->sv.patches.push_back(patch);
  c->el.subvolume = &c->sv;
  c->dc.face = 4;
  c->dc.components = Vec3(1, 0, 1);
  return c;
}

// The uncut cell: 3-point Gauss rule per axis.
GridElement uncut_cell() {
  GridElement el;
  el.box = kBox;
  const double x[3] = {0.5 - 0.5 * std::sqrt(0.6), 0.5, 0.5 + 0.5 * std::sqrt(0.6)}, w[3] = {5.0 / 18, 8.0 / 18, 5.0 / 18};
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      for (int k = 0; k < 3; ++k) {
        el.rule.points.push_back(kBox.min + Vec3(x[i], x[j], x[k]).cwiseProduct(kBox.size()));
        el.rule.weights.push_back(w[i] * w[j] * w[k] * kBox.volume());
      }
  return el;
}

// Shape-function gradients (nodes × 3) at X.
Eigen::MatrixXd gradients(ElementType type, const Vec3& X) {
  if (type == ElementType::Hex27) {
    Eigen::Matrix<double, 27, 1> N;
    Eigen::Matrix<double, 27, 3> G;
    triquadratic_shape(kBox, X, N, G);
    return G;
  }
  Eigen::Matrix<double, 8, 1> N;
  Eigen::Matrix<double, 8, 3> G;
  trilinear_shape(kBox, X, N, G);
  return G;
}

// B = Σ_q w_q Jᵀ M J over the patch, J v = traction σ(v)n, built from the displacement gradient.
Eigen::MatrixXd flux_matrix(const CutElement& c, const ElasticMaterial& m, ElementType type, int degree) {
  const int nodes = nodes_per_element(type), n = 3 * nodes;
  const double lambda = m.youngs_modulus * m.poisson_ratio / ((1 + m.poisson_ratio) * (1 - 2 * m.poisson_ratio));
  const double mu = m.youngs_modulus / (2 * (1 + m.poisson_ratio));
  SurfaceRuleOptions so;
  so.area.degree = degree;
  const SurfaceRule sr = surface_rule(c.sv.patches[0], so);
  Eigen::MatrixXd B = Eigen::MatrixXd::Zero(n, n);
  for (size_t q = 0; q < sr.points.size(); ++q) {
    const Eigen::MatrixXd G = gradients(type, sr.points[q]);
    Eigen::MatrixXd J(3, n);
    for (int a = 0; a < nodes; ++a)
      for (int i = 0; i < 3; ++i) {  // unit displacement of node a in direction i
        Eigen::Matrix3d grad = Eigen::Matrix3d::Zero();
        grad.row(i) = G.row(a);
        const Eigen::Matrix3d eps = 0.5 * (grad + grad.transpose());
        const Eigen::Matrix3d sigma = lambda * eps.trace() * Eigen::Matrix3d::Identity() + 2 * mu * eps;
        J.col(3 * a + i) = c.dc.components.asDiagonal() * (sigma * sr.normals[q]);
      }
    B.noalias() += sr.weights[q] * J.transpose() * J;
  }
  return B;
}

// Projector onto the rigid motions at the nodes (3 translations, 3 rotations).
Eigen::MatrixXd rigid_projector(ElementType type) {
  const int nodes = nodes_per_element(type);
  Eigen::MatrixXd R(3 * nodes, 6);
  for (int a = 0; a < nodes; ++a) {
    const Vec3 x = node_position(kBox, nodes, a) - 0.5 * (kBox.min + kBox.max);
    R.block<3, 3>(3 * a, 0).setIdentity();
    R.block<3, 1>(3 * a, 3) = Vec3::UnitX().cross(x);
    R.block<3, 1>(3 * a, 4) = Vec3::UnitY().cross(x);
    R.block<3, 1>(3 * a, 5) = Vec3::UnitZ().cross(x);
  }
  const Eigen::HouseholderQR<Eigen::MatrixXd> qr(R);
  const Eigen::MatrixXd Q = qr.householderQ() * Eigen::MatrixXd::Identity(3 * nodes, 6);
  return Q * Q.transpose();
}

double smallest_eigenvalue(const Eigen::MatrixXd& S) {
  return Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(S, Eigen::EigenvaluesOnly).eigenvalues()(0);
}

void check(ElementType type, double fraction) {
  const ElasticMaterial m{210000, 0.3, 0};
  LinearXfemOptions o;
  o.element = type;
  o.incompatible_modes = false;  // aₑ is the plain bulk energy (the uncut cell's has no modes either)
  o.nitsche_penalty = LinearXfemOptions::NitschePenalty::Local;
  const auto c = cut_element(fraction);
  const Eigen::MatrixXd A = element_system(c->el, m, {}, {}, o).K;  // no Dirichlet patch: bulk only
  const Eigen::MatrixXd A_cell = element_system(uncut_cell(), m, {}, {}, o).K;
  const Eigen::MatrixXd A_hat = A + o.nitsche_local_floor * A_cell;
  const int degree = patch_rule_degree(o, c->sv.patches[0], true);
  const Eigen::MatrixXd B = flux_matrix(*c, m, type, degree);
  const double scale = A_hat.norm();
  // Λ on the range of Â: Â = V diag(d) Vᵀ, keep d > 0, Λ = λ_max(W ᵀB W) with W = V_+ d_+^(−1/2).
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> ea(A_hat);
  ASSERT_EQ(ea.info(), Eigen::Success);
  const Eigen::VectorXd& d = ea.eigenvalues();
  int rigid = 0;
  while (d(rigid) < 1e-10 * d.maxCoeff()) ++rigid;
  EXPECT_EQ(rigid, 6);  // Â's null space: the rigid motions
  const int r = static_cast<int>(d.size()) - rigid;
  const Eigen::MatrixXd W = ea.eigenvectors().rightCols(r) * d.tail(r).cwiseSqrt().cwiseInverse().asDiagonal();
  const double Lambda = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(W.transpose() * B * W).eigenvalues().maxCoeff();
  const double p = nitsche_penalty(c->el, m, {c->dc}, o);
  std::printf("%s, volume fraction %g: Λ h / E = %.4g (test) against p / (κ E / h) = %.4g\n", element_type_name(type),
              fraction, Lambda * 1.5 / m.youngs_modulus, p / o.nitsche_local_factor * 1.5 / m.youngs_modulus);
  EXPECT_NEAR(p / o.nitsche_local_factor, Lambda, 1e-9 * Lambda);

  // The promised coercivity: vᵀ(K − A)v ≥ −â(v, v)/κ for every v (K: bulk + Nitsche terms of
  // the element), i.e. the smallest eigenvalue of the pencil (K − A, Â) is at least −1/κ.
  const Eigen::MatrixXd P = scale * rigid_projector(type);
  const Eigen::MatrixXd K = element_system(c->el, m, {c->dc}, {}, o).K;
  const Eigen::GeneralizedSelfAdjointEigenSolver<Eigen::MatrixXd> gk(K - A, A_hat + P, Eigen::EigenvaluesOnly);
  ASSERT_EQ(gk.info(), Eigen::Success);
  const double lowest = gk.eigenvalues().minCoeff();
  std::printf("  smallest eigenvalue of (K − A, Â): %.4f (bound −1/κ = %.4f)\n", lowest, -1 / o.nitsche_local_factor);
  EXPECT_GE(lowest, -1 / o.nitsche_local_factor - 1e-9);
}

TEST(LocalNitschePenalty, IsTheFluxEigenvalueAndCoerciveOnAHex27CutCell) { check(ElementType::Hex27, 0.4); }
TEST(LocalNitschePenalty, IsTheFluxEigenvalueAndCoerciveOnAThinHex27Piece) { check(ElementType::Hex27, 0.02); }
TEST(LocalNitschePenalty, IsTheFluxEigenvalueAndCoerciveOnAHex8CutCell) { check(ElementType::Hex8, 0.4); }

// The fixed default β = 100 on the thin piece: the element matrix (bulk + Nitsche) has a
// negative eigenvalue; with the local penalty it has none.
TEST(LocalNitschePenalty, MakesTheThinPieceDefiniteWhereTheFixedDefaultIsNot) {
  const ElasticMaterial m{210000, 0.3, 0};
  LinearXfemOptions o;
  o.element = ElementType::Hex27;
  const auto c = cut_element(0.02);
  const Eigen::MatrixXd K_fixed = element_system(c->el, m, {c->dc}, {}, o).K;
  o.nitsche_penalty = LinearXfemOptions::NitschePenalty::Local;
  const Eigen::MatrixXd K_local = element_system(c->el, m, {c->dc}, {}, o).K;
  const double fixed = smallest_eigenvalue(K_fixed), local = smallest_eigenvalue(K_local);
  std::printf("smallest eigenvalue: fixed β = 100 %.4g, local %.4g (of ‖K‖ %.3g); penalties %.4g, %.4g E/h\n", fixed,
              local, K_local.norm(), 100.0, nitsche_penalty(c->el, m, {c->dc}, o) * 1.5 / m.youngs_modulus);
  EXPECT_LT(fixed, -1e-6 * K_fixed.norm());
  EXPECT_GE(local, -1e-10 * K_local.norm());
}

// σ(u, v) = (u³, v, 0): the plane z = 0 with tangents that change along u.
class CubicPlane : public SurfaceMap {
 public:
  void evaluate(double u, double v, Vec3& X, Vec3& Xu, Vec3& Xv) const override {
    X = Vec3(u * u * u, v, 0);
    Xu = Vec3(3 * u * u, 0, 0);
    Xv = Vec3(0, 1, 0);
  }
};

// The solver's patch rules: a curved Dirichlet patch gets dirichlet_surface_degree (its Nitsche
// integrand is no polynomial), a planar one and a traction patch keep surface_degree (hex27: ≥ 8).
// A plane counts as one by its affine map: the same plane parametrized by u³ counts as curved.
TEST(PatchRuleDegree, CurvedSupportsGetTheDirichletDegree) {
  CutPatch plane, cylinder, cubic_plane;
  plane.surface = std::make_shared<testing::PlaneMap>(Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0.3, 1, 0.2));
  cylinder.surface = std::make_shared<testing::CylinderMap>(Vec2(0, 0), 3);
  cubic_plane.surface = std::make_shared<CubicPlane>();
  for (CutPatch* p : {&plane, &cylinder, &cubic_plane})
    p->loops = {BoundaryLoop{{{0.1, 0}, {0.5, 0}, {0.5, 1}, {0.1, 1}, {0.1, 0}}, 1}};
  LinearXfemOptions o;
  EXPECT_EQ(patch_rule_degree(o, plane, true), 5);
  EXPECT_EQ(patch_rule_degree(o, cylinder, true), 8);
  EXPECT_EQ(patch_rule_degree(o, cubic_plane, true), 8);
  EXPECT_EQ(patch_rule_degree(o, cylinder, false), 5);
  o.dirichlet_surface_degree = 12;
  EXPECT_EQ(patch_rule_degree(o, cylinder, true), 12);
  o.dirichlet_surface_degree = 3;  // a least degree: below surface_degree it changes nothing
  EXPECT_EQ(patch_rule_degree(o, cylinder, true), 5);
  o.dirichlet_surface_degree = 8;
  o.element = ElementType::Hex27;
  EXPECT_EQ(patch_rule_degree(o, plane, true), 8);
  EXPECT_EQ(patch_rule_degree(o, cylinder, false), 8);
  o.surface_degree = 11;
  EXPECT_EQ(patch_rule_degree(o, cylinder, true), 11);
}

}  // namespace
}  // namespace parafab::xfem
