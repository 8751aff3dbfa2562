#include "request_schema.h"

#include <algorithm>
#include <cctype>
#include <climits>
#include <cmath>
#include <functional>
#include <map>
#include <sstream>

#include "common/error.h"

namespace parafab::entry::schema {

using nlohmann::json;

namespace {

NodePtr leaf(const char* type) {
  auto n = std::make_shared<Node>();
  n->type = type;
  return n;
}
NodePtr integer(long long min, long long max) {
  auto n = std::make_shared<Node>();
  n->type = "integer";
  n->min = min, n->max = max;
  return n;
}
NodePtr object(std::vector<Field> fields, const char* type = "object") {
  auto n = std::make_shared<Node>();
  n->kind = Node::Kind::Object;
  n->type = type;
  n->fields = std::move(fields);
  return n;
}
NodePtr array(NodePtr item, const char* type = "array") {
  auto n = std::make_shared<Node>();
  n->kind = Node::Kind::Array;
  n->type = type;
  n->item = std::move(item);
  return n;
}
/// The keys of `base` and more (the strip request under strip-improve).
NodePtr extended(const NodePtr& base, const char* base_name, std::vector<Field> more) {
  auto n = std::make_shared<Node>();
  n->kind = Node::Kind::Object;
  n->type = base->type;
  n->base = base, n->base_name = base_name;
  n->fields = std::move(more);
  return n;
}

const Field* find_field(const Node& n, const std::string& key) {
  for (const Field& f : n.fields)
    if (f.name == key) return &f;
  return n.base ? find_field(*n.base, key) : nullptr;
}

void field_names(const Node& n, std::vector<std::string>& out) {
  for (const Field& f : n.fields) out.push_back(f.name);
  if (n.base) field_names(*n.base, out);
}

const NodePtr kNumber = leaf("number");
const NodePtr kBool = leaf("boolean");
const NodePtr kString = leaf("string");
const NodePtr kVec3 = leaf("[x, y, z]");
const NodePtr kVec2 = leaf("[x, y]");
const NodePtr kNumbers = leaf("[number, ...]");
const NodePtr kAny = leaf("any");
constexpr long long kIntMax = INT_MAX;

Field note() { return {"note", kAny, "Free text for the reader of the file; ignored."}; }

// A face of the part: by index (`parafab inspect` lists them) or by a point on it.
std::vector<Field> face_ref(const char* what) {
  return {{"face", integer(0, kIntMax), std::string("The ") + what + " face's index (`parafab inspect`)."},
          {"point", kVec3, std::string("A point on the ") + what + " face, instead of its index (mm)."}};
}

std::vector<Field> with(std::vector<Field> a, std::vector<Field> b) {
  for (auto& f : b) a.push_back(std::move(f));
  return a;
}

// ---- strips (thesis ch. 4)
NodePtr plane_bspline() {
  return object({{"degree", integer(1, 30), "Degree p."},
                 {"knots", kNumbers, "Knot vector (n + p + 1 values)."},
                 {"poles", leaf("[[x, y], ...]"), "Control points (m)."},
                 {"weights", kNumbers, "Rational weights, one per pole (default: all 1)."}});
}

NodePtr strip_curve() {
  return object({{"bspline", plane_bspline(), "The curve as a B-spline."},
                 {"points", leaf("[[x, y], ...]"), "Points the curve interpolates (m), instead of bspline."},
                 {"degree", integer(1, 7), "Degree of the interpolant through points (default 4: K stays continuous)."}});
}

NodePtr strip_gravity() {
  return object(
      {{"direction", kVec2, "Direction of gravity in the curve's plane (default [0, -1])."},
       {"beta_l3", kNumber, "Weight parameter beta * L^3 (m^3), Eq. 4.6; or give density."},
       {"density", kNumber, "Density (kg/m^3), with E and thickness from the material (default: material.density)."},
       {"g", kNumber, "Gravitational acceleration (m/s^2, default 9.81); with density only."}},
      "object, or false / null (no gravity)");
}

NodePtr make_strip_request();
const NodePtr& strip_request_base() {
  static const NodePtr n = make_strip_request();
  return n;
}

NodePtr make_strip_request() {
  const NodePtr end = object({{"free_x", kBool, "The end slides along x."},
                              {"free_y", kBool, "The end slides along y."},
                              {"free_angle", kBool, "The end turns freely (a pin, not a clamp)."}});
  const NodePtr law = object({{"cubic", kNumber, "Cubic coefficient of the moment law m(kappa)."},
                              {"table_curvature", kNumbers, "Curvatures |kappa| of a tabulated law (with table_moment)."},
                              {"table_moment", kNumbers, "Moments of the tabulated law."},
                              {"curvature_limit", kNumber, "Elastic limit curvature; beyond it the law is plastic."},
                              {"hardening", kNumber, "Plastic slope beyond curvature_limit (>= 0)."}});
  return object(
      {{"curve", strip_curve(), "The plane curve the clamped strip must bend into (required)."},
       {"material",
        object({{"E", kNumber, "Young's modulus (Pa, required)."},
                {"thickness", kNumber, "Thickness h (m, required)."},
                {"density", kNumber, "Density (kg/m^3): the weight under gravity."},
                {"law", law, "A nonlinear or plastic moment law (§4.6.1); default linear."},
                {"yield_strain", kNumber, "Strain limit: the design reports where it is exceeded."},
                {"yield_stress", kNumber, "Stress limit (Pa), instead of yield_strain."},
                {"name", kString, "Material name, carried to the result."}}),
        "The strip's material (required)."},
       {"min_width", kNumber, "Narrowest width the strip may have (m, required)."},
       {"gravity", strip_gravity(), "Design under self-weight (Eq. 4.6 with smoothing)."},
       {"boundary", object({{"start", end, "The start's end conditions."}, {"end", end, "The end's end conditions."}}),
        "End conditions other than clamped."},
       {"natural_curvature", kNumber, "Rest curvature of the straight strip (1/m)."},
       {"smooth", kBool, "Smooth K(s) (default true under gravity)."},
       {"samples", integer(4, 1 << 20), "A fixed sample count (default: from tolerance)."},
       {"tolerance", kNumber, "Accuracy target of the sampling (relative)."},
       {"max_samples", integer(4, 1 << 22), "Upper bound of the adaptive sample count."},
       {"validate",
        object({{"edges", integer(4, 100000), "Edges of the forward rod simulation."},
                {"gravity", strip_gravity(), "Simulate under this gravity instead of the design's."}},
               "true / false or object"),
        "Simulate the design forward and report its deviation."},
       {"robustness",
        object({{"stiffness_change", kNumber, "Relative stiffness error studied, in (0, 1)."},
                {"gravity_change", kNumber, "Relative weight error studied, in (0, 1)."},
                {"angle_deg", kNumber, "End-angle error studied (degrees, in (0, 90))."},
                {"plastic_fractions", kNumbers, "Plastic fractions studied, each in (0, 1)."},
                {"plastic_hardening", kNumber, "Hardening of the plastic study (> 0)."},
                {"edges", integer(4, 100000), "Edges of the simulations."}},
               "true / false or object"),
        "Robustness study of the design (§4.7)."},
       {"composite",
        object({{"h1", kNumber, "Outer layer thickness (m)."},
                {"h2", kNumber, "Inner layer thickness (m)."},
                {"outer_width", kNumber, "Width of the outer layer (m)."},
                {"inner_density_ratio", kNumber, "Density of the inner layer relative to the outer."}}),
        "A two-layer strip of constant outline (App. A.5)."},
       {"perforated",
        object({{"outer_width", kNumber, "Constant outer width (m)."},
                {"min_ligament", kNumber, "Narrowest material between holes (m)."},
                {"columns", integer(1, 1000), "Hole columns across the width."},
                {"cell_aspect", kNumber, "Length over width of a hole cell."}}),
        "A strip of constant outline whose holes set K(s)."},
       {"name", kString, "Name carried to the result and the FreeCAD feature."},
       {"lp_form", leaf("\"dense\" | \"dual\" | \"primal\""), "Form of the LP given to Clp (default primal)."},
       {"stability",
        object({{"edges", integer(8, 1000000), "Edges of the Jacobi test."},
                {"eigenvalue_check", kBool, "Cross-check by the constrained Hessian."},
                {"simulation_edges", integer(8, 4000), "Edges of the simulation check."}},
               "true / false or object"),
        "Stability of the design (§4.5; default on)."},
       note()});
}

NodePtr fair_options(const char* type = "object") {
  return object({{"poles", integer(6, 1000), "Poles of the fitted B-spline."},
                 {"fairness", kNumber, "Weight of the fairness term."},
                 {"min_separation", kNumber, "Least distance of two kept inflections (relative)."},
                 {"end_separation", kNumber, "Least distance of a kept inflection from an end (relative)."}},
                type);
}

std::vector<Field> repair_common() {
  return {{"max_iterations", integer(0, 100000), "Iterations at most."},
          {"p", kNumber, "Exponent of the smooth maximum."},
          {"samples", integer(16, 20000), "Samples of the curve."},
          {"max_seconds", kNumber, "Time budget (s)."},
          {"initial_step", kNumber, "First step (relative to the curve's size)."},
          {"fix_length", kBool, "Keep the curve's length."},
          {"fit_poles", integer(6, 1000), "Poles of the B-spline fitted to points."}};
}

NodePtr strip_improve_request() {
  return extended(strip_request_base(), "the strip request",
                  {{"improve",
                    object(with({{"target_R", kNumber, "Stiffness ratio R to reach (default 3.5)."},
                                 {"global_every", integer(1, 1000), "A global step every n iterations."},
                                 {"fair", fair_options(), "Fit of the points before the improvement."}},
                                repair_common())),
                    "The repair's options (§4.5.4, §4.6.2)."}});
}

NodePtr strip_stabilize_request() {
  return extended(strip_request_base(), "the strip request",
                  {{"stabilize",
                    object(with({{"R_max", leaf("number | null"), "Bound on the stiffness ratio (default 10; null: none)."},
                                 {"margin", kNumber, "Stability margin to reach."},
                                 {"edges", integer(16, 20000), "Edges of the Jacobi test."},
                                 {"verify_edges", integer(16, 20000), "Edges of the final check."}},
                                repair_common())),
                    "Stability recovery's options (§4.5.4, Algorithm 4.2)."}});
}

// ---- rods (thesis ch. 5)
NodePtr rod_request() {
  const NodePtr bspline = object({{"degree", integer(1, 30), "Degree p."},
                                  {"knots", kNumbers, "Knot vector."},
                                  {"poles", leaf("[[x, y, z], ...]"), "Control points (m)."},
                                  {"weights", kNumbers, "Rational weights (default: all 1)."}});
  return object(
      {{"curve",
        object({{"bspline", bspline, "The curve as a B-spline."},
                {"points", leaf("[[x, y, z], ...]"), "Points the curve interpolates (m), instead of bspline."},
                {"degree", integer(1, 7), "Degree of the interpolant (default 3)."}}),
        "The 3D curve the rod takes at equilibrium (required)."},
       {"material",
        object({{"preset", kString, "A named material: \"SmoothSil 960\"."},
                {"E", kNumber, "Young's modulus (Pa)."},
                {"nu", kNumber, "Poisson's ratio."},
                {"density", kNumber, "Density (kg/m^3)."}}),
        "The rod's material (default SmoothSil 960)."},
       {"max_radius", kNumber, "Largest section radius (m)."},
       {"w_reg", kNumber, "Regularization weight of the LP (Eq. 5.19)."},
       {"stiffness_ratio_stage", kBool, "Second LP stage minimizing the stiffness ratio (default true)."},
       {"section", object({{"factor", kNumber, "t/t* of the sections (default 1: the most circular)."}}),
        "Section shape (§5.7.3)."},
       {"samples", integer(3, 100000), "Samples of the curve (default 200)."},
       {"loads",
        object({{"dead_load", kBool, "Include the rod's own weight (§5.8)."},
                {"gravity", kVec3, "Gravitational acceleration (m/s^2)."},
                {"point_loads",
                 array(object({{"s", kNumber, "Arc length where the force acts (m)."}, {"force", kVec3, "Force (N)."}})),
                 "Point forces along the rod."}}),
        "Loads at equilibrium."},
       {"fixed_point",
        object({{"tolerance", kNumber, "Convergence of the dead-load fixed point."},
                {"max_iterations", integer(1, 10000), "Iterations at most."}}),
        "The dead-load iteration."},
       {"validate", kBool, "Simulate the design (discrete elastic rod)."},
       {"validate_edges", integer(3, 5000), "Edges of the validation (default 100; 20,000 took 100 s)."},
       {"stability", kBool, "Hessian stability verdict (default true)."},
       {"stability_edges", integer(8, 2000), "Edges of the stability test (default 100)."},
       {"stability_at", leaf("\"equilibrium\" | \"target\""), "Where stability is judged."},
       {"name", kString, "Name carried to the result."},
       note()});
}

// ---- X-CAD (thesis ch. 6)
std::vector<Field> xcad_material() {
  return {{"E", kNumber, "Young's modulus (MPa with a part in mm)."},
          {"nu", kNumber, "Poisson's ratio (default 0.3)."},
          {"density", kNumber, "Density (for gravity and mass constraints)."},
          {"model", kString, "\"linear\" (default) or a hyperelastic law (\"neo-hookean\", ...)."}};
}

NodePtr supports() {
  return array(object(with(face_ref("supported"),
                           {{"displacement", kVec3, "Prescribed displacement (default 0: clamped)."}})),
               "array of objects");
}
NodePtr loads() {
  return array(object(with(face_ref("loaded"), {{"traction", kVec3, "Traction per area."},
                                                 {"force", kVec3, "Total force, spread evenly over the face."}})),
               "array of objects");
}

std::vector<Field> solver_fields() {
  return {{"supports", supports(), "Clamped faces (at least one)."},
          {"loads", loads(), "Loaded faces."},
          {"gravity", kVec3, "Body acceleration (with material.density)."},
          {"element", leaf("\"hex8\" | \"hex27\""), "Basis on the grid (default hex27)."},
          {"nitsche_penalty", leaf("\"fixed\" | \"local\""), "Penalty of the clamped faces (Nitsche)."},
          {"nitsche_beta", kNumber, "beta of the fixed penalty beta E/h."},
          {"nitsche_local_factor", kNumber, "Factor of the local penalty (> 1)."},
          {"nitsche_surface_degree", integer(2, 20), "Rule degree on curved clamped faces (default 8)."},
          {"incompatible_modes", kBool, "hex8 with incompatible modes (linear model)."},
          {"load_steps", integer(1, 100000), "Load steps of the hyperelastic Newton solve (default 5)."},
          {"threads", integer(0, 4096), "Threads (0: all cores)."},
          {"solver",
           object({{"type", leaf("\"auto\" | \"cholmod\" | \"petsc\""),
                    "CHOLMOD's Cholesky, PETSc's CG + AMG, or auto (PETSc from petsc_from unknowns and under mpirun)."},
                   {"ksp", kString, "PETSc Krylov solver (default \"cg\")."},
                   {"pc", kString, "PETSc preconditioner (default \"gamg\")."},
                   {"rtol", kNumber, "Relative residual at which PETSc stops (default 1e-9)."},
                   {"max_iterations", integer(1, 1000000000), "PETSc iterations at most."},
                   {"petsc_from", integer(0, kIntMax), "Unknowns from which auto takes PETSc (default 200000)."}}),
           "The linear solver."}};
}

NodePtr simulation_job() {
  return object(with(
      {{"material", object(xcad_material()), "The part's material (required)."},
       {"grid",
        object({{"cells", integer(1, 100000), "Cells along the part's longest side (default 8 hex27, 16 hex8)."},
                {"cell_size", kNumber, "Cell size instead of cells."},
                {"origin", kVec3, "A point the grid planes pass through (default: centred on the part)."},
                {"method", kString, "Cut route; \"face\" is the only one."},
                {"block_cells", kAny, "Refused (belonged to the retired splitter route)."},
                {"target", kNumber, "Accuracy target in (0, 1): grids refined until the estimated error is below it."},
                {"max_cells", integer(1, 100000), "Finest grid the target may reach (default 64)."}}),
        "The fixed grid."},
       {"quadrature",
        object({{"max_depth", integer(0, 64), "Refinement depth of curved patches."},
                {"flux_tolerance", kNumber, "Flux tolerance of the refinement."},
                {"degree_boost", integer(0, 12), "Extra degree of the cut-cell rules."}}),
        "Cut-cell rule tuning (§6.3.3)."},
       {"reuse",
        object({{"elements", kBool, "Reuse unchanged element matrices on update."},
                {"factorization", kBool, "Reuse the factorization as a CG preconditioner."},
                {"tolerance", kNumber, "CG relative residual, in (0, 1)."},
                {"max_iterations", integer(0, kIntMax), "CG iterations at most."}}),
        "What an update reuses of the previous solve."},
       {"memory_limit_mb", kNumber, "Memory the solve may use (default 70% of the machine's)."},
       {"solid", integer(0, kIntMax), "Index of the solid when the file holds several."},
       {"rotate",
        object({{"axis", kVec3, "Rotation axis (default [0, 0, 1])."},
                {"center", kVec3, "Centre (default origin)."},
                {"degrees", kNumber, "Angle (default 0)."}}),
        "Turn the part inside the grid before cutting."},
       {"probes", array(kVec3, "array of [x, y, z]"), "Points where displacement and stress are reported."},
       note()},
      solver_fields()));
}

const NodePtr& axis_object() {
  static const NodePtr n = object({{"point", kVec3, "A point of the axis."}, {"direction", kVec3, "The axis direction."}},
                                  "[x, y, z] or object");
  return n;
}

NodePtr objective_fields(bool term) {
  static const NodePtr target_surface =
      object({{"plane", object({{"point", kVec3, ""}, {"normal", kVec3, ""}}), "A plane."},
              {"sphere", object({{"center", kVec3, ""}, {"radius", kNumber, ""}}), "A sphere."},
              {"cylinder", object({{"point", kVec3, ""}, {"axis", kVec3, ""}, {"radius", kNumber, ""}}), "A cylinder."},
              {"torus",
               object({{"center", kVec3, ""}, {"axis", kVec3, ""}, {"major_radius", kNumber, ""}, {"minor_radius", kNumber, ""}}),
               "A torus."}});
  std::vector<Field> f = with(
      {{"type", kString,
        "mass, volume, center_of_mass, inertia_alignment, balance, compliance, failure, target"
        + std::string(term ? "" : ", sum")}},
      face_ref("matched (target)"));
  f = with(f, {{"target", target_surface, "Target surface of the matched face (default: its own as read)."},
               {"yield_stress", kNumber, "Yield stress of the failure metric."},
               {"exponent", kNumber, "Exponent of the failure metric's p-norm."},
               {"normalize", kBool, "Failure: per volume; sum: terms scaled by their initial values."},
               {"density", kNumber, "Density of the mass-property objectives."},
               {"axis", axis_object(),
                "Axis of inertia_alignment / balance."},
               {"length_scale", kNumber, "Length scale of the moment objectives."}});
  if (term) f.push_back({"weight", kNumber, "Weight of the term (default 1)."});
  else {
    f.push_back({"terms", array(objective_fields(true)), "Terms of a sum."});
    f.push_back({"step", kNumber, "Finite-difference step of the changed cells (mm)."});
    f.push_back({"gradient", leaf("\"exact\" | \"semi-analytic\""), "Route of the compliance gradient."});
  }
  return object(f);
}

NodePtr optimization_job() {
  const NodePtr param_ref = object(with(face_ref("designed"), {{"parameter", kString, "The face's parameter (radius, offset, pole[i].x, ...)."}}));
  return object(with(
      {{"material", object(xcad_material()), "The part's material (objectives that simulate)."},
       {"grid",
        object({{"cells", integer(1, 100000), "Cells along the longest side."},
                {"cell_size", kNumber, "Cell size instead of cells."},
                {"method", kString, "Cut route; \"face\" is the only one."},
                {"block_cells", kAny, "Refused (retired)."},
                {"target", kAny, "Refused: the grid stays fixed while the shape moves."}}),
        "The fixed grid of every evaluation."},
       {"merge_penalty",
        object({{"critical_fraction", kNumber, "Cut fraction below which a cell is merged."},
                {"law", leaf("\"inverse_square\" | ..."), "Penalty law."},
                {"cap", kNumber, "Cap of the penalty (0: none)."}},
               "object or false"),
        "Smooth tie of small cut cells."},
       {"objective", objective_fields(false), "What is minimized (required)."},
       {"parameters",
        array(object(with(face_ref("designed"),
                          {{"parameter", kString, "Which parameter of the face (radius, offset, ...)."},
                           {"min", kNumber, "Lower bound."},
                           {"max", kNumber, "Upper bound."}})),
              "\"auto\" or array of objects"),
        "The designed face parameters (default \"auto\")."},
       {"fixed_faces", array(object(face_ref("fixed"), "index or object"), "array of indices or objects"),
        "Faces that must not move."},
       {"ties", array(array(param_ref), "array of arrays"), "Groups of parameters that move together."},
       {"mirrors",
        array(object({{"faces", leaf("[a, b]"), "The mirrored pair."},
                      {"plane", object({{"normal", kVec3, ""}, {"offset", kNumber, ""}}), "The mirror plane."}})),
        "Mirror symmetries."},
       {"rotations",
        array(object({{"faces", leaf("[a, b, ...]"), "Faces in rotation order."},
                      {"axis", object({{"point", kVec3, ""}, {"direction", kVec3, ""}}), "The axis."},
                      {"degrees", kNumber, "Angle between neighbours."}})),
        "Rotational symmetries."},
       {"orthogonal", array(object(with(face_ref("drafted"), {{"axis", kVec3, "Axis the face stays parallel to."}}))),
        "Draft: faces kept parallel to an axis."},
       {"constraints",
        array(object({{"type", kString, "\"volume\" or \"mass\"."},
                      {"max_ratio", kNumber, "Volume: V / V0 at most."},
                      {"min_ratio", kNumber, "Volume: V / V0 at least."},
                      {"density", kNumber, "Mass: density (default material.density)."},
                      {"max", kNumber, "Mass: at most."},
                      {"min", kNumber, "Mass: at least."}})),
        "Volume and mass bounds."},
       {"max_iterations", integer(0, 100000), "L-BFGS iterations at most (default 50)."},
       {"freeze_switches", kBool, "Freeze discrete switches during a line search."},
       {"relative_improvement", kNumber, "Stop below this relative improvement (default 1e-6)."},
       {"first_step", kNumber, "Max-norm of the first step (parameter units, default 1)."},
       {"bound", kNumber, "Relative bound of every parameter around its start."},
       {"max_outer", integer(1, 1000), "Augmented-Lagrangian outer iterations at most."},
       {"estimate_multiplier", kBool, "Estimate the first multiplier of the volume bound."},
       {"start", kNumbers, "Design values to start from, one per parameters entry."},
       {"chart", kBool, "Write history.png (default true)."},
       note()},
      solver_fields()));
}

NodePtr sections_job() {
  return object(
      {{"planes",
        object({{"normal", kVec3, "Normal of the section planes."},
                {"offsets", kNumbers, "Offsets of the planes along the normal."},
                {"count", integer(1, 1000), "Evenly spaced planes instead of offsets (200 took 2 s on a cylinder)."}}),
        "The section planes."},
       {"split", object({{"normal", kVec3, ""}, {"offset", kNumber, ""}}), "A plane that splits closed sections."},
       {"samples", integer(8, 100000), "Samples of each section curve (default 60)."},
       {"units", leaf("\"mm\" | \"cm\" | \"m\""), "Units of the part (default mm)."},
       {"strip", extended(strip_request_base(), "the strip request", {}), "The strip request of every section (without curve)."},
       {"fair", fair_options("\"auto\", true, false or object"), "Fit the section points first (default \"auto\": where they have spurious inflections)."},
       {"part", kString, "The part's file name, for scripts (.ci/main.sh); the CLI takes the part as its argument."},
       note()});
}

NodePtr revolution_job() {
  return object({{"a", kNumber, "Meridian parameter a."},
                 {"b", kVec2, "Meridian parameter b."},
                 {"start", kVec2, "Start point (distance from the axis, height; m)."},
                 {"start_angle_deg", kNumber, "Start angle (default 90)."},
                 {"length", kNumber, "Meridian length (m, default 1)."},
                 {"points", integer(2, 1000000), "Output points (default 401; 100,000 took 0.3 s)."},
                 {"strips", integer(3, kIntMax), "Strips around the axis (default 12)."},
                 {"material", object({{"E", kNumber, "Young's modulus (Pa)."}, {"thickness", kNumber, "Thickness (m)."}}),
                  "The strips' material."},
                 note()});
}

std::string quoted_list(const Node& n) {
  std::vector<std::string> names;
  field_names(n, names);
  std::string s;
  for (const auto& f : names) s += (s.empty() ? "" : ", ") + f;
  return s;
}

// Damerau-Levenshtein (optimal string alignment) distance.
size_t distance(const std::string& a, const std::string& b) {
  std::vector<std::vector<size_t>> d(a.size() + 1, std::vector<size_t>(b.size() + 1));
  for (size_t i = 0; i <= a.size(); ++i) d[i][0] = i;
  for (size_t j = 0; j <= b.size(); ++j) d[0][j] = j;
  for (size_t i = 1; i <= a.size(); ++i)
    for (size_t j = 1; j <= b.size(); ++j) {
      const size_t cost = std::tolower(a[i - 1]) == std::tolower(b[j - 1]) ? 0 : 1;
      d[i][j] = std::min({d[i - 1][j] + 1, d[i][j - 1] + 1, d[i - 1][j - 1] + cost});
      if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1]) d[i][j] = std::min(d[i][j], d[i - 2][j - 2] + 1);
    }
  return d[a.size()][b.size()];
}

bool accepts_other(const Node& n) { return n.type.find(" or ") != std::string::npos; }

std::string where(const std::string& path) { return path.empty() ? std::string("the request") : path; }

// The plain leaf types; a union ("\"mm\" | \"cm\"", "number | null") is the parser's to check.
void check_leaf_type(const json& v, const Node& n, const std::string& path) {
  const std::string& t = n.type;
  auto fail = [&](const char* what) { PARAFAB_INPUT_ERROR(where(path) << " must be " << what << ", got " << v.dump()); };
  auto numbers = [&](size_t size) {
    if (!v.is_array() || (size && v.size() != size)) return false;
    return std::all_of(v.begin(), v.end(), [](const json& x) { return x.is_number(); });
  };
  if ((t == "number" || t == "integer") && !v.is_number()) fail(t == "number" ? "a number" : "an integer");
  if (t == "boolean" && !v.is_boolean()) fail("true or false");
  if (t == "string" && !v.is_string()) fail("a string");
  if (t == "[x, y, z]" && !numbers(3)) fail("[x, y, z] (three numbers)");
  if (t == "[x, y]" && !numbers(2)) fail("[x, y] (two numbers)");
  if (t == "[number, ...]" && !numbers(0)) fail("a list of numbers");
  // A choice of strings ("\"mm\" | \"cm\" | \"m\""): one of them (a near miss named).
  if (!t.empty() && t[0] == '"') {
    std::vector<std::string> choices;
    for (size_t a = 0; a < t.size();) {
      const size_t b = t.find(" | ", a);
      const std::string c = t.substr(a, b == std::string::npos ? std::string::npos : b - a);
      if (c.size() < 2 || c.front() != '"' || c.back() != '"') return;  // an open list ("..."): the parser's
      choices.push_back(c.substr(1, c.size() - 2));
      a = b == std::string::npos ? t.size() : b + 3;
    }
    if (!v.is_string()) fail(("one of " + t).c_str());
    if (std::find(choices.begin(), choices.end(), v.get<std::string>()) != choices.end()) return;
    const std::string near = nearest(v.get<std::string>(), choices);
    PARAFAB_INPUT_ERROR(where(path) << " must be one of " << t << ", got " << v.dump()
                                    << (near.empty() ? "" : ", did you mean \"" + near + "\"?"));
  }
}

}  // namespace

std::string nearest(const std::string& word, const std::vector<std::string>& candidates) {
  std::string best;
  size_t best_d = std::max<size_t>(2, word.size() / 3) + 1;
  for (const auto& c : candidates) {
    const size_t d = distance(word, c);
    if (d < best_d) best_d = d, best = c;
  }
  return best;
}

const NodePtr& of(Format format) {
  static const NodePtr strip = strip_request_base(), improve = strip_improve_request(),
                       stabilize = strip_stabilize_request(), rod = rod_request(), sim = simulation_job(),
                       opt = optimization_job(), sections = sections_job(), revolution = revolution_job();
  switch (format) {
    case Format::Strip: return strip;
    case Format::StripImprove: return improve;
    case Format::StripStabilize: return stabilize;
    case Format::Rod: return rod;
    case Format::Simulation: return sim;
    case Format::Optimization: return opt;
    case Format::Sections: return sections;
    case Format::Revolution: return revolution;
  }
  return strip;
}

std::string name_of(Format format) {
  switch (format) {
    case Format::Strip: return "strip request";
    case Format::StripImprove: return "strip-improve request";
    case Format::StripStabilize: return "strip-stabilize request";
    case Format::Rod: return "rod request";
    case Format::Simulation: return "simulation job";
    case Format::Optimization: return "optimization job";
    case Format::Sections: return "sections job";
    case Format::Revolution: return "revolution job";
  }
  return "request";
}

void check(const json& value, const Node& node, const std::string& path, const std::string& what) {
  switch (node.kind) {
    case Node::Kind::Object: {
      if (!value.is_object()) {
        // A documented alternative ("true / false or object", "\"auto\" or array"): the parser's.
        if (accepts_other(node)) return;
        PARAFAB_INPUT_ERROR(where(path) << " must be a JSON object {" << quoted_list(node) << "}, got " << value.dump());
      }
      for (auto it = value.begin(); it != value.end(); ++it) {
        const std::string key_path = path.empty() ? it.key() : path + "." + it.key();
        const Field* f = find_field(node, it.key());
        if (!f) {
          std::vector<std::string> names;
          field_names(node, names);
          const std::string near = nearest(it.key(), names);
          if (!near.empty())
            PARAFAB_INPUT_ERROR(key_path << ": unknown key in the " << what << ", did you mean \"" << near << "\"?");
          PARAFAB_INPUT_ERROR(key_path << ": unknown key in the " << what << " (known here: " << quoted_list(node) << ")");
        }
        check(*it, *f->node, key_path, what);
      }
      return;
    }
    case Node::Kind::Array:
      if (!value.is_array()) {
        if (accepts_other(node)) return;
        PARAFAB_INPUT_ERROR(where(path) << " must be a list (" << node.type << "), got " << value.dump());
      }
      for (size_t i = 0; i < value.size(); ++i) check(value[i], *node.item, path + "[" + std::to_string(i) + "]", what);
      return;
    case Node::Kind::Leaf:
      check_leaf_type(value, node, path);
      if (node.type == "integer" && value.is_number()) {
        const double x = value.get<double>();
        if (!std::isfinite(x) || x != std::floor(x))
          PARAFAB_INPUT_ERROR(path << " must be an integer (a whole number), got " << value.dump());
        if (x < static_cast<double>(node.min) || x > static_cast<double>(node.max))
          PARAFAB_INPUT_ERROR(path << " must be an integer " << node.min << ".." << node.max << ", got " << value.dump());
      }
      return;
  }
}

void check(const json& request, Format format) {
  if (!request.is_object()) PARAFAB_INPUT_ERROR("the " << name_of(format) << " must be a JSON object, got " << request.type_name());
  if (format == Format::Optimization)  // a simulation job reused: say which keys it does not use
    for (auto it = request.begin(); it != request.end(); ++it)
      if (!find_field(*of(format), it.key()) && find_field(*of(Format::Simulation), it.key()))
        PARAFAB_INPUT_ERROR(it.key() << ": unknown key in the optimization job (a simulation-job key it does not use: "
                                        "remove it)");
  check(request, *of(format), "", name_of(format));
}

std::string reference_markdown() {
  std::ostringstream md;
  md << "# JSON reference\n\n"
        "Generated by `parafab reference` from the key tables every request is checked against before it is\n"
        "parsed (`workbench/entry/request_schema.cpp`); `tests/docs` fails when this file is not current.\n"
        "An unknown key is an error naming it and the nearest known key; an integer field must hold a\n"
        "whole number in its range. Each format has one table per object; `a[]` is an item of array `a`.\n"
        "Units are those of the capability: SI for strips and rods, the part's (usually mm, MPa) for X-CAD.\n";
  struct Entry {
    Format format;
    const char* entry;
  };
  const Entry formats[] = {{Format::Strip, "`parafab strip`, `parafab strip-stability`, `parafab.design_strip`, `parafab.strip_stability`"},
                           {Format::StripImprove, "`parafab strip-improve`, `parafab.strip_improve`"},
                           {Format::StripStabilize, "`parafab strip-stabilize`, `parafab.stabilize_strip`"},
                           {Format::Rod, "`parafab rod`, `parafab.design_rod`"},
                           {Format::Simulation, "`parafab simulate PART JOB`, `parafab.simulate`"},
                           {Format::Optimization, "`parafab optimize PART JOB -o DIR`, `parafab.optimize`"},
                           {Format::Sections, "`parafab sections PART JOB`, `parafab.strip_sections`"},
                           {Format::Revolution, "`parafab revolution`, `parafab.revolution_strips`"}};
  std::map<const Node*, std::string> printed;  // each shared object once; later uses point to it
  for (const Entry& e : formats) {
    const std::string name = name_of(e.format);
    md << "\n## The " << name << "\n\nRead by " << e.entry << ".\n";
    std::function<void(const Node&, const std::string&)> table = [&](const Node& n, const std::string& path) {
      printed[&n] = (path.empty() ? std::string("the top level") : "`" + path + "`") + " of the " + name;
      md << "\n### " << (path.empty() ? "top level" : "`" + path + "`") << "\n\n";
      if (n.base) md << "All keys of " << n.base_name << (n.fields.empty() ? ".\n" : ", and:\n\n");
      if (n.fields.empty()) return;
      md << "| key | value | meaning |\n|---|---|---|\n";
      std::vector<std::pair<const Node*, std::string>> nested;
      for (const Field& f : n.fields) {
        std::string type = f.node->type;
        if (f.node->kind == Node::Kind::Leaf && type == "integer")
          type += f.node->max >= kIntMax ? " >= " + std::to_string(f.node->min)
                                         : " " + std::to_string(f.node->min) + ".." + std::to_string(f.node->max);
        const std::string sub = path.empty() ? f.name : path + "." + f.name;
        const Node* inner = f.node.get();
        std::string inner_path = sub;
        while (inner->kind == Node::Kind::Array) inner = inner->item.get(), inner_path += "[]";
        std::string doc = f.doc;
        if (inner->kind == Node::Kind::Object && (!inner->fields.empty() || inner->base)) {
          const auto seen = printed.find(inner);
          if (seen != printed.end()) doc += (doc.empty() ? "" : " ") + std::string("Keys as in ") + seen->second + ".";
          else nested.emplace_back(inner, inner_path);
        }
        for (auto& c : doc) if (c == '|') c = '/';
        for (auto& c : type) if (c == '|') c = '/';
        md << "| `" << f.name << "` | " << type << " | " << doc << " |\n";
      }
      for (const auto& [node, p] : nested)
        if (!printed.count(node)) table(*node, p);
    };
    table(*of(e.format), "");
  }
  return md.str();
}

}  // namespace parafab::entry::schema
