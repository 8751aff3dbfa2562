// Plane sections of a surface or solid as input curves for bending-active strips (thesis
// §4.8.2, Fig. 4.18): a family of parallel planes cuts the shape (OCCT's BRepAlgoAPI_Section),
// the section edges are chained into curves, optionally split where they cross a second
// plane (the "spine"), and every curve is sampled by arc length in its plane's 2D frame.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <string>
#include <vector>

namespace parafab::occ {

struct PartShape;

struct PlaneSectionOptions {
  Eigen::Vector3d normal{1, 0, 0};  ///< normal of the plane family
  /// Plane positions ⟨normal, X⟩ = offset (model units). Empty: `count` planes spread evenly
  /// over the shape's extent along the normal (ends excluded).
  std::vector<double> offsets;
  int count = 5;
  /// Split every section where it crosses the plane ⟨split_normal, X⟩ = split_offset.
  bool split = false;
  Eigen::Vector3d split_normal{0, 0, 1};
  double split_offset = 0;
  int samples = 60;            ///< points per curve, equally spaced in arc length
  double min_length = 0;       ///< drop pieces shorter than this (model units); 0: 1e-3 of the diagonal
};

struct SectionCurve {
  int plane = 0;               ///< index into `offsets`
  double offset = 0;
  int piece = 0;               ///< several curves per plane: separate loops or split pieces
  bool closed = false;
  double length = 0;
  Eigen::Vector3d origin{0, 0, 0}, u_axis{0, 0, 0}, v_axis{0, 0, 0};  ///< X = origin + x u + y v
  std::vector<Eigen::Vector3d> points;  ///< 3D samples
  std::vector<Eigen::Vector2d> points2d;  ///< the same in the plane frame
};

struct PlaneSectionResult {
  bool done = false;
  std::string message;
  std::vector<double> offsets;   ///< the planes used
  std::vector<SectionCurve> curves;
  std::vector<int> empty_planes; ///< planes that miss the shape
};

/// Never throws for planes that miss the shape (listed in empty_planes); throws
/// parafab::Error for invalid options (zero normal, fewer than 4 samples).
PlaneSectionResult plane_sections(const PartShape& shape, const PlaneSectionOptions& options = {});

}  // namespace parafab::occ
