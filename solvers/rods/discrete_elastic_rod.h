// Forward simulation of designed Kirchhoff rods (validation as in thesis §5.7.4, Fig. 5.15,
// and §5.9): the discrete elastic rod model of Bergou et al. 2008 (centreline nodes, one material-frame angle per edge relative to a reference frame
// that is parallel transported in time, anisotropic bending E·I per edge, twist μ·J,
// stiff stretching E·A), clamped positions and frames at both ends, dead load and nodal point
// loads. Static equilibrium by Newton's method with exact gradient and Hessian (second-order
// forward differentiation of each stencil), sparse LDLᵀ with diagonal shift when the Hessian
// is indefinite, and backtracking line search. Used to verify designs of thesis §5.7–5.8.
#pragma once

#include <Eigen/Core>
#include <string>
#include <utility>
#include <vector>

#include "rods/space_curve.h"

namespace parafab {

/// A straight rod (zero natural curvature and twist), given in its initial deformed state.
/// Edge j joins nodes j and j+1. Ends clamped: nodes 0, 1, N−1, N and the material angles
/// of the first and last edge keep their initial values.
struct DiscreteRodModel {
  std::vector<Vec3> nodes;                        ///< N+1 ≥ 4 initial positions [m]
  std::vector<Vec3> material_normal;              ///< N: d1 of each edge (⊥ edge, unit)
  std::vector<Eigen::Matrix2d> bending_stiffness; ///< N: E·I in (d1, d2) coordinates [N·m²]
  std::vector<double> twisting_stiffness;         ///< N: μ·J [N·m²]
  std::vector<double> stretching_stiffness;       ///< N: E·A [N]
  std::vector<double> rest_length;                ///< N: undeformed edge lengths [m]
  std::vector<double> line_density;               ///< N: ρ·A [kg/m] (dead load)
  Vec3 gravity{0, 0, 0};                          ///< [m/s²]
  std::vector<std::pair<int, Vec3>> nodal_forces; ///< (node, force [N])
};

struct DiscreteRodOptions {
  int max_iterations = 100;
  /// Converged when max |∂E/∂q| over free DOFs ≤ tolerance · force scale, where the force
  /// scale is max ‖E·I‖ / L² + total weight + Σ|nodal forces| (forces and moments alike),
  /// or when the gradient is within 1e3× that and the Newton step is at round-off level
  /// (< 1e-13·L in positions and 1e-13 rad in angles).
  double gradient_tolerance = 1e-8;
};

enum class DiscreteRodStatus { Converged, NotConverged };

struct DiscreteRodResult {
  DiscreteRodStatus status = DiscreteRodStatus::NotConverged;
  std::vector<Vec3> nodes;            ///< equilibrium positions
  std::vector<Vec3> material_normal;  ///< equilibrium d1 per edge
  std::vector<double> theta;          ///< material angles relative to the final reference
  double energy = 0;                  ///< total potential energy [J]
  double gradient_norm = 0;           ///< max |∂E/∂q| (free DOFs), relative to the force scale
  int iterations = 0;
  int hessian_shifts = 0;             ///< Newton steps that needed a diagonal shift
  double seconds = 0;
  std::string message;
  bool ok() const { return status == DiscreteRodStatus::Converged; }
};

/// Throws parafab::Error for inconsistent sizes or non-positive stiffness/lengths.
DiscreteRodResult simulate_discrete_rod(const DiscreteRodModel& model,
                                        const DiscreteRodOptions& options = {});

/// Energy, gradient and (dense) Hessian over all DOFs q = (x₀..x_N, θ₀..θ_{N−1}) at the
/// initial state perturbed by dq (reference frames = the initial material frames). For tests.
double discrete_rod_energy(const DiscreteRodModel& model, const Eigen::VectorXd& dq,
                           Eigen::VectorXd* gradient = nullptr,
                           Eigen::MatrixXd* hessian = nullptr);

/// max over nodes of the distance to the target polyline nodes (same count) [m].
double max_node_distance(const std::vector<Vec3>& a, const std::vector<Vec3>& b);

}  // namespace parafab
