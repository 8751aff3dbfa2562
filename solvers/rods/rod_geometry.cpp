#include "rods/rod_geometry.h"

#include <chrono>
#include <cmath>

#include "common/error.h"

namespace parafab {

void validate(const RodMaterial& m) {
  if (!(m.youngs_modulus > 0) || !std::isfinite(m.youngs_modulus))
    PARAFAB_INPUT_ERROR("rod material: youngs_modulus must be > 0, got " << m.youngs_modulus);
  if (!(m.poisson_ratio > -1 && m.poisson_ratio < 0.5))
    PARAFAB_INPUT_ERROR("rod material: poisson_ratio must be in (-1, 0.5), got " << m.poisson_ratio);
  if (!(m.density >= 0) || !std::isfinite(m.density))
    PARAFAB_INPUT_ERROR("rod material: density must be >= 0, got " << m.density);
}

RodGeometryResult generate_rod_geometry(const std::vector<RodSample>& samples,
                                        const std::vector<Vec3>& moment,
                                        const RodMaterial& material,
                                        const RodGeometryOptions& options) {
  const auto t0 = std::chrono::steady_clock::now();
  validate(material);
  PARAFAB_VERIFY(samples.size() == moment.size(), "rod geometry: " << samples.size()
                                                                   << " samples but " << moment.size()
                                                                   << " moments");
  if (!(options.circularity_factor > 0) || !std::isfinite(options.circularity_factor))
    PARAFAB_INPUT_ERROR("rod geometry: circularity_factor must be > 0, got "
                        << options.circularity_factor);
  const double E = material.youngs_modulus, mu = material.shear_modulus();
  RodGeometryResult out;
  out.sections.resize(samples.size());
  for (size_t i = 0; i < samples.size(); ++i) {
    const RodSample& p = samples[i];
    const Vec3& h = moment[i];
    RodSection& sec = out.sections[i];
    sec.s = p.s;
    // Frénet coordinates: kn = (0, κ), f = (⟨N, h⟩, ⟨B, h⟩), ⟨f, kn⟩ = ⟨ωn, h⟩.
    const Eigen::Vector2d f(p.normal.dot(h), p.binormal.dot(h));
    const double fk = p.kappa * f.y();
    if (!(fk > 0)) {
      out.status = RodGeometryStatus::BinormalInComplex;
      out.failed_sample = int(i);
      out.failed_s = p.s;
      out.message = "rod geometry: <gamma' x gamma'', h> = " + std::to_string(fk) +
                    " <= 0 at s = " + std::to_string(p.s) +
                    " m: no cross section carries this moment (binormal line in the complex)";
      return out;
    }
    const Eigen::Matrix2d I1 = f * f.transpose() / (E * fk);
    Eigen::Matrix2d I2 = Eigen::Matrix2d::Zero();
    I2(0, 0) = 1;  // k⊥ k⊥ᵀ/κ² with k⊥ = (−κ, 0)
    const double tstar = I1.trace() / I2.trace();
    sec.I_frenet = I1 + options.circularity_factor * tstar * I2;
    sec.J = 4 * psi(sec.I_frenet);
    sec.twist = p.tangent.dot(h) / (mu * sec.J);
  }
  // β = ∫τβ and the parallel-frame angle −∫torsion (trapezoid rule).
  double beta = 0, par = 0;
  for (size_t i = 0; i < samples.size(); ++i) {
    if (i > 0) {
      const double ds = samples[i].s - samples[i - 1].s;
      beta += 0.5 * ds * (out.sections[i].twist + out.sections[i - 1].twist);
      par -= 0.5 * ds * (samples[i].torsion + samples[i - 1].torsion);
    }
    RodSection& sec = out.sections[i];
    const RodSample& p = samples[i];
    sec.beta = beta;
    sec.frame_angle = par + beta;
    const double c = std::cos(sec.frame_angle), s = std::sin(sec.frame_angle);
    sec.n1 = c * p.normal + s * p.binormal;
    sec.n2 = -s * p.normal + c * p.binormal;
    Eigen::Matrix2d Q;
    Q << c, -s, s, c;
    sec.I_material = Q.transpose() * sec.I_frenet * Q;
    sec.I_material(1, 0) = sec.I_material(0, 1);
    sec.ellipse = ellipse_from_area_moment(sec.I_material);
    sec.area = sec.ellipse.area();
  }
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

}  // namespace parafab
