// Curve rules (thesis §6.3.1): Gauss–Legendre integration along the linear and parabolic
// segments of uv boundary loops, in the flux form that Green's theorem (Eq. 6.12) needs, and
// the parabolic (Lagrange) sampling of smooth curves that produces such segments.
#pragma once

#include <functional>
#include <vector>

#include "xfem/cut_geometry.h"

namespace parafab::xfem {

/// One polynomial segment x(t), t ∈ [0, 1]: order 1 joins `start` and `end`; order 2 is the
/// parabola through start (t = 0), mid (t = 1/2) and end (t = 1). `mid` is unused for order 1.
struct CurveSegment2 {
  Vec2 start{0, 0}, mid{0, 0}, end{0, 0};
  int order = 1;
  Vec2 position(double t) const;
  Vec2 derivative(double t) const;
};

/// A closed chain of segments (each segment's end is the next one's start), region on the left.
using UvLoop = std::vector<CurveSegment2>;

/// Segments of a BoundaryLoop. A closing gap up to 1e-9 × (loop diameter) is bridged by a
/// straight segment; larger gaps, wrong point counts or orders throw parafab::Error.
UvLoop to_uv_loop(const BoundaryLoop& loop);
std::vector<UvLoop> to_uv_loops(const std::vector<BoundaryLoop>& loops);

/// Exact axis-aligned bounding box of the segments (parabola extremes included) grown into
/// [lo, hi]; start with lo = +∞, hi = −∞.
void extend_bounding_box(const CurveSegment2& segment, Vec2& lo, Vec2& hi);

struct CurveRuleOptions {
  /// Gauss–Legendre points per segment. 0: the fewest for which g(x(t))·x'(t) is integrated
  /// exactly when g is a polynomial of total degree `polynomial_degree` in (u, v), i.e.
  /// ⌊d/2⌋ + 1 points on linear and d + 1 on parabolic segments.
  int points_per_segment = 0;
  int polynomial_degree = 1;
};

/// Points x_j and weighted derivatives dx_j = x'(t_j)·w_j of all segments, such that
///   ∫ g ds ≈ Σ g(x_j) ‖dx_j‖   and   ∮ n·P ds ≈ Σ (P₁(x_j) dx_j.y − P₂(x_j) dx_j.x)
/// (n the outward normal, i.e. pointing to the right of the direction of travel).
struct CurveRule2 {
  std::vector<Vec2> points;
  std::vector<Vec2> dx;
};
CurveRule2 curve_rule(const std::vector<CurveSegment2>& segments,
                      const CurveRuleOptions& options = {});

struct ParabolicSamplingOptions {
  /// Largest allowed distance between the curve and its parabolic interpolant, checked at
  /// t = 1/4 and 3/4 of every segment (the interpolation error is O(h³), the enclosed-area
  /// and arc-length errors O(h⁴)).
  double tolerance = 1e-10;
  int initial_segments = 1;
  int max_segments = 1 << 16;
};
struct ParabolicSampling {
  std::vector<Vec2> points;        ///< 2N + 1 samples: segment k is points[2k..2k+2]
  std::vector<double> parameters;  ///< the curve parameters of the samples
  double max_deviation = 0;        ///< largest deviation found at the check points
  bool converged = false;          ///< max_deviation ≤ tolerance
};
/// Parabolic segments (order 2, as in BoundaryLoop) interpolating `curve` on [t0, t1],
/// bisected until the deviation check passes. The samples can be appended to a BoundaryLoop
/// (drop the first point when it repeats the previous segment's end).
ParabolicSampling sample_parabolic(const std::function<Vec2(double)>& curve, double t0, double t1,
                                   const ParabolicSamplingOptions& options = {});

}  // namespace parafab::xfem
