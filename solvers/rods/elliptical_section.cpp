#include "rods/elliptical_section.h"

#include <Eigen/Eigenvalues>
#include <cmath>

#include "common/error.h"

namespace parafab {

double EllipticalSection::area() const { return M_PI * a * b; }

Eigen::Matrix2d EllipticalSection::area_moment() const {
  Eigen::Matrix2d Q;
  Q << std::cos(angle), -std::sin(angle), std::sin(angle), std::cos(angle);
  const Eigen::Vector2d d(a * b * b * b, a * a * a * b);
  return M_PI / 4 * Q * d.asDiagonal() * Q.transpose();
}

double EllipticalSection::torsion_constant() const {
  return M_PI * std::pow(a * b, 3) / (a * a + b * b);
}

double psi(const Eigen::Matrix2d& X) { return X.determinant() / X.trace(); }

EllipticalSection ellipse_from_area_moment(const Eigen::Matrix2d& I) {
  const double asym = std::abs(I(0, 1) - I(1, 0));
  if (!I.allFinite() || asym > 1e-12 * I.norm())
    PARAFAB_INPUT_ERROR("area moment must be a finite symmetric matrix, got [" << I(0, 0) << ", "
                        << I(0, 1) << "; " << I(1, 0) << ", " << I(1, 1) << "]");
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(I);
  const double l0 = es.eigenvalues()(0), l1 = es.eigenvalues()(1);  // l0 ≤ l1
  if (!(l0 > 0))
    PARAFAB_INPUT_ERROR("area moment must be positive definite, smallest eigenvalue " << l0);
  // Eigenvalue π a b³/4 belongs to the a-axis, π a³ b/4 to the b-axis; a ≥ b ⇔ a-axis has l0.
  EllipticalSection e;
  const double ab = 2 * std::pow(l0 * l1, 0.25) / std::sqrt(M_PI);
  const double ratio = std::sqrt(l1 / l0);  // a / b
  e.a = std::sqrt(ab * ratio);
  e.b = std::sqrt(ab / ratio);
  const Eigen::Vector2d v = es.eigenvectors().col(0);
  double phi = std::atan2(v.y(), v.x());
  if (phi > M_PI / 2) phi -= M_PI;
  if (phi <= -M_PI / 2) phi += M_PI;
  e.angle = phi;
  return e;
}

bool is_admissible_stiffness(const Eigen::Matrix2d& I, double J, double rel_tol) {
  if (!I.allFinite() || !std::isfinite(J)) return false;
  if (std::abs(I(0, 1) - I(1, 0)) > 1e-12 * I.norm()) return false;
  if (!(I(0, 0) > 0) || !(I.determinant() > 0)) return false;
  return J > 0 && J <= 4 * psi(I) * (1 + rel_tol);
}

Eigen::Matrix2d elliptify(const Eigen::Matrix2d& I, double J, const Eigen::Vector2d& kn) {
  if (!is_admissible_stiffness(I, J))
    PARAFAB_INPUT_ERROR("elliptify: (I, J) is not admissible (Eq. 5.9): J = "
                        << J << ", 4 psi(I) = " << 4 * psi(I) << ", det I = " << I.determinant());
  const double k = kn.norm();
  if (!(k > 0)) PARAFAB_INPUT_ERROR("elliptify: curvature vector kn must be non-zero");
  // Q kn = κ e1: rows of Q are kn/κ and its perpendicular.
  Eigen::Matrix2d Q;
  Q << kn.x() / k, kn.y() / k, -kn.y() / k, kn.x() / k;
  Eigen::Matrix2d It = Q * I * Q.transpose();
  It(1, 1) = (J * It(0, 0) + 4 * It(0, 1) * It(0, 1)) / (4 * It(0, 0) - J);
  return Q.transpose() * It * Q;
}

}  // namespace parafab
