// Geometry generation for general equilibrium curves (thesis §5.7.3): given the moment field
// h(s) = c×γ + c̄ (or its loaded form (c − Q)×γ + c̄ − M, §5.8) solve E·I·kn = Fnᵀh per sample
// with the one-parameter family I = I₁ + t·I₂ (I₁ = f fᵀ/(E⟨f,kn⟩), I₂ = k⊥k⊥ᵀ/κ²,
// f = Fnᵀh), t = factor·t*, t* = tr I₁ / tr I₂ (most circular ellipse), J = 4ψ(I) (ellipse,
// Eq. 5.8/5.10), twist τβ = ⟨γ', h⟩/(μJ) and β = ∫τβ (Eq. 5.17), and the rotated ellipse in
// the material frame Fβ (I_mat = Qᵀ I Q).
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "rods/elliptical_section.h"
#include "rods/space_curve.h"

namespace parafab {

/// Linear elastic rod material, SI units.
struct RodMaterial {
  double youngs_modulus = 2.3e6;  ///< E [Pa]
  double poisson_ratio = 0.48;    ///< ν
  double density = 1250;          ///< ρ [kg/m³]
  double shear_modulus() const { return youngs_modulus / (2 * (1 + poisson_ratio)); }  ///< μ
  /// SmoothSil 960 silicone (thesis §5.9.5): E = 2.3 MPa, ν = 0.48, ρ = 1250 kg/m³.
  static RodMaterial smooth_sil_960() { return {2.3e6, 0.48, 1250}; }
};

struct RodGeometryOptions {
  /// t = circularity_factor · t*; 1 gives the most circular ellipse, > 1 elongates the
  /// ellipse along the bending axis kn (more stable, §5.6.3 / §5.7.3). Must be > 0.
  double circularity_factor = 1.0;
};

/// Cross section and frame at one sample.
struct RodSection {
  double s = 0;
  Eigen::Matrix2d I_frenet = Eigen::Matrix2d::Identity();    ///< I in (N, B) coordinates [m⁴]
  Eigen::Matrix2d I_material = Eigen::Matrix2d::Identity();  ///< I in (n1, n2) of Fβ [m⁴]
  double J = 0;            ///< torsion constant 4ψ(I) [m⁴]
  EllipticalSection ellipse;  ///< semi-axes and angle in (n1, n2)
  double twist = 0;        ///< τβ [1/m], Eq. 5.17
  double beta = 0;         ///< β = ∫₀ˢ τβ [rad] (rotation from the parallel frame)
  double frame_angle = 0;  ///< θ: n1 = cos θ N + sin θ B (parallel-frame angle − ∫torsion + β)
  Vec3 n1{1, 0, 0}, n2{0, 1, 0};  ///< material normals of Fβ
  double area = 0;         ///< π a b [m²]
};

enum class RodGeometryStatus { Ok, BinormalInComplex };

struct RodGeometryResult {
  RodGeometryStatus status = RodGeometryStatus::Ok;
  std::vector<RodSection> sections;
  int failed_sample = -1;  ///< first sample with ⟨γ'×γ'', h⟩ ≤ 0
  double failed_s = -1;
  double seconds = 0;
  std::string message;
  bool ok() const { return status == RodGeometryStatus::Ok; }
};

/// `moment[i]` is h at samples[i] in N·m (E·I·kn = Fnᵀh). Throws parafab::Error for
/// mismatched sizes or invalid material/options; ⟨γ'×γ'', h⟩ ≤ 0 at a sample is a status.
RodGeometryResult generate_rod_geometry(const std::vector<RodSample>& samples,
                                        const std::vector<Vec3>& moment,
                                        const RodMaterial& material,
                                        const RodGeometryOptions& options = {});

/// Throws parafab::Error naming the field if E, ν or ρ is out of range.
void validate(const RodMaterial& material);

}  // namespace parafab
