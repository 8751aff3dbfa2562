// Design under load (thesis §5.8): line loads p(s) (the dead load p = ρ·A(s)·g with
// A = 2√π (det I)^{1/4} = πab) and point loads f_k at γ(s_k). Equilibrium (Eq. 5.20, signs
// derived from n' + q = 0, m' + γ'×n = 0 with q the applied force per length):
//   F K k = (c − Q(s)) × γ(s) + c̄ − M(s),  Q = ∫₀ˢ q,  M = ∫₀ˢ γ × q.
// (The thesis prints + signs, i.e. Q and M of −q; the forward simulation confirms this form.)
// q = dead load + external line load + point loads (δ-distributions).
// Algorithm of §5.8.2: shift (c, c̄) by the midrange of (Q₀, M₀) of the load-free geometry
// (step 1), then iterate p_{i+1} = p(I(p_i)) until sup|p_{i+1} − p_i| < tolerance (step 2).
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "rods/rod_geometry.h"

namespace parafab {

struct PointLoad {
  double s = 0;           ///< arc length of the application point (snapped to the nearest sample)
  Vec3 force{0, 0, 0};    ///< [N]
};

struct RodLoads {
  bool dead_load = false;            ///< include the rod's own weight ρ·A·g
  Vec3 gravity{0, 0, -9.81};         ///< g [m/s²]
  std::vector<PointLoad> point_loads;
  /// External line load q(s) [N/m] (fixed, e.g. wind or a cable along the rod); empty: none.
  std::function<Vec3(double s)> line_load;
  bool any() const { return dead_load || !point_loads.empty() || bool(line_load); }
};

struct DeadLoadOptions {
  double tolerance = 1e-10;   ///< on sup_s |p_{i+1}(s) − p_i(s)| [N/m] (thesis: ε = 1e-10)
  int max_iterations = 50;
  bool shift_constants = true;  ///< step 1 heuristic shift of c, c̄ (else keep c₀, c̄₀)
  RodGeometryOptions geometry;
};

enum class DeadLoadStatus { Converged, NotConverged, LoadInfeasible };
const char* to_string(DeadLoadStatus status);

struct DeadLoadResult {
  DeadLoadStatus status = DeadLoadStatus::NotConverged;
  Vec3 c{0, 0, 0}, c_bar{0, 0, 0};  ///< shifted constants used in the iteration [N], [N·m]
  RodGeometryResult geometry;       ///< geometry of the last iterate
  std::vector<Vec3> line_load;      ///< dead load p of the last geometry [N/m] (without q)
  std::vector<Vec3> moment;         ///< h = (c − Q)×γ + c̄ − M of the last iterate [N·m]
  std::vector<double> history;      ///< sup|p_{i+1} − p_i| per iteration [N/m]
  int iterations = 0;
  double seconds = 0;
  std::string message;
  bool ok() const { return status == DeadLoadStatus::Converged; }
};

/// Accumulated force Q(s) and moment M(s) of line load p (trapezoid rule) plus point loads
/// (applied at the nearest sample, included for s ≥ s_k).
void accumulate_loads(const std::vector<RodSample>& samples, const std::vector<Vec3>& p,
                      const std::vector<PointLoad>& point_loads, std::vector<Vec3>& Q,
                      std::vector<Vec3>& M);

/// `c0`, `c_bar0`: the load-free constants in physical units (h = c×γ + c̄ in N·m);
/// `load_free` the geometry they give. Throws parafab::Error for invalid input; failure
/// to converge (history included) or a load that no section can carry is a status.
DeadLoadResult solve_dead_load(const std::vector<RodSample>& samples, const Vec3& c0,
                               const Vec3& c_bar0, const RodGeometryResult& load_free,
                               const RodMaterial& material, const RodLoads& loads,
                               const DeadLoadOptions& options = {});

}  // namespace parafab
