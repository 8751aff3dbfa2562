// Material laws Ψ(F), P = ∂Ψ/∂F, A = ∂P/∂F (see materials.h for the formulas and layout).
//
// Derivative building blocks (G = F⁻ᵀ, J = det F, C = FᵀF, B = FFᵀ, all 9×9 on
// column-major vec, index (i, j) ↦ i + 3j):
//     ∂J/∂F = J G,            ∂ ln J/∂F = G,           ∂G_ij/∂F_kl = −G_il G_kj,
//     ∂I₁/∂F = 2F,            ∂I₂/∂F = 2(I₁ F − F C),
//     ∂(F C)_ij/∂F_kl = δik C_lj + F_il F_kj + B_ik δjl.
#include "xfem/materials.h"

#include <Eigen/LU>
#include <cmath>
#include <limits>

#include "common/error.h"

namespace parafab::xfem {
namespace {

inline int ix(int i, int j) { return i + 3 * j; }

/// K(i + 3j, k + 3l) = G_il G_kj, so that ∂vec(G)/∂vec(F) = −K for G = F⁻ᵀ. Symmetric.
Mat9 inverse_transpose_kernel(const Mat3& G) {
  Mat9 K;
  for (int j = 0; j < 3; ++j)
    for (int i = 0; i < 3; ++i)
      for (int l = 0; l < 3; ++l)
        for (int k = 0; k < 3; ++k) K(ix(i, j), ix(k, l)) = G(i, l) * G(k, j);
  return K;
}

/// ∂vec(F C)/∂vec(F) with C = FᵀF (F C = F Fᵀ F).
Mat9 fc_derivative(const Mat3& F) {
  const Mat3 C = F.transpose() * F, B = F * F.transpose();
  Mat9 D;
  for (int j = 0; j < 3; ++j)
    for (int i = 0; i < 3; ++i)
      for (int l = 0; l < 3; ++l)
        for (int k = 0; k < 3; ++k)
          D(ix(i, j), ix(k, l)) =
              (i == k ? C(l, j) : 0.0) + F(i, l) * F(k, j) + (j == l ? B(i, k) : 0.0);
  return D;
}

/// J = det F, checked > 0 for stress/tangent evaluation.
double checked_det(const Mat3& F, const char* model, const char* what) {
  const double J = F.determinant();
  PARAFAB_VERIFY(std::isfinite(J) && J > 0, model << ": " << what
                                                   << " needs det F > 0 (inverted element), got J = "
                                                   << J);
  return J;
}

const double kInf = std::numeric_limits<double>::infinity();

// Small-strain accurate kinematics. With F = I + H and strains ε ~ 1e-4 (steel parts), the
// textbook forms I₁ − 3 and ln J = ln(det F) lose everything below eps·3 ≈ 7e-16 while Ψ is of
// order ε² ≈ 1e-8: Ψ came out with a relative noise of ~1e-9, larger than a Newton step's
// predicted energy decrease near the solution, and the line search failed on a machine whose
// BLAS kernel moved the iterate by round-off (python.simulate_threads, SkylakeX kernel). These
// helpers keep every term relative to ε.

/// J − 1 = det(I + H) − 1 = tr H + ½((tr H)² − tr(H²)) + det H.
double det_minus_one(const Mat3& H) {
  const double t = H.trace();
  return t + 0.5 * (t * t - (H * H).trace()) + H.determinant();
}

/// j − ln(1 + j), accurate for small |j| (a series there; it is of order j²/2).
double minus_log1p_remainder(double j) {
  if (std::abs(j) >= 0.1) return j - std::log1p(j);
  double term = j * j, sum = 0;  // Σ_{k≥2} (−1)^k j^k / k
  for (int k = 2; k < 40; ++k) {
    const double add = term / k;
    sum += add;
    if (std::abs(add) <= 1e-18 * std::abs(sum)) break;
    term *= -j;
  }
  return sum;
}

}  // namespace

ElasticConstants ElasticConstants::from_young_poisson(double E, double nu, const std::string& model) {
  PARAFAB_VERIFY(std::isfinite(E) && E > 0,
                 "material '" << model << "': Young's modulus E must be > 0, got " << E);
  PARAFAB_VERIFY(std::isfinite(nu) && nu > -1 && nu < 0.5,
                 "material '" << model << "': Poisson's ratio nu must lie in (-1, 0.5), got " << nu);
  ElasticConstants c;
  c.E = E;
  c.nu = nu;
  c.mu = E / (2 * (1 + nu));
  c.lambda = E * nu / ((1 + nu) * (1 - 2 * nu));
  c.kappa = E / (3 * (1 - 2 * nu));
  return c;
}

// ---------------------------------------------------------------------------------------
// LinearElastic

LinearElastic::LinearElastic(double E, double nu)
    : c_(ElasticConstants::from_young_poisson(E, nu, "linear")) {}

double LinearElastic::energy(const Mat3& F) const {
  const Mat3 H = F - Mat3::Identity();
  const Mat3 eps = 0.5 * (H + H.transpose());
  const double tr = eps.trace();
  return c_.mu * eps.squaredNorm() + 0.5 * c_.lambda * tr * tr;
}

Mat3 LinearElastic::stress(const Mat3& F) const {
  const Mat3 H = F - Mat3::Identity();
  const Mat3 eps = 0.5 * (H + H.transpose());
  return 2 * c_.mu * eps + c_.lambda * eps.trace() * Mat3::Identity();
}

Mat9 LinearElastic::tangent(const Mat3& /*F*/) const {
  Mat9 A = Mat9::Zero();
  for (int j = 0; j < 3; ++j)
    for (int i = 0; i < 3; ++i) {
      A(ix(i, j), ix(i, j)) += c_.mu;  // δik δjl
      A(ix(i, j), ix(j, i)) += c_.mu;  // δil δjk
    }
  for (int i = 0; i < 3; ++i)
    for (int k = 0; k < 3; ++k) A(ix(i, i), ix(k, k)) += c_.lambda;  // δij δkl
  return A;
}

// ---------------------------------------------------------------------------------------
// NeoHookean (Bonet–Wood)

NeoHookean::NeoHookean(double E, double nu)
    : c_(ElasticConstants::from_young_poisson(E, nu, "neo_hooke")) {}

double NeoHookean::energy(const Mat3& F) const {
  const double J = F.determinant();
  if (!(J > 0) || !std::isfinite(J)) return kInf;
  // Ψ = μ/2 (I₁ − 3) − μ ln J + λ/2 ln²J written without cancellation (see det_minus_one):
  // I₁ − 3 = 2 tr H + |H|², tr H − ln J = −(i₂ + det H) + (j − ln(1 + j)), j = J − 1.
  const Mat3 H = F - Mat3::Identity();
  const double t = H.trace(), i2 = 0.5 * (t * t - (H * H).trace()), d = H.determinant();
  const double j = t + i2 + d;
  if (!(j > -1)) return kInf;
  const double lnJ = std::log1p(j);
  return c_.mu * (minus_log1p_remainder(j) - i2 - d) + 0.5 * c_.mu * H.squaredNorm() +
         0.5 * c_.lambda * lnJ * lnJ;
}

Mat3 NeoHookean::stress(const Mat3& F) const {
  const double J = checked_det(F, "neo_hooke", "stress");
  const Mat3 G = F.inverse().transpose();
  return c_.mu * (F - G) + c_.lambda * std::log(J) * G;
}

Mat9 NeoHookean::tangent(const Mat3& F) const {
  const double J = checked_det(F, "neo_hooke", "tangent");
  const Mat3 G = F.inverse().transpose();
  const Vec9 g = vec9(G);
  return c_.mu * Mat9::Identity() + (c_.mu - c_.lambda * std::log(J)) * inverse_transpose_kernel(G) +
         c_.lambda * g * g.transpose();
}

// ---------------------------------------------------------------------------------------
// MooneyRivlin (CalculiX / Abaqus, isochoric invariants)

MooneyRivlin::MooneyRivlin(double C10, double C01, double D1) : C10_(C10), C01_(C01), D1_(D1) {
  PARAFAB_VERIFY(std::isfinite(D1) && D1 > 0,
                 "material 'mooney_rivlin': D1 must be > 0 (compressible form), got " << D1);
  PARAFAB_VERIFY(std::isfinite(C10) && std::isfinite(C01) && C10 + C01 > 0,
                 "material 'mooney_rivlin': need finite C10, C01 with C10 + C01 > 0, got C10 = "
                     << C10 << ", C01 = " << C01);
}

MooneyRivlin MooneyRivlin::from_young_poisson(double E, double nu, double ratio) {
  const auto c = ElasticConstants::from_young_poisson(E, nu, "mooney_rivlin");
  PARAFAB_VERIFY(std::isfinite(ratio) && ratio >= 0 && ratio <= 1,
                 "material 'mooney_rivlin': ratio C01/(C10 + C01) must lie in [0, 1], got " << ratio);
  return MooneyRivlin(0.5 * c.mu * (1 - ratio), 0.5 * c.mu * ratio, 2 / c.kappa);
}

NeoHookeanIsochoric NeoHookeanIsochoric::from_young_poisson(double E, double nu) {
  const auto c = ElasticConstants::from_young_poisson(E, nu, "neo_hooke_isochoric");
  return NeoHookeanIsochoric(0.5 * c.mu, 2 / c.kappa);
}

namespace {
// Kinematics shared by the Mooney–Rivlin energy, stress and tangent (J > 0 checked by caller).
struct Invariants {
  Mat3 C;
  double I1, I2, Jm23, Jm43;  // I₂ = ½(I₁² − C:C), J^{-2/3}, J^{-4/3}
  Invariants(const Mat3& F, double J) : C(F.transpose() * F) {
    I1 = C.trace();
    I2 = 0.5 * (I1 * I1 - C.squaredNorm());  // tr(C²) = C:C (C symmetric)
    Jm23 = 1 / std::cbrt(J * J);
    Jm43 = Jm23 * Jm23;
  }
};
}  // namespace

double MooneyRivlin::energy(const Mat3& F) const {
  const double J = F.determinant();
  if (!(J > 0) || !std::isfinite(J)) return kInf;
  // Ī₁ − 3 = J^{-2/3} ((I₁ − 3) − 3 (J^{2/3} − 1)), likewise Ī₂ − 3 with J^{4/3}, each part
  // computed to full relative accuracy in the strain (see det_minus_one): with C = I + E,
  // I₁ − 3 = tr E and I₂ − 3 = 2 tr E + ½((tr E)² − |E|²). The difference of the two parts
  // still cancels at first order (both ≈ 2 tr H for Ī₁, ≈ 4 tr H for Ī₂), leaving ~eps/ε relative
  // (2e-12 at ε = 1e-4), far below the textbook form's eps/ε² (1e-8).
  const Mat3 H = F - Mat3::Identity();
  const Mat3 E = H + H.transpose() + H.transpose() * H;
  const double e1 = E.trace(), j = det_minus_one(H);
  if (!(j > -1)) return kInf;
  const double lnJ = std::log1p(j);
  const double bar1 = std::exp(-2.0 / 3.0 * lnJ) * (e1 - 3 * std::expm1(2.0 / 3.0 * lnJ));
  const double bar2 = std::exp(-4.0 / 3.0 * lnJ) *
                      (2 * e1 + 0.5 * (e1 * e1 - E.squaredNorm()) - 3 * std::expm1(4.0 / 3.0 * lnJ));
  return C10_ * bar1 + C01_ * bar2 + j * j / D1_;
}

Mat3 MooneyRivlin::stress(const Mat3& F) const {
  const double J = checked_det(F, name().c_str(), "stress");
  const Mat3 G = F.inverse().transpose();
  const Invariants v(F, J);
  const Mat3& C = v.C;
  const double I1 = v.I1, I2 = v.I2, Jm23 = v.Jm23, Jm43 = v.Jm43;
  const Mat3 dI1bar = Jm23 * (2 * F - (2.0 / 3.0) * I1 * G);
  const Mat3 dI2bar = Jm43 * (2 * I1 * F - 2 * F * C - (4.0 / 3.0) * I2 * G);
  return C10_ * dI1bar + C01_ * dI2bar + (2 / D1_) * (J - 1) * J * G;
}

Mat9 MooneyRivlin::tangent(const Mat3& F) const {
  const double J = checked_det(F, name().c_str(), "tangent");
  const Mat3 G = F.inverse().transpose();
  const Invariants v(F, J);
  const Mat3& C = v.C;
  const double I1 = v.I1, I2 = v.I2, Jm23 = v.Jm23, Jm43 = v.Jm43;
  const Vec9 f = vec9(F), g = vec9(G);
  const Mat9 K = inverse_transpose_kernel(G);  // ∂g/∂f = −K
  const Mat9 I9 = Mat9::Identity();

  // ∂²Ī₁/∂F² = J^{-2/3} [2 I − ⁴⁄₃ (f gᵀ + g fᵀ) + ⁴⁄₉ I₁ g gᵀ + ⅔ I₁ K].
  const Mat9 H1 = Jm23 * (2 * I9 - (4.0 / 3.0) * (f * g.transpose() + g * f.transpose()) +
                          (4.0 / 9.0) * I1 * g * g.transpose() + (2.0 / 3.0) * I1 * K);
  Mat9 A = C10_ * H1;

  if (C01_ != 0) {
    // w = vec(2 I₁ F − 2 F C − ⁴⁄₃ I₂ G) = dI₂ − ⁴⁄₃ I₂ g, with dI₂ = vec(∂I₂/∂F).
    // ∂²Ī₂/∂F² = J^{-4/3} [−⁴⁄₃ w gᵀ + 4 f fᵀ + 2 I₁ I − 2 ∂vec(FC)/∂f − ⁴⁄₃ g dI₂ᵀ + ⁴⁄₃ I₂ K].
    const Vec9 dI2 = 2 * (I1 * f - vec9(F * C));
    const Vec9 w = dI2 - (4.0 / 3.0) * I2 * g;
    const Mat9 H2 = Jm43 * (-(4.0 / 3.0) * w * g.transpose() + 4 * f * f.transpose() + 2 * I1 * I9 -
                            2 * fc_derivative(F) - (4.0 / 3.0) * g * dI2.transpose() +
                            (4.0 / 3.0) * I2 * K);
    A += C01_ * H2;
  }

  // Volumetric: P_vol = (2/D1)(J² − J) g ⇒ A_vol = (2/D1)[(2J − 1) J g gᵀ − (J² − J) K].
  A += (2 / D1_) * ((2 * J - 1) * J * g * g.transpose() - (J * J - J) * K);
  return A;
}

// ---------------------------------------------------------------------------------------

std::unique_ptr<Material> make_material(const std::string& model, double E, double nu,
                                        const MaterialOptions& options) {
  if (model == "linear") return std::make_unique<LinearElastic>(E, nu);
  if (model == "neo_hooke") return std::make_unique<NeoHookean>(E, nu);
  if (model == "neo_hooke_isochoric")
    return std::make_unique<NeoHookeanIsochoric>(NeoHookeanIsochoric::from_young_poisson(E, nu));
  if (model == "mooney_rivlin")
    return std::make_unique<MooneyRivlin>(
        MooneyRivlin::from_young_poisson(E, nu, options.mooney_rivlin_ratio));
  PARAFAB_INPUT_ERROR("unknown material model '"
                      << model
                      << "' (expected 'linear', 'neo_hooke', 'neo_hooke_isochoric' or 'mooney_rivlin')");
}

}  // namespace parafab::xfem
