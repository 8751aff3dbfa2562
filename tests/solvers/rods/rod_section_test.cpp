// Cross sections of rods (thesis §5.4): the ellipse moment of Eq. 5.7 against quadrature,
// J = 4ψ(I) against Saint-Venant's closed form for ellipses, the admissible set K (Eq. 5.9),
// concavity of ψ (Lemma 3) and the elliptification of Proposition 5.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "common/error.h"
#include "rods/elliptical_section.h"

namespace parafab {
namespace {

// ∫_D (y², −xy; −xy, x²) dA over the rotated ellipse by Gauss–Legendre in ρ and the
// trapezoid rule in θ (exact for trigonometric polynomials).
Eigen::Matrix2d area_moment_by_quadrature(const EllipticalSection& e) {
  const double gx[4] = {-0.8611363115940526, -0.3399810435848563, 0.3399810435848563, 0.8611363115940526};
  const double gw[4] = {0.3478548451374538, 0.6521451548625461, 0.6521451548625461, 0.3478548451374538};
  const int nt = 64;
  Eigen::Matrix2d I = Eigen::Matrix2d::Zero();
  const double c = std::cos(e.angle), s = std::sin(e.angle);
  for (int k = 0; k < nt; ++k) {
    const double th = 2 * M_PI * k / nt;
    for (int q = 0; q < 4; ++q) {
      const double rho = 0.5 * (gx[q] + 1), w = 0.5 * gw[q] * (2 * M_PI / nt) * e.a * e.b * rho;
      const double u = e.a * rho * std::cos(th), v = e.b * rho * std::sin(th);
      const double x = c * u - s * v, y = s * u + c * v;
      I(0, 0) += w * y * y, I(0, 1) -= w * x * y, I(1, 1) += w * x * x;
    }
  }
  I(1, 0) = I(0, 1);
  return I;
}

TEST(RodSection, EllipseAreaMomentMatchesQuadrature) {
  for (const EllipticalSection e : {EllipticalSection{0.02, 0.01, 0.3}, EllipticalSection{0.01, 0.01, 0},
                                    EllipticalSection{0.05, 0.002, -1.2}}) {
    const Eigen::Matrix2d I = e.area_moment(), Iq = area_moment_by_quadrature(e);
    EXPECT_LT((I - Iq).norm(), 1e-13 * I.norm());
    // Saint-Venant: J of an ellipse is π a³ b³ / (a² + b²), the Diaz–Weinstein bound 4ψ(I).
    EXPECT_NEAR(4 * psi(I), M_PI * std::pow(e.a * e.b, 3) / (e.a * e.a + e.b * e.b), 1e-13 * e.torsion_constant());
    const EllipticalSection r = ellipse_from_area_moment(I);
    EXPECT_NEAR(r.a, std::max(e.a, e.b), 1e-14);
    EXPECT_NEAR(r.b, std::min(e.a, e.b), 1e-14);
    EXPECT_NEAR(r.area(), e.area(), 1e-16);
    EXPECT_LT((r.area_moment() - I).norm(), 1e-13 * I.norm());
  }
}

TEST(RodSection, AdmissibleSetAndConcavity) {
  const Eigen::Matrix2d I = EllipticalSection{0.02, 0.01, 0.4}.area_moment();
  EXPECT_TRUE(is_admissible_stiffness(I, 4 * psi(I)));
  EXPECT_TRUE(is_admissible_stiffness(I, 0.1 * psi(I)));
  EXPECT_FALSE(is_admissible_stiffness(I, 4.01 * psi(I)));
  EXPECT_FALSE(is_admissible_stiffness(I, 0));
  EXPECT_FALSE(is_admissible_stiffness(-I, 1e-9));
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> U(0.001, 0.05), A(-2, 2), T(0, 1);
  for (int k = 0; k < 200; ++k) {
    const Eigen::Matrix2d X = EllipticalSection{U(rng), U(rng), A(rng)}.area_moment();
    const Eigen::Matrix2d Y = EllipticalSection{U(rng), U(rng), A(rng)}.area_moment();
    const double t = T(rng);
    EXPECT_GE(psi((1 - t) * X + t * Y), ((1 - t) * psi(X) + t * psi(Y)) * (1 - 1e-12));  // Lemma 3
  }
}

TEST(RodSection, ElliptificationKeepsMomentAndTorsion) {
  std::mt19937 rng(2);
  std::uniform_real_distribution<double> U(0.001, 0.05), A(-2, 2), F(0.05, 1.0);
  for (int k = 0; k < 100; ++k) {
    const Eigen::Matrix2d I = EllipticalSection{U(rng), U(rng), A(rng)}.area_moment();
    const double J = F(rng) * 4 * psi(I);  // e.g. a cross-shaped section: J < 4ψ(I)
    const Eigen::Vector2d kn(std::cos(A(rng)), std::sin(A(rng)));
    const Eigen::Matrix2d Is = elliptify(I, J, 3.0 * kn);
    EXPECT_LT((Is * kn - I * kn).norm(), 1e-12 * (I * kn).norm());
    EXPECT_NEAR(4 * psi(Is), J, 1e-12 * J);
    EXPECT_GT(Is.determinant(), 0);
    EXPECT_GT(Is(0, 0), 0);
  }
  const Eigen::Matrix2d I = Eigen::Matrix2d::Identity();
  EXPECT_THROW(elliptify(I, 3.0, Eigen::Vector2d(1, 0)), Error);  // J > 4ψ(I) = 2
  EXPECT_THROW(elliptify(I, 1.0, Eigen::Vector2d(0, 0)), Error);
  EXPECT_THROW(ellipse_from_area_moment(-I), Error);
}

}  // namespace
}  // namespace parafab
