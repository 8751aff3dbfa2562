// Moment fitting (thesis Eq. 6.11, after Müller, Kummer & Oberlack 2013): weights for fixed
// tensor Gauss points in the unit square / cube that integrate a polynomial basis exactly,
// w = Aᵀ(AAᵀ)⁻¹ b with A prefactorized once per (dimension, degree, points).
//
// The basis is the span of the thesis' monomials — ξ^a η^b (a, b ≤ p) for areas and
// ξ^a η^b ζ^c (a + b + c ≤ p) for volumes — written in normalized shifted Legendre polynomials
// L_a(ξ) L_b(η) L_c(ζ). The minimal-norm solution depends on the span only (A → T A, b → T b
// leaves Aᵀ(AAᵀ)⁻¹b unchanged for invertible T), so the rules are the thesis' rules, but A is
// well conditioned — A W Aᵀ = I for the Gauss weights W, since q ≥ p + 1 points per direction
// integrate the products exactly — instead of a monomial Vandermonde matrix.
#pragma once

#include <Eigen/Core>
#include <array>
#include <vector>

namespace parafab::xfem {

/// Normalized shifted Legendre polynomials L_k(x) = √(2k+1) P_k(2x − 1) (∫₀¹ L_j L_k = δ_jk)
/// and antiderivatives I_k(x) = ∫₀ˣ L_k, written to values[0..n) and integrals[0..n).
void legendre_basis(double x, int n, double* values, double* integrals);
/// legendre_basis at the points x[0..count) at once (the same values, vectorizable): row k < n
/// of `values` / `integrals`, starting at k·stride, receives L_k / I_k at the points.
/// `work` holds 3·stride doubles; stride ≥ count.
void legendre_basis_rows(const double* x, int count, int stride, int n, double* values,
                         double* integrals, double* work);

enum class WeightFit {
  MinimalNorm,  ///< w = Aᵀ(AAᵀ)⁻¹ b (thesis Eq. 6.11): exact moments, weights of either sign
  NonNegative  ///< min ‖A w − b‖ s.t. w ≥ 0 (Lawson–Hanson): moments exact only if feasible
};

/// The constant moment-fitting system of one (dimension, degree, points per direction, cap).
struct FittingSystem {
  std::vector<std::array<int, 3>> exponents;  ///< basis i is L_a(ξ) L_b(η) L_c(ζ), c = 0 in 2D
  Eigen::MatrixXd points;                     ///< dimension × n tensor Gauss points in [0, 1]^d
  Eigen::MatrixXd A;                          ///< m × n, A(i, j) = basis i at point j
  Eigen::MatrixXd pseudo_inverse;  ///< n × m, Aᵀ(AAᵀ)⁻¹ (from a QR factorization of Aᵀ)
};

/// Area system: basis 0 ≤ a, b ≤ degree, points_per_direction² points.
/// Systems are built at first use and cached (thread-safe). Throws parafab::Error unless
/// 0 ≤ degree and degree + 1 ≤ points_per_direction ≤ kMaxGaussPoints.
const FittingSystem& square_fitting_system(int degree, int points_per_direction);
/// Volume system: basis a + b + c ≤ degree, points_per_direction³ points. Same conditions.
/// With max_exponent ≥ 0 also a, b, c ≤ max_exponent (the capped span: degree 10 capped at 4
/// holds every product of two gradients of triquadratic functions, x⁴y⁴z² and the like, with
/// 121 functions instead of 286), and points_per_direction ≥ min(degree, max_exponent) + 1.
const FittingSystem& cube_fitting_system(int degree, int points_per_direction, int max_exponent = -1);

struct WeightFitResult {
  Eigen::VectorXd weights;  ///< on the system's unit square / cube points
  double residual = 0;  ///< ‖A w − b‖∞ (moments of the normalized basis on the unit domain)
};
WeightFitResult fit_weights(const FittingSystem& system, const Eigen::VectorXd& moments,
                            WeightFit fit);

}  // namespace parafab::xfem
