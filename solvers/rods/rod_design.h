// Kirchhoff rod design for a curve in R³ (thesis §5.7 with §5.8): the line-complex LP of
// Eq. 5.19 (feasibility by Prop. 9), scaling of the cross sections to a given size,
// geometry generation (§5.7.3) and, under loads, the dead-load fixed point (§5.8.2); plus
// the discrete elastic rod model of the result for forward simulation.
#pragma once

#include <string>
#include <vector>

#include "rods/dead_load.h"
#include "rods/discrete_elastic_rod.h"
#include "rods/line_complex_lp.h"
#include "rods/rod_geometry.h"

namespace parafab {

struct RodDesignOptions {
  RodMaterial material;         ///< default: SmoothSil 960
  LineComplexLpOptions lp;
  RodGeometryOptions geometry;
  /// Size: the load-free sections are scaled (h → λ·h, I ∝ λ) so that the largest mean
  /// radius √(a·b) along the rod equals this [m]. The loaded design keeps λ.
  double max_radius = 0.005;
  RodLoads loads;               ///< default: no loads
  DeadLoadOptions dead_load;    ///< its `geometry` is overwritten by `geometry`
};

enum class RodDesignStatus { Ok, Infeasible, LoadInfeasible, NotConverged, SolverFailed };
const char* to_string(RodDesignStatus status);

struct RodDesign {
  RodDesignStatus status = RodDesignStatus::SolverFailed;
  std::vector<RodSample> samples;
  LineComplexLpResult lp;           ///< normalized complex, twist ratio, binding samples
  double scale = 0;                 ///< λ [N]: h = λ (c_lp × γ + c̄_lp)
  Vec3 c{0, 0, 0}, c_bar{0, 0, 0};  ///< constants of the final equilibrium [N], [N·m]
  std::vector<Vec3> moment;         ///< h(s) [N·m]
  std::vector<RodSection> sections; ///< final cross sections and frame
  std::vector<Vec3> line_load;      ///< dead load p(s) of the final sections [N/m]
  std::vector<double> fixed_point_history;  ///< sup|p_{i+1} − p_i| [N/m]
  int fixed_point_iterations = 0;
  double lp_seconds = 0, geometry_seconds = 0, dead_load_seconds = 0, total_seconds = 0;
  std::string message;
  bool ok() const { return status == RodDesignStatus::Ok; }
};

/// `samples` from sample_by_arc_length; the curve must be Frénet (call require_frenet_curve,
/// which throws with the location of κ = 0). Throws parafab::Error for invalid options.
RodDesign design_rod(const std::vector<RodSample>& samples, const RodDesignOptions& options = {});

/// Convenience: samples `count` points equally in arc length, rejects κ = 0 (throws
/// parafab::Error naming s and t), and designs.
RodDesign design_rod(const SpaceCurve& curve, int count, const RodDesignOptions& options = {});

/// Discrete elastic rod of a design with `edges` edges, nodes equally spaced in arc length
/// on `curve` (the target), per-edge E·I, μ·J, E·A, ρ·A and material normal interpolated
/// linearly in s from the design's sections at the edge midpoints. With `with_loads`, the
/// design's gravity (if dead_load), point loads (at the nearest node) and external line load
/// (midpoint rule per edge, half to each node) are applied.
DiscreteRodModel discrete_rod_model(const RodDesign& design, const SpaceCurve& curve, int edges,
                                    const RodMaterial& material, const RodLoads& loads,
                                    bool with_loads);

}  // namespace parafab
