// Arc-length geometry of a regular curve in R³ (thesis §3.1.2 and §5.3.1): arc length,
// Serret–Frénet frame (T, N, B), curvature κ = |γ'×γ''|, torsion, and the binormal vector
// ωn = γ'×γ'' used by the rod solvers (§5.6–5.7). Rods need Frénet curves (κ > 0).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <functional>
#include <vector>

namespace parafab {

using Vec3 = Eigen::Vector3d;

/// One point of an arc-length parametrized curve with its Frénet data.
struct RodSample {
  double t = 0;          ///< curve parameter
  double s = 0;          ///< arc length from the start [m]
  Vec3 point{0, 0, 0};   ///< γ(s)
  Vec3 tangent{0, 0, 1}; ///< T = γ'(s)
  Vec3 normal{1, 0, 0};  ///< principal normal N = γ''/κ
  Vec3 binormal{0, 1, 0};///< B = T × N
  double kappa = 0;      ///< curvature κ = |γ''| [1/m]
  double torsion = 0;    ///< Frénet torsion ⟨B, N'⟩ [1/m]
  Vec3 omega_n() const { return kappa * binormal; }  ///< γ' × γ''
};

/// γ and its parameter derivatives d^k γ / dt^k, k = 0..3.
using CurveDerivatives = std::function<std::array<Vec3, 4>(double t)>;

/// A regular parametric curve t ∈ [t0, t1] with an arc-length table (Gauss–Legendre).
class SpaceCurve {
 public:
  /// Throws parafab::Error if t1 ≤ t0, the curve has zero speed somewhere, or a value is not
  /// finite. `table_intervals` sets the resolution of the arc-length table.
  SpaceCurve(CurveDerivatives derivatives, double t0, double t1, int table_intervals = 512);

  double length() const { return table_s_.back(); }
  double first_parameter() const { return t0_; }
  double last_parameter() const { return t1_; }
  double arc_length_at(double t) const;
  /// Parameter t with arc_length_at(t) = s (safeguarded Newton), s clamped to [0, length].
  double parameter_at(double s) const;
  RodSample at_parameter(double t) const;
  /// Frénet data at t without the arc length (s = 0): for callers that know s.
  RodSample frenet_at_parameter(double t) const;
  RodSample at_arc_length(double s) const { return at_parameter(parameter_at(s)); }

 private:
  double speed(double t) const { return derivatives_(t)[1].norm(); }
  double integrate_speed(double a, double b) const;
  CurveDerivatives derivatives_;
  double t0_, t1_;
  std::vector<double> table_t_, table_s_, table_v_;  // parameter, arc length, speed
};

/// Samples at the arc lengths `s` (sorted, in [0, length]).
std::vector<RodSample> sample_at(const SpaceCurve& curve, const std::vector<double>& s);

/// `count` ≥ 2 samples equally spaced in arc length, ends included.
std::vector<RodSample> sample_by_arc_length(const SpaceCurve& curve, int count);

/// Rejects curves that are not Frénet curves: throws parafab::Error (PARAFAB_INPUT_ERROR)
/// naming the arc length s and parameter t where κ·length < `min_kappa_length` (default
/// 1e-6). Checks the samples and, between samples, every local minimum of κ refined by
/// golden-section search on the continuous curve.
void require_frenet_curve(const SpaceCurve& curve, const std::vector<RodSample>& samples,
                          double min_kappa_length = 1e-6);

}  // namespace parafab
