// Volume rules (thesis §6.3.3, Eq. 6.16): moment fitting on the subvolume's bounding box
// mapped to the unit cube, moments from the divergence theorem over the boundary patches,
// whose flux integrals use the patches' uv area rules (the second nesting of §6.3).
#pragma once

#include "xfem/area_rules.h"
#include "xfem/cut_geometry.h"
#include "xfem/moment_fitting.h"
#include "xfem/quadrature_rule.h"

namespace parafab::xfem {

enum class FittingBox {
  Tight,  ///< bounding box of the images of loop points and patch rule points, ∩ cell
  Cell    ///< the grid cell (relative accuracy degrades as the volume fraction shrinks)
};

struct VolumeRuleOptions {
  int degree = 4;                ///< basis ξ^a η^b ζ^c with a + b + c ≤ degree (35 functions)
  int points_per_direction = 5;  ///< tensor Gauss points in the unit cube (≥ degree + 1, or cap + 1)
  /// With a cap ≥ 0 also a, b, c ≤ max_exponent: degree 10 capped at 4 integrates the
  /// triquadratic stiffness exactly on 5³ points (−1: no cap).
  int max_exponent = -1;
  FittingBox box = FittingBox::Tight;
  WeightFit fit = WeightFit::MinimalNorm;
  double residual_tolerance = 1e-10;  ///< status ResidualAboveTolerance beyond (NNLS)
  AreaRuleOptions patch{5};           ///< uv rules of the patches (thesis: degree 5)
  /// Flux refinement per patch (see refined_area_rule): absolute tolerance on the basis
  /// moments over the unit cube, i.e. roughly relative to the fitting-box volume; 0: off.
  double flux_tolerance = 1e-10;
  int max_depth = 6;
  /// Degree raise tried on a patch region before it is split (RefinementOptions::degree_boost).
  int flux_degree_boost = 6;
};

struct VolumeRule {
  QuadratureRule3 rule;  ///< physical points (tensor Gauss points of the box) and weights
  RuleStatus status = RuleStatus::Ok;
  double volume = 0;           ///< fitted ∫_V 1 (signed; < 0 for reversed orientations)
  Box3 box;                    ///< the fitting box
  double moment_residual = 0;  ///< ‖A w − b‖∞ over the unit cube
  /// Σ_patches of the refinement estimates (unit-cube moments): the error of degree-p patch
  /// rules; the moments use the degree-(p+1) values and are usually far more accurate.
  double flux_error_estimate = 0;
  /// ‖∮ dA‖∞ of the boundary mapped to the unit cube: ~0 for a closed, consistently oriented
  /// boundary; of order (gap area)/(box face area) otherwise.
  double closure_defect = 0;
  int flux_leaves = 0;  ///< uv rules used for the flux integrals (patches × refinement)
  int flux_depth = 0;   ///< deepest refinement level
  /// Patch leaves the refinement left at max_depth above flux_tolerance (the depth cap was hit).
  int flux_capped_leaves = 0;
};

/// Σ_j w_j g(X_j) ≈ ∫_V g dV; exact (to the moments' accuracy) for polynomials of total
/// degree ≤ `degree` (each exponent ≤ `max_exponent` when capped). Points lie in the fitting box, not necessarily inside V.
/// Throws parafab::Error for an empty or inverted cell, no patches, or malformed patches.
VolumeRule volume_rule(const Subvolume& subvolume, const VolumeRuleOptions& options = {});

}  // namespace parafab::xfem
