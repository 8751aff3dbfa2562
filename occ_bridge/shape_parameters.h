// Shape parameters of a part (thesis §6.5.1): the mid-level parameters p of its analytic faces
// from the face model, named ("face 7 cylinder radius"), the tangency relations as constraints
// c_para(p) = 0 in a reduced independent form, unit axes, and user constraints (fixed faces,
// ties into one design variable, mirror and rotational symmetry, bounds). The math lives in
// solvers/optimize/shape_constraints.h; this file maps the face model onto it.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "face_model.h"
#include "optimize/shape_constraints.h"

namespace parafab::occ {

struct ParameterRef {
  int face = -1;
  std::string parameter;  ///< a block parameter name: "radius", "offset", "normal x", ...
};

struct ShapeParameterOptions {
  std::vector<int> fixed_faces;                   ///< faces that keep their surface (supported, loaded)
  std::vector<std::vector<ParameterRef>> ties;    ///< each list: parameters kept equal
  struct Mirror {
    int face_a = -1, face_b = -1;
    Vec3 normal = Vec3::UnitX();  ///< mirror plane normal·X = offset
    double offset = 0;
  };
  std::vector<Mirror> mirrors;
  /// Rotational symmetry of a pattern: faces[k + 1] is faces[k] turned by `degrees` about the
  /// axis through `point` along `axis` (bolt holes on a circle, spokes of a wheel). Like a
  /// mirror, it must hold at the start (the part as read).
  struct Rotation {
    std::vector<int> faces;
    Vec3 point = Vec3::Zero();
    Vec3 axis = Vec3::UnitZ();
    double degrees = 0;
  };
  std::vector<Rotation> rotations;
  /// Draft (thesis §6.6, motor housing: "normals orthogonal to the symmetry axis stay
  /// orthogonal"): plane face `face` keeps its normal orthogonal to `axis`, n·a = 0 (a wall
  /// parallel to the pull direction stays so); a cylinder keeps its axis parallel to `axis` (all
  /// its normals orthogonal to it), a cone too (its normals keep the draft angle). The part must
  /// satisfy it at the start (|n·a|, |v × a| ≤ 1e-9).
  struct Orthogonal {
    int face = -1;
    Vec3 axis = Vec3::UnitZ();
  };
  std::vector<Orthogonal> orthogonal;
  double min_radius = 1e-3;  ///< lower bound of every radius (units of the part)
};

/// The poles of a B-spline face as entries of p (§6.5.1: "B-spline poles for free-form faces"):
/// pole (i, j), i = 1..count_u along u, j = 1..count_v along v (OCCT's and FreeCAD's numbering),
/// coordinate c = 0, 1, 2 (x, y, z, world) at offset + 3 ((i − 1) count_v + j − 1) + c; weights
/// and knots stay. q(p) is then p itself, so its Jacobian is the identity.
struct PoleBlock {
  int face = -1;
  int offset = 0;
  NurbsSurface surface;  ///< the surface as read (knots and weights stay; its poles are p0's)
  int count_u() const { return surface.distinct_u(); }  ///< free poles (a periodic direction's distinct ones)
  int count_v() const { return surface.distinct_v(); }
  int size() const { return 3 * count_u() * count_v(); }
  int entry(int i, int j, int c) const { return offset + 3 * ((i - 1) * count_v() + j - 1) + c; }
};

struct ShapeParameters {
  std::vector<optimize::ParameterBlock> blocks;  ///< one per analytic face
  std::vector<int> block_of_face;                ///< per face: index into blocks, or −1
  /// One per B-spline face (periodic ones by their distinct poles), after all analytic blocks in p. A face
  /// tangent (G1) to another keeps its poles fixed, as its neighbours keep theirs.
  std::vector<PoleBlock> pole_blocks;
  std::vector<int> pole_block_of_face;           ///< per face: index into pole_blocks, or −1
  std::vector<std::string> names;                ///< per entry of p: "face 7 cylinder radius"
  Eigen::VectorXd initial, lower, upper;         ///< p of the part as read; bounds (fixed: equal)
  optimize::ConstraintSystem constraints;
  std::vector<int> fixed_faces;                  ///< fixed by the options or by a relation with a free-form face
  std::vector<std::string> notes;                ///< what was not expressible and what was done about it
  int relation_equations = 0;                    ///< tangency and coaxial equations in `constraints`
  /// Rows of `constraints` from here on are the user's (ties, mirrors, rotations, orthogonal);
  /// the rows before (unit axes, tangencies) make the B-rep valid. When no p satisfies all,
  /// the user rows give way (optimize_shape's nearest valid model).
  int first_user_constraint = 0;

  int size() const { return static_cast<int>(initial.size()); }
  const optimize::ParameterBlock* block(int face) const {
    return face >= 0 && face < static_cast<int>(block_of_face.size()) && block_of_face[face] >= 0
               ? &blocks[block_of_face[face]]
               : nullptr;
  }
  const PoleBlock* poles(int face) const {
    return face >= 0 && face < static_cast<int>(pole_block_of_face.size()) && pole_block_of_face[face] >= 0
               ? &pole_blocks[pole_block_of_face[face]]
               : nullptr;
  }
};

/// Builds p, its names, bounds and c_para from the face model. Throws parafab::Error naming
/// the face for a fixed/tied/mirrored/rotated face that does not exist or has no such parameter,
/// and for a mirror or rotation the part as read does not satisfy.
ShapeParameters build_shape_parameters(const FaceModel& model, const ShapeParameterOptions& options = {});

/// Index in p of (face, parameter name): a block parameter, or "pole i j x|y|z" on a B-spline
/// face; throws parafab::Error listing the face's parameters.
int parameter_index(const ShapeParameters& parameters, int face, const std::string& parameter);

/// Weights of the projection distance ½ Σ w_i (p_i − p̃_i)²: lengths (offsets, points, radii)
/// 1 for design entries and `follower` for the others; dimensionless entries (normals, axes,
/// half-angles) length² always (a unit tilt costs like a move of `length`, the part's size), so
/// that a moved plane drags its tangent fillet along by translation instead of tilting.
Eigen::VectorXd projection_weights(const ShapeParameters& parameters, const std::vector<int>& design,
                                   double follower, double length);

/// The primitive of a face for the block values `p` (location, axis, radii; plane location =
/// the foot of the origin's perpendicular... precisely d·n/|n|²; x_direction from `like`).
Primitive primitive_of_block(const optimize::ParameterBlock& block, const Eigen::VectorXd& p, const Primitive& like);

/// max |residual| of the face model's tangency relations re-evaluated at p (faces of `model`
/// with their primitives replaced by those of p); "g1" relations are skipped.
double tangency_residual_max(const FaceModel& model, const ShapeParameters& parameters, const Eigen::VectorXd& p);

}  // namespace parafab::occ
