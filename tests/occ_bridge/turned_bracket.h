// What the shape-derivative checks of the compliance and failure objectives share: the
// L-bracket turned 11° off the grid axes (its cells are cut), its elasticity job, and a design
// entry moved the way the optimizer moves it (projection, then B-rep write-back), with the
// Richardson-extrapolated central difference that serves as the independent reference.
#pragma once

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "face_lookup.h"
#include "occt_mass_properties.h"
#include "optimize/projection.h"
#include "part_reader.h"
#include "shape_compliance.h"
#include "shape_failure.h"
#include "shape_modify.h"
#include "shape_parameters.h"

namespace parafab::occ::testing {

inline std::string sample_part(const std::string& name) {
  return std::string(PARAFAB_SAMPLES_DIR) + "/parts/" + name + ".step";
}

inline const Vec3 kBracketCenter(30, 20, 25);
inline const Vec3 kBracketAxis = Vec3(1, 2, 3).normalized();
constexpr double kBracketDegrees = 11;
inline Vec3 turned(const Vec3& X) {
  return kBracketCenter + Eigen::AngleAxisd(kBracketDegrees * M_PI / 180, kBracketAxis) * (X - kBracketCenter);
}

/// Steel in N/mm/MPa on `part`: face `support` clamped, face `load` pulled by the total force
/// `force` (spread over the face's area on every model, so the load term of the derivatives is
/// exercised when that area changes), a 10-cell face-route grid in blocks of 4 (the Boolean
/// splitter lost cell pieces of perturbed models whose planes move; compliance_at refuses such
/// models).
inline ComplianceSetup steel_cantilever(const PartShape& part, int support, int load, const Vec3& force) {
  ComplianceSetup setup;
  setup.material.youngs_modulus = 210000;
  setup.material.poisson_ratio = 0.3;
  xfem::DirichletCondition d;
  d.face = support;
  setup.dirichlet.push_back(d);
  xfem::TractionCondition t;
  t.face = load;
  t.traction = force / face_area(part, load);
  setup.tractions.push_back(t);
  setup.forces.push_back(force);
  setup.grid.grid.cells_longest = 10;
  setup.grid.grid.block_cells = 4;
  setup.grid.grid.method = CutMethod::FaceCut;
  return setup;
}

/// The turned bracket: back of the upright (x = 0) supported, the free end of the base (x = 60)
/// pulled down by 500 N given as a total force (samples/simulations/l_bracket.json), steel in
/// N/mm/MPa, a 10-cell face-route grid.
struct TurnedBracket {
  std::shared_ptr<const PartShape> part;
  ComplianceSetup setup;
  int hole = -1, base_top = -1, upright_inner = -1, fillet = -1, outer = -1;  // face indices
  TurnedBracket() {
    part = rotated_part(*read_part(sample_part("l_bracket")), kBracketCenter, kBracketAxis, kBracketDegrees);
    const double tol = 1e-6;
    const int support = face_at_point(*part, turned({0, 20, 30}), tol);
    const int load = face_at_point(*part, turned({60, 20, 4}), tol);
    hole = face_at_point(*part, turned({44, 12, 4}), tol);
    base_top = face_at_point(*part, turned({30, 20, 8}), tol);
    upright_inner = face_at_point(*part, turned({8, 20, 30}), tol);
    outer = face_at_point(*part, turned({12 - 12 * std::sqrt(0.5), 20, 12 - 12 * std::sqrt(0.5)}), tol);
    fillet = face_at_point(*part, turned({8 + 5 - 5 * std::sqrt(0.5), 20, 8 + 5 - 5 * std::sqrt(0.5)}), tol);
    // The load face's area changes when the base top plane moves.
    setup = steel_cantilever(*part, support, load, turned(Vec3(0, 0, -500)) - turned(Vec3::Zero()));
  }
};

/// The parameters of a part (faces `fixed` kept), its own values projected onto the constraints,
/// and its size L (bounding-box diagonal).
struct DesignSpace {
  FaceModel model;
  ShapeParameters parameters;
  optimize::ProjectionResult start;
  double size = 0;
  DesignSpace(const PartShape& part, const std::vector<int>& fixed) : model(build_face_model(part)) {
    ShapeParameterOptions options;
    options.fixed_faces = fixed;
    parameters = build_shape_parameters(model, options);
    start = optimize::project(parameters.constraints, parameters.initial, parameters.initial, parameters.lower,
                              parameters.upper);
    EXPECT_TRUE(start.done) << start.message;
    const PartInfo info = part_info(part);
    size = (info.bbox_max - info.bbox_min).norm();
  }
};

/// Design entry `index` of `parameters` moved by s from `base` through the projection (weights
/// of a one-entry design, followers 1e-4) and written into `part`, as the optimizer does.
struct DesignLine {
  const PartShape& part;
  const FaceModel& model;
  const ShapeParameters& parameters;
  int index;
  Eigen::VectorXd base;
  optimize::ProjectionOptions options;

  DesignLine(const PartShape& part_, const FaceModel& model_, const ShapeParameters& parameters_, int index_,
             const Eigen::VectorXd& base_, double part_size)
      : part(part_), model(model_), parameters(parameters_), index(index_), base(base_) {
    options.weights = projection_weights(parameters, {index}, 1e-4, part_size);
  }
  std::shared_ptr<const PartShape> at(double s) const {
    Eigen::VectorXd t = base;
    t[index] += s;
    const optimize::ProjectionResult p =
        optimize::project(parameters.constraints, t, base, parameters.lower, parameters.upper, {}, options);
    EXPECT_TRUE(p.done) << parameters.names[index] << " s = " << s;
    const ModifyResult m = modify_part(part, model, parameters, p.p);
    EXPECT_TRUE(m.done) << parameters.names[index] << " s = " << s << ": " << m.message;
    return m.part;
  }
};

// Design entry `index` as the optimizer moves it: the start projected with a one-entry design's
// weights (p0), the line through p0 along the entry, and the entry's column of dp⊥/dp̃ at p0.
struct ProjectedEntry {
  optimize::ProjectionResult p0;
  std::optional<DesignLine> line;
  Eigen::VectorXd column;
  ProjectedEntry(const PartShape& part, const FaceModel& model, const ShapeParameters& sp, const Eigen::VectorXd& start,
                 int index, double L) {
    optimize::ProjectionOptions popt;
    popt.weights = projection_weights(sp, {index}, 1e-4, L);
    p0 = optimize::project(sp.constraints, start, start, sp.lower, sp.upper, {}, popt);
    EXPECT_TRUE(p0.done) << p0.message;
    line.emplace(part, model, sp, index, p0.p, L);
    column = optimize::projection_derivative(sp.constraints, p0, sp.lower, sp.upper, popt.weights).jacobian.col(index);
  }
  std::shared_ptr<const PartShape> part_at(double s) const { return line->at(s); }
};

/// One design entry checked against the pipeline's differences: what it is, its index in p and
/// the relative tolerance (near the measured difference).
struct EntryCase {
  const char* what;
  int index;
  double tolerance;
};

/// C of a perturbed model re-cut on the grid of `at` and solved (NaN, and a failure, if not):
/// the function the Richardson differences below are taken of.
inline double compliance_on(std::shared_ptr<const PartShape> part, const ComplianceState& at, const ComplianceSetup& setup) {
  const ComplianceState s = compliance_at(std::move(part), at, setup);
  EXPECT_TRUE(s.done) << s.message;
  return s.done ? s.compliance : std::nan("");
}

/// The failure metric J of a perturbed model re-cut on the grid of `at` and solved, its switches
/// and frames frozen at `at` as a line search holds them (NaN, and a failure, if not solved).
inline double failure_on(std::shared_ptr<const PartShape> part, const ComplianceState& at, const ComplianceSetup& setup,
                         const FailureOptions& options) {
  const ComplianceState s = compliance_at(std::move(part), at, setup, at.model.get());
  EXPECT_TRUE(s.done) << s.message;
  return s.done ? failure_value(s, setup, options).objective : std::nan("");
}

/// Richardson extrapolation (4 D(H/2) − D(H)) / 3 of the central differences D(h) =
/// (value(h) − value(−h)) / 2h; `coarse` receives D(H).
inline double richardson(const std::function<double(double)>& value, double H, double* coarse = nullptr) {
  double d[2];
  for (int level = 0; level < 2; ++level) {
    const double h = level ? H / 2 : H;
    d[level] = (value(h) - value(-h)) / (2 * h);
  }
  if (coarse) *coarse = d[0];
  return (4 * d[1] - d[0]) / 3;
}

}  // namespace parafab::occ::testing
