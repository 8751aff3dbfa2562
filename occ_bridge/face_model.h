// The face model of a part: surface types with mid-level parameters (thesis §6.5.1), NURBS
// patches in projective coordinates with trimming loops (§6.2.1), edge adjacency/continuity,
// and the tangency relations between adjacent faces as equations (§6.5.1, Fig. 6.11).
#pragma once

#include <Eigen/Core>
#include <array>
#include <string>
#include <vector>

#include "nurbs_surface.h"
#include "part_reader.h"

namespace parafab::occ {

using Vec2 = Eigen::Vector2d;
using Vec3 = Eigen::Vector3d;

enum class SurfaceType {
  plane,
  cylinder,
  cone,
  sphere,
  torus,
  bspline,
  bezier,
  extrusion,
  revolution,
  offset,
  other
};

/// "plane", "cylinder", ...
const char* to_string(SurfaceType type);

/// Mid-level parameters of a face's surface (entries of p in §6.5.1), in world coordinates.
/// Symbols (used in the relation equations, suffixed with the face index):
///   plane p, n | cylinder c, d, r | cone c, d, r, a | sphere c, d, r | torus c, d, R, r |
///   revolution c, d | extrusion d.
struct Primitive {
  SurfaceType type = SurfaceType::other;
  /// c: point on the axis (cone: where the radius is `radius`; sphere, torus: centre), or p: a
  /// point of the plane (its parametric origin).
  Vec3 location = Vec3::Zero();
  /// d: unit axis (extrusion: direction), or n: the plane's unit normal σ_u × σ_v / |σ_u × σ_v|.
  Vec3 axis = Vec3::Zero();
  Vec3 x_direction = Vec3::Zero();  ///< direction of parameter u = 0 (plane: of σ_u)
  double radius = 0;                ///< r: cylinder, sphere; cone: at `location`; torus: minor radius
  double major_radius = 0;          ///< R: torus
  double semi_angle = 0;            ///< a: cone, radians (the radius grows along `axis` if > 0)
  double offset = 0;                ///< offset surface distance
};

/// A closed boundary loop of a face in the (u, v) parameters of its NURBS, as a polyline
/// (last point = first). Outer loops run counter-clockwise, holes clockwise.
struct TrimLoop {
  bool outer = false;
  std::vector<int> edges;  ///< edge indices in loop order
  std::vector<Vec2> uv;
};

struct FaceInfo {
  int index = -1;
  Primitive primitive;                ///< primitive.type is the surface type
  bool reversed = false;              ///< the outward normal is −σ_u × σ_v (else +σ_u × σ_v)
  std::array<double, 4> uv_bounds{};  ///< u_min, u_max, v_min, v_max (= the NURBS's knot range)
  double area = 0;
  NurbsSurface nurbs;           ///< the face's surface restricted to uv_bounds, exact (rational) form
  /// B-spline faces on a non-periodic surface: the B-rep's own surface, unsegmented, in world
  /// coordinates; its poles are shape parameters ("pole i j x", §6.5.1). count_u == 0 otherwise.
  NurbsSurface bspline;
  std::vector<TrimLoop> loops;  ///< outer loop first
};

struct EdgeInfo {
  int index = -1;
  /// The faces sharing the edge, lower index first (seam: twice the same; degenerated: [f, −1]).
  std::array<int, 2> faces{-1, -1};
  bool seam = false, degenerated = false;
  std::string continuity;    ///< as stored in the B-rep (BRep_Tool::Continuity): "C0", "G1", "C1", ...
  double max_angle_deg = 0;  ///< largest angle between the faces' outward normals at the edge samples
  bool tangent = false;      ///< G1: max angle below FaceModelOptions::tangent_angle
};

/// A tangency between two adjacent faces, as equations in their parameters (cpara, Eq. 6.2).
/// Every equation is scalar; `residuals[k]` is the value of the left side of `equations[k]`.
struct TangencyRelation {
  /// "plane-plane", "plane-cylinder", "plane-cone", "plane-sphere", "plane-torus",
  /// "cylinder-cylinder", "cylinder-sphere", "cylinder-torus", "cylinder-torus-pipe",
  /// "sphere-torus", "g1" (normals parallel at edge samples, on the NURBS poles), or
  /// "coaxial": not a tangency but the design intent of two faces of revolution (cylinder, cone,
  /// torus; b may be a sphere) meeting along sharp edges on one axis, e.g. a countersink and its
  /// hole: b's axis parallel to a's and b's centre on a's axis.
  std::string kind;
  std::array<int, 2> faces{-1, -1};  ///< face a has the first type in `kind` ("coaxial": a has an axis)
  std::vector<int> edges;            ///< the shared tangent edges ("coaxial": the shared sharp edges)
  int sign = 1;  ///< ±1 fixed at detection: which side (convex/concave fillet, inner/outer)
  /// "g1" only: the (u, v) of each edge sample on face a and on face b.
  std::vector<std::array<Vec2, 2>> samples;
  std::vector<std::string> equations;
  std::vector<double> residuals;
};

/// Re-evaluates the residuals of `relation` for (possibly changed) face data: the primitives
/// of a and b, or for "g1" their NURBS. Same order as relation.equations. Vectors are used as
/// given (no normalization).
std::vector<double> tangency_residuals(const TangencyRelation& relation, const FaceInfo& a,
                                       const FaceInfo& b);

struct FaceModelOptions {
  int edge_samples = 9;            ///< interior points per edge for normal angles and "g1" relations
  double tangent_angle = 1e-3;     ///< radians: an edge is tangent (G1) below this
  int loop_samples_per_edge = 16;  ///< polyline segments per curved edge in trimming loops
  /// A table relation is accepted when all residuals are below this times max(1, part size);
  /// otherwise the pair gets a "g1" relation.
  double relation_tolerance = 1e-6;
};

struct FaceModel {
  std::vector<FaceInfo> faces;  ///< faces[i].index == i
  std::vector<EdgeInfo> edges;  ///< edges[i].index == i
  std::vector<TangencyRelation> relations;
};

/// Builds the face model. Throws parafab::Error (naming the face) if a face cannot be
/// converted to NURBS.
FaceModel build_face_model(const PartShape& part, const FaceModelOptions& options = {});

}  // namespace parafab::occ
