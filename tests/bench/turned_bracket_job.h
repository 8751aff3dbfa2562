// What the gradient-against-step benchmarks share (bench_compliance_gradient,
// bench_target_gradient): the L-bracket turned 11° off the grid axes (its cells are cut), the
// upright's back supported, 500 N down on the base end as a total force (spread over the face's
// area on every model), steel, a 10-cell face-route grid in blocks of 4.
#pragma once

#include <Eigen/Geometry>
#include <memory>
#include <string>

#include "face_lookup.h"
#include "optimize/projection.h"
#include "occt_mass_properties.h"
#include "part_reader.h"
#include "shape_compliance.h"
#include "shape_modify.h"
#include "shape_parameters.h"

namespace parafab::occ::bench {

struct TurnedBracketJob {
  std::shared_ptr<const PartShape> part;
  ComplianceSetup setup;
  /// A point of the untouched bracket (samples/parts/l_bracket.step) where it lies after the turn.
  Vec3 turned(const Vec3& X) const {
    const Vec3 centre(30, 20, 25), axis = Vec3(1, 2, 3).normalized();
    return centre + Eigen::AngleAxisd(11 * M_PI / 180, axis) * (X - centre);
  }
};

inline TurnedBracketJob turned_bracket_job(const std::string& samples) {
  TurnedBracketJob j;
  j.part = rotated_part(*read_part(samples + "/parts/l_bracket.step"), Vec3(30, 20, 25), Vec3(1, 2, 3).normalized(), 11);
  j.setup.material.youngs_modulus = 210000;
  j.setup.material.poisson_ratio = 0.3;
  xfem::DirichletCondition support;
  support.face = face_at_point(*j.part, j.turned({0, 20, 30}), 1e-6);
  j.setup.dirichlet.push_back(support);
  xfem::TractionCondition load;
  load.face = face_at_point(*j.part, j.turned({60, 20, 4}), 1e-6);
  const Vec3 force = j.turned(Vec3(0, 0, -500)) - j.turned(Vec3::Zero());
  load.traction = force / face_area(*j.part, load.face);
  j.setup.tractions.push_back(load);
  j.setup.forces.push_back(force);
  j.setup.grid.grid.cells_longest = 10;
  j.setup.grid.grid.block_cells = 4;
  j.setup.grid.grid.method = CutMethod::FaceCut;
  return j;
}

/// The part's design space as the benchmarks use it: the parameters of every face but the
/// support's and the load's, their own values projected onto the constraints, and the part's
/// size L (bounding-box diagonal).
struct DesignSpace {
  FaceModel model;
  ShapeParameters parameters;
  optimize::ProjectionResult start;
  double size = 0;
};

inline DesignSpace design_space(const PartShape& part, const ComplianceSetup& setup) {
  DesignSpace d;
  d.model = build_face_model(part);
  ShapeParameterOptions options;
  options.fixed_faces = {setup.dirichlet[0].face, setup.tractions[0].face};
  d.parameters = build_shape_parameters(d.model, options);
  const PartInfo info = part_info(part);
  d.size = (info.bbox_max - info.bbox_min).norm();
  const ShapeParameters& sp = d.parameters;
  d.start = optimize::project(sp.constraints, sp.initial, sp.initial, sp.lower, sp.upper);
  return d;
}

}  // namespace parafab::occ::bench
