// Stiffness of rod cross sections (thesis §5.4): the area moment of an ellipse, Eq. 5.7,
// I = π/4 · Q diag(a b³, a³ b) Qᵀ; the torsion bound J ≤ 4ψ(I), ψ = det/tr (Eq. 5.8), tight
// for ellipses; the admissible set K of Eq. 5.9; and the "elliptification" of Proposition 5,
// which maps any admissible (I, J) to an elliptical section with the same I·kn and J.
#pragma once

#include <Eigen/Core>
#include <Eigen/LU>

namespace parafab {

/// Ellipse with semi-axis a along (cos φ, sin φ) and b along (−sin φ, cos φ), in the
/// coordinates of the cross-section plane (e1, e2) ↦ (n1, n2) of the material frame.
struct EllipticalSection {
  double a = 0;      ///< [m]
  double b = 0;      ///< [m]
  double angle = 0;  ///< φ [rad], in (−π/2, π/2]
  double area() const;                     ///< π a b
  Eigen::Matrix2d area_moment() const;     ///< I of Eq. 5.7 [m⁴]
  double torsion_constant() const;         ///< J = π a³ b³ / (a² + b²) = 4ψ(I) [m⁴]
};

/// ψ(X) = det X / tr X (Eq. 5.8); concave on SPD matrices (Lemma 3).
double psi(const Eigen::Matrix2d& X);

/// The ellipse with area moment I (I symmetric positive definite, else parafab::Error).
/// a ≥ b: the major semi-axis a lies along the eigenvector of the larger eigenvalue's
/// complement, i.e. the ellipse is long in the direction about which it bends easily.
EllipticalSection ellipse_from_area_moment(const Eigen::Matrix2d& I);

/// (I, J) ∈ K (Eq. 5.9): I symmetric positive definite and 0 < J ≤ 4ψ(I)·(1 + rel_tol).
bool is_admissible_stiffness(const Eigen::Matrix2d& I, double J, double rel_tol = 1e-12);

/// Proposition 5: for (I, J) ∈ K and kn ≠ 0, the matrix I* with I*·kn = I·kn and
/// J = 4ψ(I*) (an ellipse). Throws parafab::Error if (I, J) ∉ K or kn = 0.
Eigen::Matrix2d elliptify(const Eigen::Matrix2d& I, double J, const Eigen::Vector2d& kn);

}  // namespace parafab
