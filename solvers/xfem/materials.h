// Material laws for the XFEM elasticity (thesis §6.4.1, Eq. 6.18): a strain energy density
// Ψ(F) of the deformation gradient F, its first Piola–Kirchhoff stress P = ∂Ψ/∂F and the
// tangent A = ∂P/∂F = ∂²Ψ/∂F², all derived analytically.
//
// Tangent layout: A is a 9×9 matrix acting on vec(F), the COLUMN-MAJOR vectorization of F
// (Eigen's default storage, i.e. Eigen::Map<const Vec9>(F.data())):
//     vec(F)[i + 3j] = F(i, j),      A(i + 3j, k + 3l) = ∂P(i, j) / ∂F(k, l).
// So vec(dP) = A · vec(dF), and A is symmetric (a Hessian of Ψ; "major symmetry").
//
// Elastic constants from Young's modulus E and Poisson's ratio ν:
//     μ = E / (2(1 + ν)),   λ = E ν / ((1 + ν)(1 − 2ν)),   κ = E / (3(1 − 2ν)).
// All laws below reduce to the same linear elasticity (μ, λ) at small strain.
//
// Inverted or degenerate elements (J = det F ≤ 0, or non-finite F) for the hyperelastic
// laws: energy() returns +∞ (so a line search rejects the step), while stress() and
// tangent() throw parafab::Error (PARAFAB_VERIFY) naming the model and the value of J.
// LinearElastic is defined for every F (no J restriction).
#pragma once

#include <Eigen/Core>
#include <memory>
#include <string>

namespace parafab::xfem {

using Mat3 = Eigen::Matrix3d;
using Vec9 = Eigen::Matrix<double, 9, 1>;
using Mat9 = Eigen::Matrix<double, 9, 9>;

/// Column-major vec(F) (see the layout note above).
inline Vec9 vec9(const Mat3& F) { return Eigen::Map<const Vec9>(F.data()); }

/// Lamé parameters and bulk modulus from (E, ν); throws parafab::Error unless E > 0 and
/// −1 < ν < 0.5 (`model` is named in the message).
struct ElasticConstants {
  double E = 0, nu = 0;
  double mu = 0;      ///< shear modulus μ
  double lambda = 0;  ///< Lamé λ
  double kappa = 0;   ///< bulk modulus κ = λ + 2μ/3
  static ElasticConstants from_young_poisson(double E, double nu, const std::string& model);
};

/// A strain energy density Ψ(F) per unit undeformed volume.
class Material {
 public:
  virtual ~Material() = default;
  virtual std::string name() const = 0;
  /// Ψ(F); +∞ for a hyperelastic law when det F ≤ 0.
  virtual double energy(const Mat3& F) const = 0;
  /// First Piola–Kirchhoff stress P = ∂Ψ/∂F.
  virtual Mat3 stress(const Mat3& F) const = 0;
  /// A = ∂P/∂F as 9×9 on column-major vec(F): A(i + 3j, k + 3l) = ∂P_ij/∂F_kl.
  virtual Mat9 tangent(const Mat3& F) const = 0;
};

/// Small-strain linear elasticity: ε = sym(F − I), Ψ = μ ε:ε + λ/2 tr(ε)²,
/// P = 2μ ε + λ tr(ε) I, A_ijkl = μ(δik δjl + δil δjk) + λ δij δkl (constant).
/// Not objective under finite rotations (by design: it is the linear model).
class LinearElastic : public Material {
 public:
  LinearElastic(double E, double nu);
  std::string name() const override { return "linear"; }
  double energy(const Mat3& F) const override;
  Mat3 stress(const Mat3& F) const override;
  Mat9 tangent(const Mat3& F) const override;
  const ElasticConstants& constants() const { return c_; }

 private:
  ElasticConstants c_;
};

/// Compressible neo-Hookean in the Bonet–Wood form:
///     Ψ = μ/2 (I₁ − 3) − μ ln J + λ/2 (ln J)²,   I₁ = tr(FᵀF), J = det F,
///     P = μ (F − F⁻ᵀ) + λ ln J F⁻ᵀ,
///     A_ijkl = μ δik δjl + (μ − λ ln J) G_il G_kj + λ G_ij G_kl,   G = F⁻ᵀ.
class NeoHookean : public Material {
 public:
  NeoHookean(double E, double nu);
  std::string name() const override { return "neo_hooke"; }
  double energy(const Mat3& F) const override;
  Mat3 stress(const Mat3& F) const override;
  Mat9 tangent(const Mat3& F) const override;
  const ElasticConstants& constants() const { return c_; }

 private:
  ElasticConstants c_;
};

/// Compressible Mooney–Rivlin with isochoric invariants — CalculiX's / Abaqus's
/// *HYPERELASTIC, MOONEY-RIVLIN (C10, C01, D1):
///     Ψ = C10 (Ī₁ − 3) + C01 (Ī₂ − 3) + (1/D1)(J − 1)²,
///     Ī₁ = J^{-2/3} I₁,  Ī₂ = J^{-4/3} I₂,  I₂ = ½(I₁² − tr(C²)),  C = FᵀF.
/// Stress: with G = F⁻ᵀ,
///     ∂Ī₁/∂F = J^{-2/3} (2F − ⅔ I₁ G),
///     ∂Ī₂/∂F = J^{-4/3} (2 I₁ F − 2 F C − ⁴⁄₃ I₂ G),
///     P = C10 ∂Ī₁/∂F + C01 ∂Ī₂/∂F + (2/D1)(J − 1) J G.
/// The tangent differentiates these once more (see materials.cpp).
/// Small-strain limit: shear modulus μ = 2(C10 + C01), bulk modulus κ = 2/D1.
/// With C01 = 0 this is CalculiX's *HYPERELASTIC, NEO HOOKE (C10, D1): see
/// NeoHookeanIsochoric.
class MooneyRivlin : public Material {
 public:
  /// Direct coefficients; throws parafab::Error unless D1 > 0, C10, C01 finite and
  /// C10 + C01 > 0.
  MooneyRivlin(double C10, double C01, double D1);
  /// From (E, ν): C10 = μ/2 (1 − r), C01 = μ/2 r, D1 = 2/κ, so that the law matches linear
  /// elasticity at small strain. The ratio r = C01/(C10 + C01) must lie in [0, 1].
  static MooneyRivlin from_young_poisson(double E, double nu, double ratio = 0);

  std::string name() const override { return "mooney_rivlin"; }
  double energy(const Mat3& F) const override;
  Mat3 stress(const Mat3& F) const override;
  Mat9 tangent(const Mat3& F) const override;
  double C10() const { return C10_; }
  double C01() const { return C01_; }
  double D1() const { return D1_; }

 private:
  double C10_, C01_, D1_;
};

/// CalculiX's *HYPERELASTIC, NEO HOOKE: Ψ = C10 (Ī₁ − 3) + (1/D1)(J − 1)², i.e. MooneyRivlin
/// with C01 = 0. From (E, ν): C10 = μ/2, D1 = 2/κ.
class NeoHookeanIsochoric : public MooneyRivlin {
 public:
  NeoHookeanIsochoric(double C10, double D1) : MooneyRivlin(C10, 0, D1) {}
  std::string name() const override { return "neo_hooke_isochoric"; }
  static NeoHookeanIsochoric from_young_poisson(double E, double nu);
};

struct MaterialOptions {
  /// "mooney_rivlin" only: r = C01/(C10 + C01) ∈ [0, 1]; 0 gives the isochoric neo-Hookean.
  double mooney_rivlin_ratio = 0;
};

/// Factory by model name: "linear" (LinearElastic), "neo_hooke" (NeoHookean, Bonet–Wood),
/// "neo_hooke_isochoric" (NeoHookeanIsochoric, CalculiX NEO HOOKE) or "mooney_rivlin"
/// (MooneyRivlin::from_young_poisson with options.mooney_rivlin_ratio).
/// Throws parafab::Error naming the model for unknown names and invalid parameters
/// (E ≤ 0, ν ∉ (−1, 0.5), ratio ∉ [0, 1]).
std::unique_ptr<Material> make_material(const std::string& model, double E, double nu,
                                        const MaterialOptions& options = {});

}  // namespace parafab::xfem
