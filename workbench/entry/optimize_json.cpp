// JSON layer of the shape optimization (thesis §6.5): job parsing, history output, chart.
#include "optimize_json.h"

#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include <tbb/global_control.h>

#include "common/error.h"
#include "output_files.h"
#include "request_schema.h"
#include "face_lookup.h"
#include "grid_estimate.h"
#include "install_paths.h"
#include "json_fields.h"
#include "part_reader.h"
#include "shape_modify.h"
#include "shape_optimization.h"
#include "simulation_job.h"

namespace parafab::entry {

using nlohmann::json;
using fields::number;
using fields::vec3;

namespace {

occ::ParameterRef parameter_ref(const NamedPart& part, const json& item, const std::string& path) {
  occ::ParameterRef r;
  r.face = face_index(part, item, path);
  const json& name = fields::require(item, "parameter", path);
  if (!name.is_string()) PARAFAB_INPUT_ERROR(path << ".parameter must be a name such as \"radius\" or \"offset\"");
  r.parameter = name.get<std::string>();
  return r;
}

// Thesis §6.4.4 (Eq. 6.24): pieces about to join tied (resources/doc/optimization.md, "Pieces that join").
occ::MergePenaltyOptions merge_penalty_of_job(const json& job, bool merge_ok, bool hyperelastic) {
  occ::MergePenaltyOptions merge;
  if (!job.contains("merge_penalty")) return merge;
  const json& mp = job["merge_penalty"];
  if (!(mp.is_boolean() || mp.is_object()))
    PARAFAB_INPUT_ERROR("merge_penalty must be true, false or {\"critical_fraction\", \"law\", \"cap\"}, got " << mp.dump());
  merge.enabled = mp.is_object() || mp.get<bool>();
  if (mp.is_object()) {
    fields::only(mp, "merge_penalty", {"critical_fraction", "law", "cap"});
    merge.critical_fraction = number(mp.value("critical_fraction", json(merge.critical_fraction)), "merge_penalty.critical_fraction");
    if (!(merge.critical_fraction > 0 && merge.critical_fraction <= 0.5))
      PARAFAB_INPUT_ERROR("merge_penalty.critical_fraction must be in (0, 0.5] (of a cell), got " << merge.critical_fraction);
    const std::string law = mp.value("law", std::string("inverse_square"));
    if (law == "inverse_square") merge.law = occ::MergePenaltyOptions::Law::InverseSquare;
    else if (law == "log2") merge.law = occ::MergePenaltyOptions::Law::Log2;
    else PARAFAB_INPUT_ERROR("merge_penalty.law must be \"inverse_square\" or \"log2\" (thesis Eq. 6.24), got \"" << law << "\"");
    merge.cap = number(mp.value("cap", json(0.0)), "merge_penalty.cap");
    if (!(merge.cap >= 0)) PARAFAB_INPUT_ERROR("merge_penalty.cap must be >= 0 (0: the law's default), got " << merge.cap);
  }
  if (merge.enabled) {
    if (!merge_ok)
      PARAFAB_INPUT_ERROR("merge_penalty: only with the compliance objective alone (the other objectives' "
                          "gradients have no term for the ties)");
    if (hyperelastic) PARAFAB_INPUT_ERROR("merge_penalty: the hyperelastic solve has no ties; use material.model \"linear\"");
  }
  return merge;
}

// The elasticity job of the compliance, failure and target objectives: the simulation job's
// fields (simulation_job.h, as `parafab simulate` reads them, with the optimizer's defaults: hex8;
// a total force stays fixed and is spread over the load face of every model), a hyperelastic
// material.model for `hyperelastic_ok` objectives (the target shape alone or with moment terms),
// and the merge penalty.
std::shared_ptr<const occ::ComplianceSetup> compliance_setup(const NamedPart& part, const json& job,
                                                             bool hyperelastic_ok, bool merge_ok) {
  SimulationJob sim = parse_simulation_job(part, job, SimulationJobOptions::optimize(hyperelastic_ok));
  auto s = std::make_shared<occ::ComplianceSetup>();
  s->material = sim.material.elastic;
  s->hyperelastic = sim.material.law;
  if (s->hyperelastic) s->load_steps = sim.material.load_steps;
  s->solver = sim.solver;
  s->grid = sim.grid.options;
  s->dirichlet = std::move(sim.conditions.supports);
  s->tractions = std::move(sim.conditions.loads);
  s->forces = std::move(sim.conditions.forces);
  s->merge = merge_penalty_of_job(job, merge_ok, s->hyperelastic != nullptr);
  return s;
}

// The surface of a "target" objective: {"plane": {"point", "normal"}}, {"sphere": {"center",
// "radius"}}, {"cylinder": {"point", "axis", "radius"}} or {"torus": {"center", "axis",
// "major_radius", "minor_radius"}}.
occ::TargetSurface target_surface(const json& t, const std::string& path) {
  if (!t.is_object() || t.size() != 1)
    PARAFAB_INPUT_ERROR(path << " must be one of {\"plane\": {point, normal}}, {\"sphere\": {center, radius}}, "
                                "{\"cylinder\": {point, axis, radius}}, {\"torus\": {center, axis, major_radius, minor_radius}}");
  const std::string kind = t.begin().key();
  const json& f = t.begin().value();
  const std::string fp = path + "." + kind;
  occ::TargetSurface s;
  if (kind == "plane") {
    fields::only(f, fp, {"point", "normal"});
    s.type = occ::SurfaceType::plane;
    s.point = vec3(fields::require(f, "point", fp), fp + ".point");
    s.axis = vec3(fields::require(f, "normal", fp), fp + ".normal");
  } else if (kind == "sphere") {
    fields::only(f, fp, {"center", "radius"});
    s.type = occ::SurfaceType::sphere;
    s.point = vec3(fields::require(f, "center", fp), fp + ".center");
    s.radius = number(fields::require(f, "radius", fp), fp + ".radius");
  } else if (kind == "cylinder") {
    fields::only(f, fp, {"point", "axis", "radius"});
    s.type = occ::SurfaceType::cylinder;
    s.point = vec3(fields::require(f, "point", fp), fp + ".point");
    s.axis = vec3(fields::require(f, "axis", fp), fp + ".axis");
    s.radius = number(fields::require(f, "radius", fp), fp + ".radius");
  } else if (kind == "torus") {
    fields::only(f, fp, {"center", "axis", "major_radius", "minor_radius"});
    s.type = occ::SurfaceType::torus;
    s.point = vec3(fields::require(f, "center", fp), fp + ".center");
    s.axis = vec3(fields::require(f, "axis", fp), fp + ".axis");
    s.major_radius = number(fields::require(f, "major_radius", fp), fp + ".major_radius");
    s.radius = number(fields::require(f, "minor_radius", fp), fp + ".minor_radius");
  } else {
    PARAFAB_INPUT_ERROR(path << ": '" << kind << "' is not a target surface (plane, sphere, cylinder, torus)");
  }
  occ::check_target_surface(s, fp);
  return s;
}

json target_surface_json(const occ::TargetSurface& s) {
  const auto v = [](const Eigen::Vector3d& x) { return std::vector<double>{x.x(), x.y(), x.z()}; };
  switch (s.type) {
    case occ::SurfaceType::plane: return {{"plane", {{"point", v(s.point)}, {"normal", v(s.axis.normalized())}}}};
    case occ::SurfaceType::sphere: return {{"sphere", {{"center", v(s.point)}, {"radius", s.radius}}}};
    case occ::SurfaceType::cylinder:
      return {{"cylinder", {{"point", v(s.point)}, {"axis", v(s.axis.normalized())}, {"radius", s.radius}}}};
    default:
      return {{"torus", {{"center", v(s.point)}, {"axis", v(s.axis.normalized())}, {"major_radius", s.major_radius},
                         {"minor_radius", s.radius}}}};
  }
}

// One objective (not its terms): type and the fields of the moment objectives; `path` names it
// in errors ("objective", "objective.terms[2]").
occ::ObjectiveSpec objective_spec(const NamedPart& part, const json& obj, const std::string& path,
                                  bool& needs_compliance) {
  if (!obj.is_object()) PARAFAB_INPUT_ERROR(path << " must be an object with a \"type\"");
  occ::ObjectiveSpec spec;
  const json& type = fields::require(obj, "type", path);
  if (!type.is_string()) PARAFAB_INPUT_ERROR(path << ".type must be a string");
  spec.type = type.get<std::string>();
  if (spec.type == "stress")
    PARAFAB_INPUT_ERROR(path << ".type 'stress' is called 'failure' (yield_stress, exponent, normalize); available: "
                                "mass, volume, center_of_mass, inertia_alignment, balance, compliance, failure, target, sum");
  static const char* known[] = {"mass",    "volume",     "center_of_mass", "inertia_alignment", "balance",
                                "compliance", "failure", "target",         "sum"};
  if (std::find(std::begin(known), std::end(known), spec.type) == std::end(known))
    PARAFAB_INPUT_ERROR(path << ".type '" << spec.type
                             << "' is unknown (mass, volume, center_of_mass, inertia_alignment, balance, compliance, "
                                "failure, target, sum)");
  needs_compliance |= spec.type == "compliance" || spec.type == "failure" || spec.type == "target";
  if (spec.type == "target") {
    // The deformed face (by "face" index or a "point" on it) matched to "target" (default: the
    // face's own surface as read): thesis §6.2.3 Eq. 6.6.
    if (!obj.contains("face") && !obj.contains("point"))
      PARAFAB_INPUT_ERROR(path << ": the target objective needs the matched face (\"face\": index or \"point\": [x, y, z] on it)");
    spec.face = face_index(part, obj, path);
    if (obj.contains("target")) {
      spec.target = target_surface(obj["target"], path + ".target");
      spec.has_target = true;
    }
  }
  if (spec.type == "failure") {
    // (1/V)∫ exp(α(σ_vm/σ_y − 1)) dV (thesis §6.2.3 Eq. 6.4); the fields are required.
    spec.yield_stress = number(fields::require(obj, "yield_stress", path), path + ".yield_stress");
    spec.exponent = number(fields::require(obj, "exponent", path), path + ".exponent");
    if (obj.contains("normalize")) {
      if (!obj["normalize"].is_boolean())
        PARAFAB_INPUT_ERROR(path << ".normalize must be true or false, got " << obj["normalize"].dump());
      spec.per_volume = obj["normalize"].get<bool>();
    }
    occ::check_failure_options({spec.yield_stress, spec.exponent, spec.per_volume});
  }
  if (obj.contains("density")) spec.density = number(obj["density"], path + ".density");
  if (obj.contains("axis")) {
    const json& axis = obj["axis"];
    if (axis.is_array()) {
      spec.axis = vec3(axis, path + ".axis");
    } else {
      if (axis.contains("point")) spec.point = vec3(axis["point"], path + ".axis.point");
      spec.axis = vec3(fields::require(axis, "direction", path + ".axis"), path + ".axis.direction");
    }
    if (spec.axis.norm() < 1e-12) PARAFAB_INPUT_ERROR(path << ".axis direction is zero");
  }
  spec.length_scale = obj.contains("length_scale") ? number(obj["length_scale"], path + ".length_scale") : 0;
  return spec;
}

// Writes `part` as out_dir/name (the folder created), never over the input part; the path.
std::string write_beside(const occ::PartShape& part, const std::string& out_dir, const std::string& name,
                         const std::string& part_path) {
  require_writable_folder(out_dir);
  const std::string step = out_dir + "/" + name;
  if (std::filesystem::weakly_canonical(step) == std::filesystem::weakly_canonical(part_path))
    PARAFAB_INPUT_ERROR("the output " << step << " would overwrite the input part: choose another output folder");
  AtomicFile file(step);  // a reader never sees a half-written STEP under the final name
  occ::write_step(part, file.temporary());
  file.commit();
  return step;
}

// Objective: one type, or "sum" of weighted terms of the other types; for the objectives that
// simulate, the simulation job (compliance_setup) and the compliance gradient's options. Returns
// the size estimate of their solve (null without one).
json read_objective(const NamedPart& named, const occ::PartShape& part, const json& job, occ::ShapeOptimizationOptions& o) {
  const json& obj = fields::require(job, "objective", "job");
  bool needs_compliance = false;
  o.objective = objective_spec(named, obj, "objective", needs_compliance);
  if (o.objective.type == "sum") {
    const json& terms = fields::require(obj, "terms", "objective");
    if (!terms.is_array() || terms.empty())
      PARAFAB_INPUT_ERROR("objective.terms must be a non-empty list of {\"type\", \"weight\", ...}");
    for (size_t i = 0; i < terms.size(); ++i) {
      const std::string path = "objective.terms[" + std::to_string(i) + "]";
      occ::ObjectiveSpec t = objective_spec(named, terms[i], path, needs_compliance);
      if (t.type == "sum") PARAFAB_INPUT_ERROR(path << ".type: a sum cannot be a term of a sum");
      for (const char* key : {"gradient", "step"})
        if (terms[i].contains(key))
          PARAFAB_INPUT_ERROR(path << "." << key << ": the compliance gradient's options belong on the sum (objective." << key << ")");
      if (t.type == "failure" && std::any_of(o.objective.terms.begin(), o.objective.terms.end(),
                                             [](const occ::ObjectiveSpec& u) { return u.type == "failure"; }))
        PARAFAB_INPUT_ERROR(path << ".type: a sum takes one 'failure' term at most");
      if (t.type == "target" && std::any_of(o.objective.terms.begin(), o.objective.terms.end(),
                                            [](const occ::ObjectiveSpec& u) { return u.type == "target"; }))
        PARAFAB_INPUT_ERROR(path << ".type: a sum takes one 'target' term at most");
      t.weight = terms[i].contains("weight") ? number(terms[i]["weight"], path + ".weight") : 1.0;
      if (!std::isfinite(t.weight)) PARAFAB_INPUT_ERROR(path << ".weight must be finite, got " << t.weight);
      o.objective.terms.push_back(t);
    }
    if (obj.contains("normalize")) {
      if (!obj["normalize"].is_boolean()) PARAFAB_INPUT_ERROR("objective.normalize must be true or false");
      o.objective.normalize = obj["normalize"].get<bool>();
    }
  }
  json size_estimate;  // the elasticity jobs: estimated before anything is cut, as `parafab simulate` does
  if (needs_compliance) {
    // A hyperelastic law only where every elastic term has an adjoint through the tangent.
    const auto elastic_term = [](const occ::ObjectiveSpec& t) { return t.type == "compliance" || t.type == "failure"; };
    const bool hyperelastic_ok = !elastic_term(o.objective) &&
                                 std::none_of(o.objective.terms.begin(), o.objective.terms.end(), elastic_term);
    o.compliance = compliance_setup(named, job, hyperelastic_ok, o.objective.type == "compliance" && o.objective.terms.empty());
    {
      const JobSize size = estimate_job_size(size_info(occ::part_box_and_area(part)), o.compliance->grid.grid,
                                             o.compliance->solver);
      size_estimate = {{"unknowns", size.solve.dofs}, {"peak_mb", size.solve.peak_mb}, {"peak_mb_min", size.solve.peak_mb_min},
                       {"limit_mb", size.limit_mb}, {"cut", to_json(size.cut)}};
      refuse_if_too_big(size, JobCommand::Optimize);
    }
    if (obj.contains("step")) o.compliance_step = number(obj["step"], "objective.step");
    if (!(o.compliance_step > 0)) PARAFAB_INPUT_ERROR("objective.step must be positive, got " << o.compliance_step);
    if (obj.contains("gradient")) {
      const json& g = obj["gradient"];
      if (g == "exact") o.compliance_gradient = occ::ShapeOptimizationOptions::ComplianceGradientRoute::Exact;
      else if (g == "semi-analytic") o.compliance_gradient = occ::ShapeOptimizationOptions::ComplianceGradientRoute::SemiAnalytic;
      else PARAFAB_INPUT_ERROR("objective.gradient must be \"exact\" or \"semi-analytic\", got " << g.dump());
      if (o.compliance->merge.enabled && g == "semi-analytic")
        PARAFAB_INPUT_ERROR("merge_penalty with objective.gradient \"semi-analytic\": that route has no term for the ties; "
                            "use the exact route (the default)");
    }
  }
  {  // the types are valid?
    Eigen::Matrix<double, 10, 1> g;
    occ::Moments m = occ::Moments::Ones();
    occ::objective_from_moments(o.objective, m, &g);
  }
  return size_estimate;
}

// Parameterization: the faces that stay fixed, ties and symmetries (mirrors, rotations, draft).
void read_parameterization(const NamedPart& named, const json& job, occ::ShapeOptimizationOptions& o) {
  // Fixed faces: supports and loads of the simulation job, and "fixed_faces". A support or load
  // whose face the "parameters" list names moves with its face (a bolt hole's radius under its
  // bolt load); "auto" keeps them fixed.
  // The faces of a tie group with a named face move with it (split arcs of one hole, say).
  std::set<int> named_faces;
  if (job.contains("parameters") && job["parameters"].is_array()) {
    for (size_t i = 0; i < job["parameters"].size(); ++i)
      named_faces.insert(parameter_ref(named, job["parameters"][i], "parameters[" + std::to_string(i) + "]").face);
    const json groups = job.value("ties", json::array());
    for (size_t i = 0; groups.is_array() && i < groups.size(); ++i) {
      if (!groups[i].is_array()) continue;  // reported where the ties are read
      std::vector<int> faces;
      for (size_t k = 0; k < groups[i].size(); ++k)
        faces.push_back(parameter_ref(named, groups[i][k], "ties[" + std::to_string(i) + "][" + std::to_string(k) + "]").face);
      if (std::any_of(faces.begin(), faces.end(), [&](int f) { return named_faces.count(f) > 0; }))
        named_faces.insert(faces.begin(), faces.end());
    }
  }
  for (const char* key : {"supports", "loads"}) {
    const json list = job.value(key, json::array());
    if (!list.is_array()) PARAFAB_INPUT_ERROR(key << " must be a list");
    for (size_t i = 0; i < list.size(); ++i) {
      const int face = face_index(named, list[i], std::string(key) + "[" + std::to_string(i) + "]");
      if (!named_faces.count(face)) o.parameterization.fixed_faces.push_back(face);
    }
  }
  const json fixed = job.value("fixed_faces", json::array());
  if (!fixed.is_array()) PARAFAB_INPUT_ERROR("fixed_faces must be a list of face indices or {\"face\"} / {\"point\"} entries");
  for (size_t i = 0; i < fixed.size(); ++i) {
    // A face index, or {"face": i} / {"point": [x, y, z]} as every other face reference.
    const std::string path = "fixed_faces[" + std::to_string(i) + "]";
    if (fixed[i].is_number_integer()) o.parameterization.fixed_faces.push_back(face_index(named, json{{"face", fixed[i]}}, path));
    else if (fixed[i].is_object()) o.parameterization.fixed_faces.push_back(face_index(named, fixed[i], path));
    else PARAFAB_INPUT_ERROR(path << " must be a face index, {\"face\": i} or {\"point\": [x, y, z]}, got " << fixed[i].dump());
  }
  const json ties = job.value("ties", json::array());
  for (size_t i = 0; i < ties.size(); ++i) {
    std::vector<occ::ParameterRef> tie;
    for (size_t k = 0; k < ties[i].size(); ++k)
      tie.push_back(parameter_ref(named, ties[i][k], "ties[" + std::to_string(i) + "][" + std::to_string(k) + "]"));
    o.parameterization.ties.push_back(tie);
  }
  const json mirrors = job.value("mirrors", json::array());
  for (size_t i = 0; i < mirrors.size(); ++i) {
    const std::string path = "mirrors[" + std::to_string(i) + "]";
    const json& faces = fields::require(mirrors[i], "faces", path);
    if (!faces.is_array() || faces.size() != 2 || !faces[0].is_number_integer() || !faces[1].is_number_integer())
      PARAFAB_INPUT_ERROR(path << ".faces must be [face_a, face_b]");
    occ::ShapeParameterOptions::Mirror m;
    m.face_a = faces[0].get<int>();
    m.face_b = faces[1].get<int>();
    const json& plane = fields::require(mirrors[i], "plane", path);
    m.normal = vec3(fields::require(plane, "normal", path + ".plane"), path + ".plane.normal");
    m.offset = number(fields::require(plane, "offset", path + ".plane"), path + ".plane.offset");
    o.parameterization.mirrors.push_back(m);
  }
  // Rotational symmetry: [{"faces": [f0, f1, ...], "axis": {"point": [..], "direction": [..]}, "degrees": θ}],
  // f(k+1) = f(k) turned by θ; a face is an index or a point on it ([x, y, z]).
  const json rotations = job.value("rotations", json::array());
  if (!rotations.is_array()) PARAFAB_INPUT_ERROR("rotations must be a list of {\"faces\", \"axis\", \"degrees\"}");
  for (size_t i = 0; i < rotations.size(); ++i) {
    const std::string path = "rotations[" + std::to_string(i) + "]";
    fields::only(rotations[i], path, {"faces", "axis", "degrees"});
    const json& faces = fields::require(rotations[i], "faces", path);
    if (!faces.is_array() || faces.size() < 2) PARAFAB_INPUT_ERROR(path << ".faces must be a list of at least two faces");
    occ::ShapeParameterOptions::Rotation r;
    for (size_t k = 0; k < faces.size(); ++k) {
      const std::string fp = path + ".faces[" + std::to_string(k) + "]";
      if (faces[k].is_number_integer()) r.faces.push_back(face_index(named, json{{"face", faces[k]}}, fp));
      else if (faces[k].is_array()) r.faces.push_back(face_index(named, json{{"point", faces[k]}}, fp));
      else PARAFAB_INPUT_ERROR(fp << " must be a face index or a point [x, y, z] on the face");
    }
    const json& axis = fields::require(rotations[i], "axis", path);
    r.point = vec3(fields::require(axis, "point", path + ".axis"), path + ".axis.point");
    r.axis = vec3(fields::require(axis, "direction", path + ".axis"), path + ".axis.direction");
    r.degrees = number(fields::require(rotations[i], "degrees", path), path + ".degrees");
    o.parameterization.rotations.push_back(r);
  }
  // Draft: plane normals kept orthogonal to an axis, [{"face": i | "point": [x, y, z], "axis": [x, y, z]}].
  const json orthogonal = job.value("orthogonal", json::array());
  if (!orthogonal.is_array()) PARAFAB_INPUT_ERROR("orthogonal must be a list of {\"face\" | \"point\", \"axis\"}");
  for (size_t i = 0; i < orthogonal.size(); ++i) {
    const std::string path = "orthogonal[" + std::to_string(i) + "]";
    occ::ShapeParameterOptions::Orthogonal d;
    d.face = face_index(named, orthogonal[i], path);
    d.axis = vec3(fields::require(orthogonal[i], "axis", path), path + ".axis");
    o.parameterization.orthogonal.push_back(d);
  }
}

// The designed parameters ("auto" or a list), each with its optional absolute bounds.
void read_design(const NamedPart& named, const occ::PartShape& part, const json& job, occ::ShapeOptimizationOptions& o) {
  // Parameters: the face model decides the indices (built again inside optimize_shape; cheap).
  const occ::FaceModel model = occ::build_face_model(part);
  const occ::ShapeParameters sp = occ::build_shape_parameters(model, o.parameterization);
  const json& params = job.contains("parameters") ? job["parameters"] : json("auto");
  if (params.is_string()) {
    if (params != "auto") PARAFAB_INPUT_ERROR("parameters must be \"auto\" or a list of {\"face\", \"parameter\"}");
  } else if (params.is_array()) {
    for (size_t i = 0; i < params.size(); ++i) {
      const occ::ParameterRef r = parameter_ref(named, params[i], "parameters[" + std::to_string(i) + "]");
      const int idx = occ::parameter_index(sp, r.face, r.parameter);
      if (!(sp.lower[idx] < sp.upper[idx]))
        PARAFAB_INPUT_ERROR("parameters[" << i << "]: face " << r.face
                                          << " is fixed (fixed_faces, a face without parameters, or tangent to a free-form face)");
      o.design.push_back(idx);
      // Optional absolute bounds on this entry ("min", "max"), e.g. a fin that must stay castable.
      const std::string path = "parameters[" + std::to_string(i) + "]";
      const double lo = params[i].contains("min") ? number(params[i]["min"], path + ".min") : -INFINITY;
      const double hi = params[i].contains("max") ? number(params[i]["max"], path + ".max") : INFINITY;
      if (!(lo < hi)) PARAFAB_INPUT_ERROR(path << ": min " << lo << " must be below max " << hi);
      o.design_min.push_back(lo);
      o.design_max.push_back(hi);
    }
    if (o.design.empty()) PARAFAB_INPUT_ERROR("parameters is an empty list");
    if (std::all_of(o.design_min.begin(), o.design_min.end(), [](double v) { return std::isinf(v); }) &&
        std::all_of(o.design_max.begin(), o.design_max.end(), [](double v) { return std::isinf(v); }))
      o.design_min.clear(), o.design_max.clear();
  } else {
    PARAFAB_INPUT_ERROR("parameters must be \"auto\" or a list of {\"face\", \"parameter\"}");
  }
}

// Bounds: "constraints" on the volume (ratios) and the mass; returns the density of a mass
// constraint (0: none).
double read_bounds(const occ::PartShape& part, const json& job, occ::ShapeOptimizationOptions& o) {
  const json constraints = job.value("constraints", json::array());
  double mass_density = 0;  // of a mass constraint (0: none)
  for (size_t i = 0; i < constraints.size(); ++i) {
    const std::string path = "constraints[" + std::to_string(i) + "]";
    const json& c = constraints[i];
    const json& t = fields::require(c, "type", path);
    if (t == "volume") {
      // Ratios of the volume as read: positive (a bound of 0 or below would silently be none).
      for (const char* key : {"max_ratio", "min_ratio"})
        if (c.contains(key) && !(number(c[key], path + "." + key) > 0))
          PARAFAB_INPUT_ERROR(path << "." << key << " must be a positive ratio V / V0, got " << c[key].dump());
      if (c.contains("max_ratio")) o.volume_max_ratio = number(c["max_ratio"], path + ".max_ratio");
      if (c.contains("min_ratio")) o.volume_min_ratio = number(c["min_ratio"], path + ".min_ratio");
    } else if (t == "mass") {
      // m = ρV: bounds on the mass are bounds on the volume, ρ from the entry or material.density.
      const json material = job.value("material", json::object());
      mass_density = c.contains("density") ? number(c["density"], path + ".density")
                                           : number(material.value("density", json(0.0)), "material.density");
      if (!(mass_density > 0))
        PARAFAB_INPUT_ERROR(path << ": a mass bound needs a positive density (" << path
                                 << ".density or material.density), got " << mass_density);
      if (!c.contains("max") && !c.contains("min")) PARAFAB_INPUT_ERROR(path << ": give max and/or min (mass)");
      if (c.contains("max")) {
        const double m = number(c["max"], path + ".max");
        if (!(m > 0)) PARAFAB_INPUT_ERROR(path << ".max must be positive, got " << m);
        o.volume_max = m / mass_density;
      }
      if (c.contains("min")) {
        const double m = number(c["min"], path + ".min");
        if (!(m > 0)) PARAFAB_INPUT_ERROR(path << ".min must be positive, got " << m);
        o.volume_min = m / mass_density;
      }
      if (o.volume_max > 0 && o.volume_min > 0 && !(o.volume_min <= o.volume_max))  // equal: keep the mass
        PARAFAB_INPUT_ERROR(path << ": min " << o.volume_min * mass_density << " must not exceed max "
                                 << o.volume_max * mass_density);
    } else {
      PARAFAB_INPUT_ERROR(path << ".type " << t.dump() << " is not supported (volume, mass)");
    }
  }
  // Lower and upper bounds (ratios, masses, or one of each) must not cross (equal bounds keep the
  // volume, as the wheel benchmark does with min_ratio = max_ratio = 1); the
  // optimizer turns masses into ratios of the start's volume (its rules' volume, OCCT's to
  // ~1e-12), so OCCT's volume of the part decides here.
  const bool has_min = o.volume_min_ratio > 0 || o.volume_min > 0, has_max = o.volume_max_ratio > 0 || o.volume_max > 0;
  if (has_min && has_max) {
    const double V = occ::part_info(part).volume;
    const double lo = std::max(o.volume_min_ratio, o.volume_min / V);
    const double hi = std::min(o.volume_max_ratio > 0 ? o.volume_max_ratio : INFINITY,
                               o.volume_max > 0 ? o.volume_max / V : INFINITY);
    if (!(lo <= hi))
      PARAFAB_INPUT_ERROR("constraints: the lower volume bound (" << lo << " of the part's volume " << V
                                                                   << ") is above the upper one (" << hi << ")");
  }
  return mass_density;
}

// The optimizer's options: iterations, steps, the augmented Lagrangian, the start.
void read_optimizer_options(const json& job, occ::ShapeOptimizationOptions& o) {
  if (job.contains("max_iterations")) {
    if (!job["max_iterations"].is_number_integer() || job["max_iterations"].get<int>() < 0)
      PARAFAB_INPUT_ERROR("max_iterations must be a non-negative integer");
    o.lbfgs.max_iterations = job["max_iterations"].get<int>();
  }
  if (job.contains("freeze_switches")) {
    if (!job["freeze_switches"].is_boolean())
      PARAFAB_INPUT_ERROR("freeze_switches must be true or false, got " << job["freeze_switches"].dump());
    o.freeze_switches = job["freeze_switches"].get<bool>();
  }
  if (job.contains("relative_improvement"))
    o.lbfgs.relative_improvement = number(job["relative_improvement"], "relative_improvement");
  if (job.contains("first_step")) o.lbfgs.first_step = number(job["first_step"], "first_step");
  if (job.contains("bound")) o.relative_bound = number(job["bound"], "bound");
  if (job.contains("max_outer")) {
    if (!job["max_outer"].is_number_integer() || job["max_outer"].get<int>() < 1)
      PARAFAB_INPUT_ERROR("max_outer must be a positive integer");
    o.max_outer = job["max_outer"].get<int>();
  }
  if (job.contains("estimate_multiplier")) {
    if (!job["estimate_multiplier"].is_boolean())
      PARAFAB_INPUT_ERROR("estimate_multiplier must be true or false, got " << job["estimate_multiplier"].dump());
    o.estimate_multiplier = job["estimate_multiplier"].get<bool>();
  }
  if (job.contains("start")) {
    // Design values to start from, one per entry of "parameters" (with max_iterations 0: apply
    // them and write the STEP, the route of tests/bench/bench_optimize_routes.py).
    const json& st = job["start"];
    if (!st.is_array() || st.size() != o.design.size())
      PARAFAB_INPUT_ERROR("start must be a list of " << o.design.size() << " numbers (one per parameters entry)");
    o.design_start.resize(st.size());
    for (size_t k = 0; k < st.size(); ++k) o.design_start[k] = number(st[k], "start[" + std::to_string(k) + "]");
  }
}

// Contradictory constraints: the nearest valid model is written beside the original (never
// as optimized.step) with a history naming what stays violated, and the run is an input error.
[[noreturn]] void refuse_infeasible(const occ::ShapeOptimizationResult& r, const std::string& out_dir,
                                    const std::string& part_path) {
  std::string written;
  if (!out_dir.empty()) {
    const std::string step = write_beside(*r.part, out_dir, "nearest_valid.step", part_path);
    // An optimized.step of an earlier run in this folder would now be mistaken for this run's.
    const std::string stale = out_dir + "/optimized.step";
    if (std::filesystem::weakly_canonical(stale) != std::filesystem::weakly_canonical(part_path))
      std::filesystem::remove(stale);
    json h{{"status", r.status}, {"message", r.message}, {"nearest_valid_step", step},
           {"tangency_residual_max", r.tangency_residual_max}, {"violated_constraints", json::array()},
           {"parameters", json::array()}, {"iterations", json::array()}, {"notes", r.notes}};
    for (const auto& v : r.violated_constraints) h["violated_constraints"].push_back({{"name", v.name}, {"value", v.value}});
    for (size_t k = 0; k < r.design_names.size(); ++k)
      h["parameters"].push_back({{"name", r.design_names[k]}, {"initial", r.design_initial[k]}, {"final", r.design_final[k]}});
    write_text_atomically(out_dir + "/history.json", h.dump(2) + "\n");
    written = "; the nearest valid model is written to " + step + " (not optimized; history.json lists the violations)";
  }
  PARAFAB_INPUT_ERROR("the constraints of " << part_path << " cannot all hold: " << r.message << written);
}

// The history JSON of a run (history.json without the output files).
json history_of(const occ::ShapeOptimizationResult& r, const occ::ShapeOptimizationOptions& o, double mass_density,
                const json& size_estimate) {
  json h;
  h["status"] = r.status;
  h["message"] = r.message;
  h["initial_objective"] = r.initial_objective;
  h["final_objective"] = r.final_objective;
  h["objective"] = o.objective.type;
  if (o.objective.type == "sum") {
    json terms = json::array();
    for (const auto& t : o.objective.terms) terms.push_back({{"type", t.type}, {"weight", t.weight}});
    h["objective_terms"] = terms;
    h["objective_normalized"] = o.objective.normalize;
  }
  h["initial_volume"] = r.initial_volume;
  h["final_volume"] = r.final_volume;
  if (mass_density > 0) {
    h["density"] = mass_density;
    h["initial_mass"] = mass_density * r.initial_volume;
    h["final_mass"] = mass_density * r.final_volume;
  }
  h["tangency_residual_max"] = r.tangency_residual_max;
  h["threads"] = tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism);
  h["gradient"] = r.gradient;
  if (!size_estimate.is_null()) h["estimate"] = size_estimate;
  if (r.exact_derivatives + r.semi_analytic_derivatives > 0) {
    h["exact_derivatives"] = r.exact_derivatives;
    h["semi_analytic_derivatives"] = r.semi_analytic_derivatives;
  }
  if (o.compliance) h["material_model"] = o.compliance->hyperelastic ? o.compliance->hyperelastic->name() : "linear";
  if (o.compliance)  // the clamp of the objectives that solve (entries near it differenced when local)
    h["nitsche_penalty"] =
        o.compliance->solver.nitsche_penalty == xfem::LinearXfemOptions::NitschePenalty::Local ? "local" : "fixed";
  if (o.compliance) h["nitsche_surface_degree"] = o.compliance->solver.dirichlet_surface_degree;
  if (o.compliance) {  // discrete switches frozen during line searches, accepted points re-evaluated
    h["freeze_switches"] = o.freeze_switches;
    h["switch_refreshes"] = r.switch_refreshes;
    h["frame_refreshes"] = r.frame_refreshes;
    if (o.compliance->merge.enabled)
      h["merge_penalty"] = {{"critical_fraction", o.compliance->merge.critical_fraction},
                            {"law", o.compliance->merge.law == occ::MergePenaltyOptions::Law::Log2 ? "log2" : "inverse_square"},
                            {"cap", o.compliance->merge.cap},
                            {"tied_evaluations", r.tied_evaluations},
                            {"max_ties", r.max_ties},
                            {"max_mode_tied_pairs", r.max_mode_tied_pairs}};
  }
  if (r.semi_analytic_derivatives > 0) {
    h["topology_switches"] = r.topology_switches;
    h["gradient_cells"] = r.gradient_cells;
  }
  if (const occ::ObjectiveSpec* failure_term = occ::failure_term(o.objective)) {
    h["initial_max_von_mises"] = r.initial_max_von_mises;
    h["final_max_von_mises"] = r.final_max_von_mises;
    h["yield_stress"] = failure_term->yield_stress;
    h["exponent"] = failure_term->exponent;
    h["normalize"] = failure_term->per_volume;
  }
  if (const occ::ObjectiveSpec* target_term = occ::target_term(o.objective)) {
    h["target_face"] = target_term->face;
    h["target"] = target_surface_json(r.target);
    h["target_given"] = target_term->has_target;  // false: the face's own surface as read
    h["initial_target_rms"] = r.initial_target_rms;
    h["final_target_rms"] = r.final_target_rms;
    h["initial_target_max"] = r.initial_target_max;
    h["final_target_max"] = r.final_target_max;
  }
  h["final_violation"] = r.final_violation;
  if (!r.outer.empty()) {
    h["volume_restored"] = r.volume_restored;
    h["augmented_lagrangian"] = json::array();
    for (const auto& a : r.outer)
      h["augmented_lagrangian"].push_back({{"outer", a.outer}, {"multiplier", a.multiplier}, {"penalty", a.penalty},
                                           {"violation", a.violation}, {"objective", a.objective},
                                           {"inner_status", a.inner_status}, {"inner_iterations", a.inner_iterations},
                                           {"evaluations", a.evaluations}});
  }
  h["evaluations"] = r.evaluations;
  h["invalid_models"] = r.invalid_models;
  h["failed_projections"] = r.failed_projections;
  h["seconds"] = r.seconds;
  h["notes"] = r.notes;
  h["iterations"] = json::array();
  for (const auto& it : r.iterations) {
    std::vector<double> values(it.design.data(), it.design.data() + it.design.size());
    h["iterations"].push_back({{"iteration", it.iteration},
                               {"objective", it.objective},
                               {"constraint_violation", it.constraint_violation},
                               {"outer", it.outer},
                               {"evaluations", it.evaluations},
                               {"tangency_residual", it.tangency_residual},
                               {"parameters", values},
                               {"seconds", it.seconds}});
  }
  h["parameters"] = json::array();
  for (size_t k = 0; k < r.design_names.size(); ++k) {
    json entry{{"name", r.design_names[k]}, {"initial", r.design_initial[k]}, {"final", r.design_final[k]}};
    // d objective / d parameter of the part as read (sensitivity; null if the start failed).
    entry["gradient_initial"] = k < static_cast<size_t>(r.initial_gradient.size()) ? json(r.initial_gradient[k]) : json();
    h["parameters"].push_back(entry);
  }
  return h;
}

// Runs argv[0] (an absolute path) with the arguments argv[1..] as they are, without a shell (a
// quote or a space in a path is just a character of it), its stdout and stderr to /dev/null, and
// waits for it; true when it exited with status 0.
bool run_quietly(const std::vector<std::string>& argv) {
  std::vector<char*> args;
  for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  posix_spawn_file_actions_t files;
  if (posix_spawn_file_actions_init(&files) != 0) return false;
  const bool redirected = posix_spawn_file_actions_addopen(&files, STDOUT_FILENO, "/dev/null", O_WRONLY, 0) == 0 &&
                          posix_spawn_file_actions_addopen(&files, STDERR_FILENO, "/dev/null", O_WRONLY, 0) == 0;
  pid_t pid = -1;
  const bool spawned = redirected && posix_spawn(&pid, args[0], &files, nullptr, args.data(), environ) == 0;
  posix_spawn_file_actions_destroy(&files);
  if (!spawned) return false;
  int status = 0;
  while (waitpid(pid, &status, 0) < 0)
    if (errno != EINTR) return false;
  return WIFEXITED(status) && WEXITSTATUS(status) == 0;
}

// Output: optimized.step, history.json and the chart (history.png, or "chart": null).
void write_outputs(json& h, const occ::ShapeOptimizationResult& r, const std::string& out_dir,
                   const std::string& part_path, bool chart) {
  h["optimized_step"] = write_beside(*r.part, out_dir, "optimized.step", part_path);
  const std::string history = out_dir + "/history.json";
  write_text_atomically(history, h.dump(2) + "\n");
  // The chart: a small matplotlib script (optional: the history is complete without it).
  const std::string python = "/usr/bin/python3", script = scripts_dir() + "/plot_optimization.py";
  const std::string png = out_dir + "/history.png";
  if (chart && std::filesystem::exists(script) && std::filesystem::exists(python)) {
    if (run_quietly({python, script, history, png}) && std::filesystem::exists(png)) h["chart"] = png;
  }
  if (!h.contains("chart")) h["chart"] = nullptr;
  write_text_atomically(history, h.dump(2) + "\n");
}

}  // namespace

json optimize_part_json(const std::string& part_path, const json& job, const std::string& out_dir,
                        const OptimizeProgressFn& progress, const InterruptFn& interrupted) {
  schema::check(job, schema::Format::Optimization);
  std::optional<FolderLock> lock;  // one run at a time in a folder
  if (!out_dir.empty()) {  // before the work, not after it
    require_writable_folder(out_dir);
    lock.emplace(out_dir);
    for (const char* name : {"optimized.step", "history.json", "history.png", "nearest_valid.step"})
      refuse_output_over_input(out_dir + "/" + name, part_path);
  }
  // "chart": false skips OUTDIR/history.png (matplotlib, ~1 s): scripted and repeated runs.
  if (job.contains("chart") && !job["chart"].is_boolean())
    PARAFAB_INPUT_ERROR("chart must be true or false, got " << job["chart"].dump());
  const bool chart = job.value("chart", true);
  // "threads": worker threads of the whole run (0 or absent: all cores), as in `parafab simulate`.
  if (job.contains("threads") && (!job["threads"].is_number_integer() || job["threads"].get<int>() < 0))
    PARAFAB_INPUT_ERROR("threads must be an integer >= 1 (or 0: all cores), got " << job["threads"].dump());
  const int threads = job.value("threads", 0);
  std::optional<tbb::global_control> thread_limit;
  if (threads > 0) thread_limit.emplace(tbb::global_control::max_allowed_parallelism, threads);
  const auto part = occ::read_part(part_path);
  const NamedPart named(*part);
  occ::ShapeOptimizationOptions o;

  const json size_estimate = read_objective(named, *part, job, o);
  read_parameterization(named, job, o);
  read_design(named, *part, job, o);
  const double mass_density = read_bounds(*part, job, o);
  read_optimizer_options(job, o);

  o.interrupted = interrupted;
  occ::ShapeProgress report;
  if (progress)
    report = [&](const occ::ShapeIterate& it) {
      return progress(json{{"iteration", it.iteration},
                           {"objective", it.objective},
                           {"constraint_violation", it.constraint_violation},
                           {"seconds", it.seconds}});
    };
  const occ::ShapeOptimizationResult r = occ::optimize_shape(*part, o, report);
  if (!r.part) PARAFAB_INPUT_ERROR("optimization of " << part_path << " could not start: " << r.message);
  if (r.status == "infeasible_constraints") refuse_infeasible(r, out_dir, part_path);
  json h = history_of(r, o, mass_density, size_estimate);
  if (!out_dir.empty()) write_outputs(h, r, out_dir, part_path, chart);
  return h;
}

}  // namespace parafab::entry
