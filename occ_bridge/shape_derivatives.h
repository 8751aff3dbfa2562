// Exact shape derivatives of mass properties (thesis §6.2.3 Eq. 6.5: ∫_V g(X) dV with
// g ∈ {1, X, Y, Z, XY, ...}) by the Hadamard boundary formula
//   d/dp ∫_Ω g dV = ∫_∂Ω g (∂X/∂p · n) dA,
// the normal boundary velocity of each analytic face from its implicit function φ(X; p):
// ∂X/∂p · n = −s ∂φ/∂p / |∇φ| (s = ±1: ∇φ along or against the outward normal). The boundary
// integrals use Gauss rules over the trimmed faces by Green's theorem on their pcurves (no cut,
// no mesh): ∫∫ h du dv = ∮ (∫_{u0}^{u} h(s, v) ds) dv.
#pragma once

#include <Eigen/Core>

#include "shape_parameters.h"

namespace parafab::occ {

struct PartShape;

struct BoundaryQuadratureOptions {
  int edge_segments = 4;   ///< Gauss segments per edge pcurve
  int edge_points = 12;    ///< Gauss points per segment
  int inner_points = 24;   ///< Gauss points of the inner integral in u
};

/// The ten volume moments ∫ g dV, g = 1, X, Y, Z, XX, YY, ZZ, XY, YZ, XZ (in this order).
using Moments = Eigen::Matrix<double, 10, 1>;

struct MomentDerivatives {
  Moments moments = Moments::Zero();  ///< by the divergence theorem on the same boundary rule
  Eigen::MatrixXd gradient;           ///< 10 × p: d moment / d p (zero columns for fixed-shape entries)
  int points = 0;                     ///< boundary quadrature points
  double seconds = 0;
};

/// Moments of `part` and their derivatives with respect to p, where `parameters` describes the
/// part's faces (same face indices) and p is the parameter vector of this part's geometry.
MomentDerivatives moment_derivatives(const PartShape& part, const ShapeParameters& parameters,
                                     const Eigen::VectorXd& p, const BoundaryQuadratureOptions& options = {});

/// The moments of OCCT's mass properties (BRepGProp at `eps`), same order: the reference.
Moments occt_moments(const PartShape& part, double eps = 1e-12);

}  // namespace parafab::occ
