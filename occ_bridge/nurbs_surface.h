// NURBS patches in projective coordinates (thesis §6.2.1, Eq. 6.1): σ(u, v) = Σ B_ij(u, v) q_ij
// with poles q_ij = [w x, w y, w z, w] ∈ P³, polynomial in (u, v); points by perspective division.
#pragma once

#include <Eigen/Core>
#include <vector>

namespace parafab::occ {

struct NurbsSurface {
  int degree_u = 0, degree_v = 0;
  int count_u = 0, count_v = 0;          ///< poles along u and v
  std::vector<double> knots_u, knots_v;  ///< flat knot vectors (repeated), count + degree + 1 each
  std::vector<Eigen::Vector4d> poles;    ///< q(i, j) = poles[i * count_v + j], i along u

  /// A periodic direction is stored unwrapped: its first `degree` poles repeat at the end
  /// (count = distinct + degree) over OCCT's periodic flat knots, and a parameter is taken
  /// modulo the period [knots[degree], knots[count]).
  bool periodic_u = false, periodic_v = false;

  const Eigen::Vector4d& pole(int i, int j) const { return poles[i * count_v + j]; }
  /// The poles that are free: all of a clamped direction, the first count − degree of a periodic one.
  int distinct_u() const { return periodic_u ? count_u - degree_u : count_u; }
  int distinct_v() const { return periodic_v ? count_v - degree_v : count_v; }
  double u_min() const { return knots_u[degree_u]; }
  double u_max() const { return knots_u[count_u]; }
  double v_min() const { return knots_v[degree_v]; }
  double v_max() const { return knots_v[count_v]; }
};

/// σ(u, v) in projective coordinates (Eq. 6.1). (u, v) is clamped to the knot range.
/// Throws parafab::Error if the sizes of degrees, knots and poles disagree.
Eigen::Vector4d evaluate_projective(const NurbsSurface& s, double u, double v);

/// The Euclidean surface point X = perspective division of σ, and its derivatives Xu, Xv.
void evaluate(const NurbsSurface& s, double u, double v, Eigen::Vector3d& X, Eigen::Vector3d& Xu,
              Eigen::Vector3d& Xv);

/// ∂X/∂P_ij at (u, v) for the Euclidean poles P_ij with their weights held: the rational basis
/// R_ij = w_ij N_i(u) N_j(v) / Σ w N N (Piegl & Tiller Eq. 4.15) of the (degree_u + 1)(degree_v + 1)
/// poles that can be non-zero there; `index` is i * distinct_v() + j over the distinct poles (a
/// periodic pole's repeated copy adds to its own entry).
struct PoleInfluence {
  int index = 0;
  double value = 0;
};
std::vector<PoleInfluence> pole_influence(const NurbsSurface& s, double u, double v);

}  // namespace parafab::occ
