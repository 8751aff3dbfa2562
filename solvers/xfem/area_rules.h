// Area and surface rules (thesis §6.3.2): moment fitting on the uv bounding box mapped to the
// unit square (Eq. 6.9–6.11, 6.14) with moments from Green's theorem along the loops
// (Eq. 6.12–6.13), and surface rules through the area factor ‖σu × σv‖ (Eq. 6.15).
#pragma once

#include <Eigen/Core>
#include <functional>
#include <vector>

#include "xfem/curve_rules.h"
#include "xfem/cut_geometry.h"
#include "xfem/moment_fitting.h"
#include "xfem/quadrature_rule.h"

namespace parafab::xfem {

struct AreaRuleOptions {
  /// Basis ξ^a η^b, 0 ≤ a, b ≤ degree (thesis: 4 for planar areas, 5 for surfaces).
  int degree = 4;
  /// Tensor Gauss points per direction in the unit square (≥ degree + 1). 0: the even one of
  /// degree + 1, degree + 2. Then on an uncut box the minimal-norm rule is the tensor Gauss
  /// rule (the symmetric 1D Gauss weights are an even polynomial of degree q − 2 ≤ p in the
  /// node, hence in the row space of A) and keeps Gauss accuracy for non-polynomial
  /// integrands; e.g. p = 5, q = 7 loses it (area of a sphere octant: 7e-8 instead of 6e-14).
  int points_per_direction = 0;
  WeightFit fit = WeightFit::MinimalNorm;
  /// Status ResidualAboveTolerance when ‖A w − b‖∞ exceeds this (only NNLS can).
  double residual_tolerance = 1e-10;
};

/// The points per direction `options` resolve to (the default rule above for 0).
int area_points_per_direction(const AreaRuleOptions& options);

struct AreaRule {
  QuadratureRule2 rule;  ///< uv points (tensor Gauss points of the bounding box) and weights
  RuleStatus status = RuleStatus::Ok;
  double measure = 0;                 ///< ∫ 1 over the region (signed: < 0 for clockwise loops)
  double moment_residual = 0;         ///< ‖A w − b‖∞, relative to the bounding-box area
  Vec2 box_min{0, 0}, box_max{0, 0};  ///< uv bounding box mapped to the unit square
};

/// Rule for the region bounded by `loops` (outer loops counter-clockwise, holes clockwise).
/// Integrates every polynomial of degree ≤ `degree` in each of u, v exactly, up to the
/// round-off of the moments (the loops' segments are integrated exactly, see curve_rule).
/// Points may lie outside the region (anywhere in its bounding box).
AreaRule area_rule(const std::vector<BoundaryLoop>& loops, const AreaRuleOptions& options = {});
AreaRule area_rule(const std::vector<UvLoop>& loops, const AreaRuleOptions& options = {});

/// Adaptive refinement of an area rule (an extension of the thesis, which uses one rule per
/// region): a region whose degree-p and degree-(p+1) rules integrate `integral` differently by
/// more than tolerance · 4^(−depth) (so the leaves' tolerances add up to `tolerance`) is split
/// at the centre of its bounding box into four quadrants, loops clipped to each quadrant.
/// The difference estimates the error of the degree-p rule; the integral reported is the sum
/// of the degree-(p+1) values (local extrapolation), usually far more accurate than that.
///
/// Before a region is split, rules of degree p + degree_boost and p + degree_boost + 1 are
/// tried on it (p-refinement): a smooth integrand over a curved, trimmed region (a cylinder
/// turned against the grid) is usually resolved by raising the degree long before quartering
/// converges (test AreaRule.DegreeBoostResolvesASmoothIntegrandWithFewerLeaves). The leaf then carries the
/// boosted rule.
struct RefinementOptions {
  double tolerance = 0;   ///< 0: no refinement (the estimate of the single rule is still reported)
  bool relative = false;  ///< tolerance relative to ‖integral‖∞ of the root region
  int max_depth = 6;
  int degree_boost = 0;   ///< 0: split only
  /// Regions examined at most (a safety cap on the time whatever max_depth is: a job may ask
  /// for depth 64, and a tolerance round-off cannot meet then splits every region). Once reached,
  /// every region still to come is a leaf (up to 3 per level of the current branch), counted in
  /// capped_leaves when above its tolerance. The default, the nodes of a full quadtree of depth 6
  /// (1 + 4 + … + 4⁶), never binds at the default max_depth.
  int max_regions = 5461;
};

/// Vector-valued integral of some integrand over a uv rule, Σ_j w_j f(u_j, v_j); must accept
/// an empty rule (returning zeros of the right size).
using UvIntegral = std::function<Eigen::VectorXd(const QuadratureRule2&)>;

struct RefinedAreaRule {
  QuadratureRule2 rule;  ///< union of the leaves' degree-p (or boosted) rules
  RuleStatus status = RuleStatus::Ok;
  Eigen::VectorXd integral;    ///< `integral` summed over the leaves' degree-(p+1) rules
  double error_estimate = 0;   ///< Σ over leaves of ‖I_p − I_{p+1}‖∞ (absolute)
  double moment_residual = 0;  ///< largest leaf moment residual
  int leaves = 0;
  int boosted_leaves = 0;  ///< leaves that carry the degree-boosted rule
  /// Leaves kept at max_depth with their estimate above the tolerance (the depth cap was hit;
  /// status NotConverged unless a worse status hides it).
  int capped_leaves = 0;
  int regions = 0;  ///< regions examined (leaves and split ones)
  int depth = 0;  ///< deepest leaf
};
RefinedAreaRule refined_area_rule(const std::vector<UvLoop>& loops, const AreaRuleOptions& area,
                                  const RefinementOptions& refinement, const UvIntegral& integral);

/// Keeps the part of a closed loop inside the box [lo, hi] (Sutherland–Hodgman against each
/// side; parabolic segments are split exactly at their crossings, exits are joined to the
/// next entries by straight chords on the box side). Winding numbers inside the box are
/// unchanged, so Green's theorem on the result integrates over region ∩ box.
std::vector<UvLoop> clip_loops(const std::vector<UvLoop>& loops, const Vec2& lo, const Vec2& hi);

struct SurfaceRuleOptions {
  AreaRuleOptions area{5};  ///< thesis: degree 5 for surfaces
  /// Refinement on the patch area ∫‖σu × σv‖ du dv (tolerance relative to the area).
  RefinementOptions refinement{0, true, 6};
};

struct SurfaceRule {
  std::vector<Vec3> points;     ///< σ(u_j, v_j)
  std::vector<double> weights;  ///< w_j^uv ‖σu × σv‖: Σ w_j g(X_j) ≈ ∫_S g dS
  std::vector<Vec3> normals;    ///< unit normals, orientation · σu × σv (out of the subvolume)
  std::vector<Vec2> uv;         ///< the uv points
  RuleStatus status = RuleStatus::Ok;
  double area = 0;             ///< Σ weights
  double error_estimate = 0;   ///< area difference of degree p and p + 1 rules (absolute)
  double moment_residual = 0;  ///< largest uv moment residual of the leaves
  int leaves = 0;              ///< uv rules (1 without refinement)
};
/// Surface rule of a cut patch (Eq. 6.15). Throws parafab::Error for a missing surface,
/// orientation other than ±1, or malformed loops.
SurfaceRule surface_rule(const CutPatch& patch, const SurfaceRuleOptions& options = {});

}  // namespace parafab::xfem
