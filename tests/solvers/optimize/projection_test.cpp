// Parameterization constraints, projection and L-BFGS (thesis §6.5.1-6.5.2, Eq. 6.25-6.29):
// exact Jacobians and Hessians against central finite differences, the projection of a
// perturbed fillet restoring tangency, dp⊥/dp̃ against finite differences of the projection.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <Eigen/Geometry>
#include <cmath>
#include <cstdio>
#include <map>
#include <random>

#include "common/error.h"
#include "optimize/lbfgs.h"
#include "optimize/projection.h"
#include "optimize/shape_constraints.h"

using namespace parafab::optimize;

namespace {

// A block of random values near a valid primitive (unit-ish axes, positive radii).
void fill_block(Eigen::VectorXd& p, const ParameterBlock& b, std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-1, 1);
  for (int k = 0; k < b.size(); ++k) p[b.offset + k] = u(rng);
  const int axis = b.kind == PrimitiveKind::plane ? 0 : b.kind == PrimitiveKind::sphere ? -1 : 3;
  if (axis >= 0) p.segment<3>(b.offset + axis).normalize();
  for (int k = b.kind == PrimitiveKind::sphere ? 3 : axis + 3; k < b.size(); ++k)
    if (b.kind != PrimitiveKind::plane) p[b.offset + k] = 0.5 + std::abs(u(rng));
  if (b.kind == PrimitiveKind::cone) p[b.offset + 7] = 0.3 + 0.3 * std::abs(u(rng));
  if (b.kind == PrimitiveKind::torus) p[b.offset + 6] += 2;  // R > r
}

// max over entries of |exact − FD| / max(1, |FD|) for the Jacobian, and for the Hessian of λᵀc.
void check_derivatives(const ConstraintSystem& s, const Eigen::VectorXd& p, double& jac_err, double& hess_err) {
  const double h = 1e-5;
  const Eigen::MatrixXd J = s.jacobian(p);
  Eigen::VectorXd lambda = Eigen::VectorXd::LinSpaced(s.size(), 0.5, 1.5);
  const Eigen::MatrixXd H = s.constraint_hessian(p, lambda);
  jac_err = hess_err = 0;
  for (int i = 0; i < p.size(); ++i) {
    Eigen::VectorXd pp = p, pm = p;
    pp[i] += h, pm[i] -= h;
    const Eigen::VectorXd fd = (s.values(pp) - s.values(pm)) / (2 * h);
    const Eigen::VectorXd gfd = (s.jacobian(pp).transpose() * lambda - s.jacobian(pm).transpose() * lambda) / (2 * h);
    for (int r = 0; r < s.size(); ++r) jac_err = std::max(jac_err, std::abs(J(r, i) - fd[r]) / std::max(1.0, std::abs(fd[r])));
    for (int r = 0; r < p.size(); ++r)
      hess_err = std::max(hess_err, std::abs(H(r, i) - gfd[r]) / std::max(1.0, std::abs(gfd[r])));
  }
  // The sparse Hessian values (lower triangle) agree with the dense one.
  std::vector<int> rows, cols;
  s.hessian_structure(rows, cols);
  std::vector<double> values(rows.size());
  s.hessian_values(p, 0.0, lambda, values.data());
  Eigen::MatrixXd Hs = Eigen::MatrixXd::Zero(p.size(), p.size());
  for (size_t k = 0; k < rows.size(); ++k) Hs(rows[k], cols[k]) += values[k];
  Eigen::MatrixXd Hl = H.triangularView<Eigen::Lower>();
  EXPECT_LT((Hs - Hl).cwiseAbs().maxCoeff(), 1e-12);
}

}  // namespace

TEST(ShapeConstraints, TangencyJacobiansAndHessiansMatchCentralDifferences) {
  using K = PrimitiveKind;
  const std::vector<std::tuple<std::string, K, K>> kinds = {
      {"plane-plane", K::plane, K::plane},          {"plane-cylinder", K::plane, K::cylinder},
      {"plane-cone", K::plane, K::cone},            {"plane-sphere", K::plane, K::sphere},
      {"plane-torus", K::plane, K::torus},          {"cylinder-cylinder", K::cylinder, K::cylinder},
      {"cylinder-sphere", K::cylinder, K::sphere},  {"cylinder-torus", K::cylinder, K::torus},
      {"cylinder-torus-pipe", K::cylinder, K::torus}, {"sphere-torus", K::sphere, K::torus}};
  std::mt19937 rng(7);
  for (const auto& [kind, ka, kb] : kinds) {
    const ParameterBlock a{0, ka, 0}, b{1, kb, block_size(ka)};
    Eigen::VectorXd p(a.size() + b.size());
    fill_block(p, a, rng);
    fill_block(p, b, rng);
    ConstraintSystem s(p.size());
    for (int sign : {1, -1}) add_tangency(s, kind, a, b, sign, p, kind);
    add_unit_axis(s, a, "unit a");
    add_unit_axis(s, b, "unit b");
    double je, he;
    check_derivatives(s, p, je, he);
    EXPECT_LT(je, 1e-7) << kind;
    EXPECT_LT(he, 1e-7) << kind;
  }
  // Mirror and rotational symmetry and linear ties too.
  for (K k : {K::plane, K::cylinder, K::cone, K::sphere, K::torus}) {
    const ParameterBlock a{0, k, 0}, b{1, k, block_size(k)};
    Eigen::VectorXd p(2 * a.size());
    fill_block(p, a, rng);
    fill_block(p, b, rng);
    ConstraintSystem s(p.size());
    add_mirror(s, a, b, Eigen::Vector3d(0.3, -0.2, 0.9), 0.7, p, "mirror");
    add_rotation(s, a, b, Eigen::Vector3d(0.2, 0.1, -0.4), Eigen::Vector3d(-0.5, 0.4, 0.8), 1.1, p, "rotation");
    add_linear(s, {0, b.offset}, {1.0, -2.0}, 0.25, "tie");
    double je, he;
    check_derivatives(s, p, je, he);
    EXPECT_LT(je, 1e-7) << to_string(k);
    EXPECT_LT(he, 1e-7) << to_string(k);
  }
}

// A face turned about an axis by hand (points Q(X − o) + o, axes Q a; a cylinder's axis point
// slid along its axis, a plane's normal flipped) satisfies the rotation constraints; the same
// face with a radius, an offset or the angle changed does not.
TEST(ShapeConstraints, RotatedCopiesSatisfyTheRotationConstraints) {
  using K = PrimitiveKind;
  std::mt19937 rng(11);
  const Eigen::Vector3d o(1.5, -0.5, 2.0), w = Eigen::Vector3d(0.2, -0.3, 1.0).normalized();
  const double angle = 2 * M_PI / 5;
  const Eigen::Matrix3d Q = Eigen::AngleAxisd(angle, w).toRotationMatrix();
  for (K k : {K::plane, K::cylinder, K::cone, K::sphere, K::torus}) {
    const ParameterBlock a{0, k, 0}, b{1, k, block_size(k)};
    Eigen::VectorXd p(2 * a.size());
    fill_block(p, a, rng);
    p.segment(b.offset, b.size()) = p.segment(a.offset, a.size());
    if (k == K::plane) {
      const Eigen::Vector3d n = p.segment<3>(0);
      const double d = p[3];  // n·X = d ⇒ (Qn)·X' = d + (Qn)·(o − Q o), stored flipped
      p.segment<3>(4) = -(Q * n);
      p[7] = -(d + (Q * n).dot(o - Q * o));
    } else {
      p.segment<3>(b.offset) = Q * (p.segment<3>(0) - o) + o;
      if (k != K::sphere) p.segment<3>(b.offset + 3) = Q * p.segment<3>(3);
      if (k == K::cylinder) p.segment<3>(b.offset) += 0.7 * p.segment<3>(b.offset + 3);
    }
    ConstraintSystem s(p.size());
    const int added = add_rotation(s, a, b, o, w, angle, p, "rotation");
    // Independent equations: parallel directions 2, points 3 (2 for a cylinder's sliding point), radii 1 each.
    const std::map<K, int> equations = {{K::plane, 3}, {K::cylinder, 5}, {K::cone, 7}, {K::sphere, 4}, {K::torus, 7}};
    EXPECT_EQ(added, equations.at(k)) << to_string(k);
    EXPECT_LT(s.values(p).cwiseAbs().maxCoeff(), 1e-14) << to_string(k);
    Eigen::VectorXd q = p;
    q[b.offset + b.size() - 1] += 1e-3;  // the radius (half-angle for a cone, offset for a plane)
    EXPECT_GT(s.values(q).cwiseAbs().maxCoeff(), 0.9e-3) << to_string(k);
    ConstraintSystem other(p.size());
    add_rotation(other, a, b, o, w, angle + 1e-3, p, "rotation");
    EXPECT_GT(other.values(p).cwiseAbs().maxCoeff(), 1e-4) << to_string(k);
  }
}

TEST(ShapeConstraints, ImplicitFunctionGradientsMatchCentralDifferences) {
  std::mt19937 rng(3);
  for (PrimitiveKind k : {PrimitiveKind::plane, PrimitiveKind::cylinder, PrimitiveKind::cone, PrimitiveKind::sphere,
                          PrimitiveKind::torus}) {
    const ParameterBlock b{0, k, 0};
    Eigen::VectorXd p(b.size());
    fill_block(p, b, rng);
    const Eigen::Vector3d X(0.4, -1.3, 0.8);
    const Dual phi = implicit_function(k, p.data(), X);
    const double h = 1e-6;
    for (int i = 0; i < b.size() + 3; ++i) {
      Eigen::VectorXd pp = p, pm = p;
      Eigen::Vector3d Xp = X, Xm = X;
      if (i < b.size()) pp[i] += h, pm[i] -= h;
      else Xp[i - b.size()] += h, Xm[i - b.size()] -= h;
      const double fd = (implicit_function(k, pp.data(), Xp).v - implicit_function(k, pm.data(), Xm).v) / (2 * h);
      EXPECT_NEAR(phi.g[i], fd, 1e-8 * std::max(1.0, std::abs(fd))) << to_string(k) << " entry " << i;
    }
  }
  // Closed forms: distance to a unit cylinder about z through the origin, radius 2.
  const double cyl[] = {0, 0, 0, 0, 0, 1, 2};
  EXPECT_NEAR(implicit_function(PrimitiveKind::cylinder, cyl, Eigen::Vector3d(3, 4, 7)).v, 3.0, 1e-15);
}

// The mean curvature (sum of the principal curvatures, normal along ∇φ) that the load face's own
// motion uses (occ::compliance_gradient): closed forms on each primitive's surface.
TEST(ShapeConstraints, MeanCurvatureOfTheZeroSetsIsTheClosedForm) {
  const double plane[] = {0, 0.6, 0.8, 2};
  EXPECT_EQ(implicit_mean_curvature(PrimitiveKind::plane, plane, Eigen::Vector3d(1, 0, 2.5)), 0.0);
  const double cyl[] = {0, 0, 0, 0, 0, 3, 2};  // about z, r = 2 (an axis of length 3)
  EXPECT_NEAR(implicit_mean_curvature(PrimitiveKind::cylinder, cyl, Eigen::Vector3d(1.2, 1.6, 5)), 0.5, 1e-14);
  const double sph[] = {1, 2, 3, 2};
  EXPECT_NEAR(implicit_mean_curvature(PrimitiveKind::sphere, sph, Eigen::Vector3d(1, 2, 5)), 1.0, 1e-14);
  const double tor[] = {0, 0, 0, 0, 0, 1, 4, 1};  // R = 4, r = 1: 1/r ± 1/(R ± r) at the equators
  EXPECT_NEAR(implicit_mean_curvature(PrimitiveKind::torus, tor, Eigen::Vector3d(5, 0, 0)), 1 + 1.0 / 5, 1e-14);
  EXPECT_NEAR(implicit_mean_curvature(PrimitiveKind::torus, tor, Eigen::Vector3d(0, -3, 0)), 1 - 1.0 / 3, 1e-14);
  const double cone[] = {0, 0, 0, 0, 0, 1, 2, 0.3};  // r = 2 at h = 0, half-angle 0.3: cos α / ρ
  EXPECT_NEAR(implicit_mean_curvature(PrimitiveKind::cone, cone, Eigen::Vector3d(0, 2, 0)), std::cos(0.3) / 2, 1e-14);
  const double h = 1.5;  // higher up the cone: ρ = r + h tan α
  EXPECT_NEAR(implicit_mean_curvature(PrimitiveKind::cone, cone, Eigen::Vector3d(2 + h * std::tan(0.3), 0, h)),
              std::cos(0.3) / (2 + h * std::tan(0.3)), 1e-14);
}

// The normal speed a support's own motion uses (occ::compliance_gradient): Vₙ,k = −∂φ/∂p_k/|∇φ|
// against implicit_function's gradient, and its spatial gradient against central differences,
// on every primitive at points off the surface too (the gradient holds for any X). Closed
// form: a cylinder's axis point moved along x has Vₙ = n̂·e_x, whose gradient on the surface is
// (e_x − n̂ n̂_x)/ρ.
TEST(ShapeConstraints, NormalSpeedsAndTheirGradientsMatchCentralDifferences) {
  const std::vector<std::pair<PrimitiveKind, std::vector<double>>> faces = {
      {PrimitiveKind::plane, {0, 0.6, 0.8, 2}},
      {PrimitiveKind::cylinder, {0.5, -1, 0, 0.1, 0.2, 1, 2}},
      {PrimitiveKind::cone, {0, 0, 0, 0, 0.3, 1, 2, 0.3}},
      {PrimitiveKind::sphere, {1, 2, 3, 2}},
      {PrimitiveKind::torus, {0, 0, 0, 0.2, 0, 1, 4, 1}},
  };
  const Eigen::Vector3d X(1.3, 2.2, 0.7);
  double worst = 0;
  for (const auto& [kind, block] : faces) {
    const NormalSpeed ns = implicit_normal_speed(kind, block.data(), X);
    const Dual phi = implicit_function(kind, block.data(), X);
    const int nb = block_size(kind);
    const Eigen::Vector3d grad = phi.g.tail<3>();
    EXPECT_NEAR((ns.normal - grad.normalized()).norm(), 0, 1e-15) << to_string(kind);
    for (int k = 0; k < nb; ++k) {
      EXPECT_NEAR(ns.speed[k], -phi.g[k] / grad.norm(), 1e-15) << to_string(kind) << " " << k;
      for (int c = 0; c < 3; ++c) {
        const double h = 1e-6;
        const Eigen::Vector3d e = h * Eigen::Vector3d::Unit(c);
        const double fd = (implicit_normal_speed(kind, block.data(), X + e).speed[k] -
                           implicit_normal_speed(kind, block.data(), X - e).speed[k]) / (2 * h);
        worst = std::max(worst, std::abs(ns.gradient(k, c) - fd));
      }
    }
  }
  std::printf("largest |∇Vₙ − central difference|: %.2e\n", worst);
  EXPECT_LE(worst, 1e-9);
  // Closed form on a cylinder about z through the origin, r = 2, at (2 cos t, 2 sin t, 1).
  const double cyl[] = {0, 0, 0, 0, 0, 1, 2};
  const double t = 0.7;
  const Eigen::Vector3d n(std::cos(t), std::sin(t), 0);
  const NormalSpeed ns = implicit_normal_speed(PrimitiveKind::cylinder, cyl, 2 * n + Eigen::Vector3d(0, 0, 1));
  EXPECT_NEAR(ns.speed[0], n.x(), 1e-15);
  const Eigen::Vector3d expected = (Eigen::Vector3d::UnitX() - n * n.x()) / 2;
  EXPECT_NEAR((ns.gradient.row(0).transpose() - expected).norm(), 0, 1e-15);
  // On the axis ∇φ = 0: no normal, an empty speed (the callers skip the point).
  EXPECT_EQ(implicit_normal_speed(PrimitiveKind::cylinder, cyl, Eigen::Vector3d(0, 0, 3)).speed.size(), 0);
}

TEST(ShapeConstraints, SpinePointsAreTheClosedFormsAndTheirGradientsMatchCentralDifferences) {
  // Closed forms: cylinder about z through (1, 2, 0): S = (1, 2, X.z); torus about z centred at
  // (1, 2, 3), R = 4: S = (1, 2, 3) + 4 (X − c)_⊥ / |(X − c)_⊥|; sphere: the centre.
  const Eigen::Vector3d X(4, 6, 5);
  const double cyl[] = {1, 2, 0, 0, 0, 2.5, 1};  // an axis of length 2.5: S must not depend on it
  const double tor[] = {1, 2, 3, 0, 0, -1, 4, 1};
  const double sph[] = {1, 2, 3, 2};
  auto value = [](const V3<Dual>& S) { return Eigen::Vector3d(S.x.v, S.y.v, S.z.v); };
  EXPECT_LT((value(spine_point(PrimitiveKind::cylinder, cyl, X)) - Eigen::Vector3d(1, 2, 5)).norm(), 1e-15);
  EXPECT_LT((value(spine_point(PrimitiveKind::torus, tor, X)) - Eigen::Vector3d(1 + 4 * 0.6, 2 + 4 * 0.8, 3)).norm(), 1e-14);
  EXPECT_LT((value(spine_point(PrimitiveKind::sphere, sph, X)) - Eigen::Vector3d(1, 2, 3)).norm(), 1e-15);
  std::mt19937 rng(5);
  for (PrimitiveKind k : {PrimitiveKind::cylinder, PrimitiveKind::sphere, PrimitiveKind::torus}) {
    const ParameterBlock b{0, k, 0};
    Eigen::VectorXd p(b.size());
    fill_block(p, b, rng);
    const Eigen::Vector3d Y(0.4, -1.3, 0.8);
    const V3<Dual> S = spine_point(k, p.data(), Y);
    const double h = 1e-6;
    for (int i = 0; i < b.size(); ++i) {
      Eigen::VectorXd pp = p, pm = p;
      pp[i] += h, pm[i] -= h;
      const Eigen::Vector3d fd = (value(spine_point(k, pp.data(), Y)) - value(spine_point(k, pm.data(), Y))) / (2 * h);
      const Eigen::Vector3d g(S.x.g[i], S.y.g[i], S.z.g[i]);
      EXPECT_LT((g - fd).norm(), 1e-8 * std::max(1.0, fd.norm())) << to_string(k) << " entry " << i;
    }
  }
  const double plane[] = {0, 0, 1, 0};
  EXPECT_THROW(spine_point(PrimitiveKind::plane, plane, X), parafab::Error);
  EXPECT_THROW(spine_point(PrimitiveKind::torus, tor, Eigen::Vector3d(1, 2, 9)), parafab::Error);  // on the axis
}

namespace {

// Fig. 6.11: a fillet cylinder (radius 5, axis y) tangent to the planes z = 8 (normal +z) and
// x = 8 (normal +x), both on the cylinder's −z/−x side... here: concave inner fillet of an L.
struct Fillet {
  ConstraintSystem system{15};
  ParameterBlock p1{0, PrimitiveKind::plane, 0}, p2{1, PrimitiveKind::plane, 4}, c{2, PrimitiveKind::cylinder, 8};
  Eigen::VectorXd p0{15}, lower{15}, upper{15};
  Fillet() {
    p0 << 0, 0, 1, 8,            // z = 8
        1, 0, 0, 8,              // x = 8
        13, 0, 13, 0, 1, 0, 5;   // axis (13, y, 13), radius 5
    for (const auto& [plane, label] : {std::pair{p1, "a"}, std::pair{p2, "b"}}) {
      const double side = (p0.segment<3>(plane.offset).dot(p0.segment<3>(8)) - p0[plane.offset + 3]) > 0 ? -1 : 1;
      add_tangency(system, "plane-cylinder", plane, c, static_cast<int>(side), p0, label);
    }
    for (const auto& b : {p1, p2, c}) add_unit_axis(system, b, "unit");
    lower = Eigen::VectorXd::Constant(15, -1e19);
    upper = Eigen::VectorXd::Constant(15, 1e19);
  }
};

}  // namespace

TEST(Projection, PerturbedFilletRestoresTangencyAndIsTheNearestValidModel) {
  Fillet f;
  ASSERT_LT(f.system.values(f.p0).cwiseAbs().maxCoeff(), 1e-14);
  Eigen::VectorXd target = f.p0;
  target[3] += 0.7;          // plane z = 8.7
  target[14] += 0.4;         // radius 5.4
  target.segment<3>(4) += Eigen::Vector3d(0.02, 0.01, -0.03);  // tilt plane b
  ASSERT_GT(f.system.values(target).cwiseAbs().maxCoeff(), 0.1);
  const ProjectionResult r = project(f.system, target, f.p0, f.lower, f.upper);
  ASSERT_TRUE(r.done) << r.message;
  EXPECT_LT(r.constraint_violation, 1e-10);
  // Independent optimality check (KKT): p⊥ − p̃ lies in the row space of ∂c/∂p.
  const Eigen::MatrixXd J = f.system.jacobian(r.p);
  const Eigen::VectorXd residual = r.p - target;
  const Eigen::VectorXd in_range = J.transpose() * J.transpose().colPivHouseholderQr().solve(residual);
  EXPECT_LT((residual - in_range).norm(), 1e-9);
  // Geometry: the axis is parallel to both planes at the distance r from each.
  const Eigen::Vector3d c = r.p.segment<3>(8), a = r.p.segment<3>(11).normalized();
  for (int plane : {0, 4}) {
    const Eigen::Vector3d n = r.p.segment<3>(plane);
    EXPECT_NEAR(std::abs(n.dot(c) - r.p[plane + 3]) / n.norm(), r.p[14], 1e-10);
    EXPECT_NEAR(n.normalized().dot(a), 0, 1e-10);
  }
  EXPECT_GT(r.p[14], 5.0);  // the radius moved towards its target 5.4
  // Warm start from the answer with its multipliers: converges at once to the same point.
  const ProjectionResult w = project(f.system, target, r.p, f.lower, f.upper, r.multipliers);
  EXPECT_LT((w.p - r.p).norm(), 1e-9);
  EXPECT_LE(w.iterations, 3);
}

// A stop short of success (here Ipopt's iteration limit; on the AMD EPYC machine of 2026-12-02
// "restoration phase failed" at the wrench's start) away from the nearest point: the projection
// is solved again cold, from the target clamped to its bounds. A warm start far off (plane a
// tilted 40°, the axis 6 mm away) with an iteration limit the cold start meets: the retry gives
// the nearest valid model. Where the cold start cannot meet it either, the user gets "failed",
// Ipopt's status for both starts and no valid model.
TEST(Projection, AStopShortOfSuccessIsSolvedAgainColdAndSaysWhenThatFailsToo) {
  Fillet f;
  Eigen::VectorXd target = f.p0;
  target[3] += 0.2;  // plane a: z = 8.2
  Eigen::VectorXd far = f.p0;
  far.segment<3>(0) = Eigen::Vector3d(std::sin(0.7), 0, std::cos(0.7));
  far.segment<3>(8) += Eigen::Vector3d(6, 0, -6);
  far[14] = 11;
  const ProjectionResult reference = project(f.system, target, target, f.lower, f.upper);
  ASSERT_TRUE(reference.done) << reference.message;
  ASSERT_EQ(reference.restarts, 0);
  const ProjectionResult free_run = project(f.system, target, far, f.lower, f.upper);
  std::printf("iterations: from the target %d, from the far start %d (restarts %d)\n", reference.iterations,
              free_run.iterations, free_run.restarts);
  ASSERT_EQ(free_run.restarts, 0);
  ASSERT_GT(free_run.iterations, reference.iterations + 1);  // measured 6 against 3: the warm start fails
  // The retry starts from the target as `reference` does, but with the adaptive barrier update
  // (projection.cpp); that it meets the limit of 4 is measured, not guaranteed.
  ProjectionOptions limited;
  limited.max_iterations = reference.iterations + 1;
  const ProjectionResult r = project(f.system, target, far, f.lower, f.upper, Eigen::VectorXd(), limited);
  EXPECT_TRUE(r.done) << r.message;
  EXPECT_EQ(r.restarts, 1);
  EXPECT_LT((r.p - reference.p).norm(), 1e-9);
  limited.max_iterations = 1;
  const ProjectionResult none = project(f.system, target, far, f.lower, f.upper, Eigen::VectorXd(), limited);
  EXPECT_FALSE(none.done);
  EXPECT_EQ(none.status, "failed");
  EXPECT_EQ(none.restarts, 1);
  EXPECT_NE(none.message.find("warm and cold start"), std::string::npos) << none.message;
}

TEST(Projection, ReportsInfeasibleConstraintsAndReturnsTheNearestModel) {
  Fillet f;
  // Contradiction: radius fixed at 5 and at 6 by two linear constraints.
  add_linear(f.system, {14}, {1.0}, 5.0, "radius 5");
  add_linear(f.system, {14}, {1.0}, 6.0, "radius 6");
  const ProjectionResult r = project(f.system, f.p0, f.p0, f.lower, f.upper);
  EXPECT_FALSE(r.done);
  EXPECT_NE(r.status, "solved");
  EXPECT_GT(r.constraint_violation, 0.4);
  EXPECT_NE(r.message.find("not valid"), std::string::npos) << r.message;
}

TEST(Projection, LeastViolationKeepsTheTangenciesAndSplitsContradictoryUserConstraints) {
  // Plane a (z = 8) fixed, plane b (x = 8) with its normal fixed and its offset free; the user
  // asks for radius 5 and radius 6. The least squares of the two is radius 5.5 (violations
  // ∓0.5); the nearest such model to p0 keeps plane a, so the axis goes to z = 8 + 5.5 = 13.5,
  // and against plane b the 0.5 splits evenly between the plane's offset and the axis' x
  // (min α² + (0.5 − α)²): offset 7.75, axis x 13.25.
  Fillet f;
  for (int k = 0; k < 7; ++k) f.lower[k] = f.upper[k] = f.p0[k];
  const int first_user = f.system.size();
  add_linear(f.system, {14}, {1.0}, 5.0, "radius 5");
  add_linear(f.system, {14}, {1.0}, 6.0, "radius 6");
  ASSERT_FALSE(project(f.system, f.p0, f.p0, f.lower, f.upper).done);
  std::vector<bool> soft(f.system.size(), false);
  for (int i = first_user; i < f.system.size(); ++i) soft[i] = true;
  const ProjectionResult r = project_least_violation(f.system, soft, f.p0, f.p0, f.lower, f.upper);
  ASSERT_TRUE(r.done) << r.message;
  EXPECT_EQ(r.status, "least_violation");
  const Eigen::VectorXd c = f.system.values(r.p);
  EXPECT_LT(c.head(first_user).cwiseAbs().maxCoeff(), 1e-10);  // tangencies and unit axes hold
  EXPECT_NEAR(c[first_user], 0.5, 1e-9);
  EXPECT_NEAR(c[first_user + 1], -0.5, 1e-9);
  EXPECT_NEAR(r.p[14], 5.5, 1e-9);
  EXPECT_NEAR(r.p[10], 13.5, 1e-9);  // axis z
  EXPECT_NEAR(r.p[7], 7.75, 1e-9);   // plane b's offset
  EXPECT_NEAR(r.p[8], 13.25, 1e-9);  // axis x
  EXPECT_NEAR(r.p[9], 0, 1e-9);      // axis y stays
  // The same contradiction among the rows that must hold: no valid model, said so.
  std::vector<bool> none(f.system.size(), false);
  const ProjectionResult hard = project_least_violation(f.system, none, f.p0, f.p0, f.lower, f.upper);
  EXPECT_FALSE(hard.done);
  EXPECT_EQ(hard.status, "failed");
  EXPECT_NE(hard.message.find("must hold are violated"), std::string::npos) << hard.message;
  EXPECT_THROW(project_least_violation(f.system, {true}, f.p0, f.p0, f.lower, f.upper), parafab::Error);
}

TEST(Projection, DerivativeMatchesFiniteDifferencesOfTheProjection) {
  Fillet f;
  Eigen::VectorXd target = f.p0;
  target[3] += 0.3;
  target[14] -= 0.2;
  target[9] += 0.1;  // move the axis point along y (a null direction)
  // Fix plane b (lower = upper) to exercise the free-entry restriction.
  for (int k = 4; k < 8; ++k) f.lower[k] = f.upper[k] = f.p0[k];
  const ProjectionResult r = project(f.system, target, f.p0, f.lower, f.upper);
  ASSERT_TRUE(r.done) << r.message;
  const ProjectionDerivative d = projection_derivative(f.system, r, f.lower, f.upper);
  EXPECT_EQ(d.free, 11);
  const double h = 1e-5;
  double worst = 0;
  for (int i = 0; i < 15; ++i) {
    Eigen::VectorXd tp = target, tm = target;
    tp[i] += h, tm[i] -= h;
    const ProjectionResult rp = project(f.system, tp, r.p, f.lower, f.upper);
    const ProjectionResult rm = project(f.system, tm, r.p, f.lower, f.upper);
    ASSERT_TRUE(rp.done && rm.done);
    const Eigen::VectorXd fd = (rp.p - rm.p) / (2 * h);
    worst = std::max(worst, (d.jacobian.col(i) - fd).lpNorm<Eigen::Infinity>());
  }
  EXPECT_LT(worst, 1e-6);
}

// A system of independent parts (two fillets, an entry no constraint touches, one fixed)
// as a part with separate features has (the bridge sample's 160 holes): the projection's linear
// algebra runs group by group (coupled_groups in projection.cpp). dp⊥/dp̃ must be what each part
// gives alone, with nothing across parts, and match differences of the projection.
TEST(Projection, DerivativeOfIndependentPartsIsEachPartsOwn) {
  Fillet one;
  const int n1 = 15, n = 2 * n1 + 2;
  ConstraintSystem system(n);
  for (int copy = 0; copy < 2; ++copy)
    for (const ScalarConstraint& c : one.system.constraints()) {
      ScalarConstraint d = c;
      for (int& v : d.vars) v += copy * n1;
      system.add(d);
    }
  Eigen::VectorXd p0(n), lower = Eigen::VectorXd::Constant(n, -1e19), upper = Eigen::VectorXd::Constant(n, 1e19);
  p0 << one.p0, one.p0, 0.5, 2.0;
  lower[n - 1] = upper[n - 1] = 2.0;  // the last lone entry is fixed: not free
  Eigen::VectorXd w = Eigen::VectorXd::Ones(n);
  w.segment(n1, n1).setConstant(3.0);  // the second fillet weighs its entries differently
  w[n - 2] = 0.25;
  Eigen::VectorXd target = p0;
  target[3] += 0.3, target[14] -= 0.2, target[n1 + 7] += 0.2, target[n1 + 14] += 0.1, target[n - 2] += 0.4;
  ProjectionOptions options;
  options.weights = w;
  const ProjectionResult r = project(system, target, p0, lower, upper, {}, options);
  ASSERT_TRUE(r.done) << r.message;
  const ProjectionDerivative d = projection_derivative(system, r, lower, upper, w);
  EXPECT_EQ(d.free, n - 1);
  // Each fillet alone (its own system, its own weights) gives its own block.
  for (int copy = 0; copy < 2; ++copy) {
    ProjectionOptions alone_options;
    alone_options.weights = w.segment(copy * n1, n1);
    const ProjectionResult ra = project(one.system, target.segment(copy * n1, n1), one.p0, one.lower, one.upper, {},
                                        alone_options);
    ASSERT_TRUE(ra.done) << ra.message;
    EXPECT_LT((ra.p - r.p.segment(copy * n1, n1)).lpNorm<Eigen::Infinity>(), 1e-9);
    const ProjectionDerivative da = projection_derivative(one.system, ra, one.lower, one.upper, alone_options.weights);
    EXPECT_LT((da.jacobian - d.jacobian.block(copy * n1, copy * n1, n1, n1)).lpNorm<Eigen::Infinity>(), 1e-8) << copy;
    EXPECT_EQ(d.jacobian.block(copy * n1, (1 - copy) * n1, n1, n1).cwiseAbs().maxCoeff(), 0.0);
    EXPECT_EQ(d.jacobian.block(copy * n1, 2 * n1, n1, 2).cwiseAbs().maxCoeff(), 0.0);
  }
  EXPECT_EQ(d.rank, 2 * projection_derivative(one.system, project(one.system, one.p0, one.p0, one.lower, one.upper),
                                              one.lower, one.upper).rank);
  EXPECT_DOUBLE_EQ(d.jacobian(n - 2, n - 2), 1.0);  // a lone free entry follows its target
  EXPECT_EQ(d.jacobian.row(n - 1).cwiseAbs().maxCoeff(), 0.0);  // fixed: does not move
  // Against central differences of the whole projection.
  const double h = 1e-5;
  double worst = 0;
  for (int i = 0; i < n - 1; ++i) {
    Eigen::VectorXd tp = target, tm = target;
    tp[i] += h, tm[i] -= h;
    const ProjectionResult rp = project(system, tp, r.p, lower, upper, {}, options);
    const ProjectionResult rm = project(system, tm, r.p, lower, upper, {}, options);
    ASSERT_TRUE(rp.done && rm.done);
    worst = std::max(worst, (d.jacobian.col(i) - (rp.p - rm.p) / (2 * h)).lpNorm<Eigen::Infinity>());
  }
  EXPECT_LT(worst, 1e-6);
  std::printf("independent parts: dp/dp~ against central differences %.2e\n", worst);
}

TEST(Lbfgs, RosenbrockAndAnActiveBound) {
  auto rosen = [](const Eigen::VectorXd& x, double& f, Eigen::VectorXd& g) {
    f = 100 * std::pow(x[1] - x[0] * x[0], 2) + std::pow(1 - x[0], 2);
    g.resize(2);
    g[0] = -400 * x[0] * (x[1] - x[0] * x[0]) - 2 * (1 - x[0]);
    g[1] = 200 * (x[1] - x[0] * x[0]);
    return true;
  };
  const Eigen::Vector2d big(1e9, 1e9);
  LbfgsOptions o;
  o.max_iterations = 200;
  o.relative_improvement = 0;
  o.gradient_tolerance = 1e-8;
  LbfgsResult r = minimize_lbfgs(rosen, Eigen::Vector2d(-1.2, 1), -big, big, o);
  EXPECT_TRUE(r.done) << r.message;
  EXPECT_NEAR(r.x[0], 1, 1e-6);
  EXPECT_NEAR(r.x[1], 1, 1e-6);
  EXPECT_EQ(r.iterates.front().iteration, 0);
  // With x0 <= 0.5 the constrained minimum of Rosenbrock is (0.5, 0.25).
  r = minimize_lbfgs(rosen, Eigen::Vector2d(-1.2, 1), -big, Eigen::Vector2d(0.5, 1e9), o);
  EXPECT_NEAR(r.x[0], 0.5, 1e-9);
  EXPECT_NEAR(r.x[1], 0.25, 1e-6);
  // Cancel after the second iterate.
  r = minimize_lbfgs(rosen, Eigen::Vector2d(-1.2, 1), -big, big, o,
                     [](const LbfgsIterate& it) { return it.iteration < 2; });
  EXPECT_EQ(r.status, "cancelled");
  EXPECT_EQ(r.iterates.size(), 3u);
}

TEST(Lbfgs, BacktrackingInterpolatesTheRejectedStep) {
  // Exact on a quadratic φ(α) = (α − 0.3)² and on a cubic φ(α) = α³ − 0.27α (minimum at 0.3).
  EXPECT_NEAR(backtrack_factor(0.09, -0.6, 0.49, 1.4), 0.3, 1e-14);
  EXPECT_NEAR(backtrack_factor(0.0, -0.27, 0.73, 2.73), 0.3, 1e-14);
  // Safeguards: at most half the trial, at least a tenth.
  EXPECT_EQ(backtrack_factor(0.64, -1.6, 0.04, 0.4), 0.5);       // (α − 0.8)²
  EXPECT_EQ(backtrack_factor(0.0, -1.0, 1e6 - 1, 2e6 - 1), 0.1);  // 10⁶α² − α: minimum 5e-7
  // A stiff quadratic ½(x² + 10⁴y²) from (1, 1), first step 5 in max-norm: the trial overshoots
  // the line's minimum 5 times. The cubic finds it on the second trial; halving takes three and
  // stops 25 % beyond it.
  auto stiff = [](const Eigen::VectorXd& x, double& f, Eigen::VectorXd& g) {
    f = 0.5 * (x[0] * x[0] + 1e4 * x[1] * x[1]);
    g = Eigen::Vector2d(x[0], 1e4 * x[1]);
    return true;
  };
  const Eigen::Vector2d big(1e9, 1e9);
  LbfgsOptions o;
  o.max_iterations = 1;
  o.first_step = 5;
  const LbfgsResult r = minimize_lbfgs(stiff, Eigen::Vector2d(1, 1), -big, big, o);
  ASSERT_EQ(r.iterates.size(), 2u);
  EXPECT_EQ(r.iterates[1].evaluations, 3);
  // The line x = (1, 1) − t(1, 10⁴) has its minimum at t = gᵀg / gᵀHg:
  const double t = (1 + 1e8) / (1 + 1e12);
  EXPECT_NEAR(r.x[0], 1 - t, 1e-12);
  EXPECT_NEAR(r.x[1], 1 - 1e4 * t, 1e-12);
  // Halving (the rule until 2026-12-01) on the same line, the same Armijo test: the trials
  // 5e-4, 2.5e-4, 1.25e-4, the third accepted, 25 % beyond t.
  const Eigen::Vector2d x0(1, 1), g0(1, 1e4);
  double f0 = 0, fa = 0;
  Eigen::VectorXd scratch;
  stiff(x0, f0, scratch);
  double alpha = o.first_step / g0.lpNorm<Eigen::Infinity>();
  int trials = 1;
  for (; stiff(x0 - alpha * g0, fa, scratch) && fa > f0 - o.armijo * alpha * g0.squaredNorm(); ++trials) alpha *= 0.5;
  EXPECT_EQ(trials, 3);
  EXPECT_NEAR(alpha / t, 1.25, 1e-4);
}
