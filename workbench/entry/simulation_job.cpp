#include "simulation_job.h"

#include <unistd.h>

#include <cmath>

#include "common/error.h"
#include "json_fields.h"
#include "xfem/sparse_cholesky.h"

namespace parafab::entry {

using nlohmann::json;
using fields::number;
using fields::vec3;

NamedPart::NamedPart(const occ::PartShape& p)
    : part(p), tolerance(1e-6 * occ::part_box(p).diagonal() + 1e-9) {}  // the tight box, without part_info's integrals

NamedPart::NamedPart(const occ::PartShape& p, double tol, const Eigen::Vector3d& frame_origin, bool entry)
    : part(p), tolerance(tol), origin(frame_origin), entry_in_errors(entry) {}

NamedPart::~NamedPart() = default;

const occ::FaceLocator& NamedPart::locator() const {
  if (!locator_) locator_ = std::make_unique<occ::FaceLocator>(part);
  return *locator_;
}

int face_index(const NamedPart& named, const json& item, const std::string& path) {
  if (item.contains("face")) {
    if (!item["face"].is_number_integer()) PARAFAB_INPUT_ERROR(path << ".face must be a face index");
    const int f = item["face"].get<int>();
    occ::face_area(named.part, f);  // validates the index
    return f;
  }
  if (item.contains("point")) {
    const Eigen::Vector3d X = vec3(item["point"], path + ".point") - named.origin;
    if (!named.entry_in_errors) return named.locator().face_at(X, named.tolerance);
    try {
      return named.locator().face_at(X, named.tolerance);
    } catch (const Error& e) {
      PARAFAB_INPUT_ERROR(path << ": " << e.what());  // which entry named the point
    }
  }
  PARAFAB_INPUT_ERROR(path << " needs \"face\" (index from parafab inspect) or \"point\" (on the face)");
}

// The two commands' defaults, in one place.
SimulationJobOptions SimulationJobOptions::simulate() {
  SimulationJobOptions o;
  o.command = JobCommand::Simulate;
  // hex27 (triquadratic Lagrange) by default: resources/doc/simulation.md ("Element") gives the
  // measurements that chose it.
  o.default_element = xfem::ElementType::Hex27;
  o.hyperelastic_ok = true;
  return o;
}

SimulationJobOptions SimulationJobOptions::optimize(bool hyperelastic_ok) {
  SimulationJobOptions o;
  o.command = JobCommand::Optimize;
  // hex8 by default (unlike `parafab simulate`): the optimizer's gradient checks and figures were
  // measured with it, and a solve costs less (resources/doc/simulation.md, "Element"); a job may
  // name hex27.
  o.default_element = xfem::ElementType::Hex8;
  o.hyperelastic_ok = hyperelastic_ok;
  return o;
}

namespace {

// "material" {E, nu, density, model} and "load_steps" (its range is the schema's).
void parse_material(const json& job, const SimulationJobOptions& options, SimulationJob::Material& out) {
  const bool simulate = options.command == JobCommand::Simulate;
  if (simulate && !job.contains("material")) PARAFAB_INPUT_ERROR("missing material {E, nu[, density]}");
  const json& m = simulate ? job["material"] : fields::require(job, "material", "job (objective compliance)");
  xfem::ElasticMaterial& mat = out.elastic;
  mat.youngs_modulus = number(simulate ? m.value("E", json()) : fields::require(m, "E", "material"), "material.E");
  mat.poisson_ratio = number(m.value("nu", json(0.3)), "material.nu");
  mat.density = number(m.value("density", json(0.0)), "material.density");
  if (!(mat.youngs_modulus > 0)) PARAFAB_INPUT_ERROR("material.E must be positive, got " << mat.youngs_modulus);
  if (!(mat.poisson_ratio > -1 && mat.poisson_ratio < 0.5))
    PARAFAB_INPUT_ERROR("material.nu must be in (-1, 0.5), got " << mat.poisson_ratio);
  // "linear" (small strain, one linear solve) or a hyperelastic law solved by Newton.
  out.model = m.value("model", std::string("linear"));
  if (out.model != "linear") {
    if (!options.hyperelastic_ok)
      PARAFAB_INPUT_ERROR("material.model \"" << out.model << "\": compliance and failure run on a linear solve (a "
                                                 "hyperelastic law serves the target objective only); use \"linear\"");
    out.law = xfem::make_material(out.model, mat.youngs_modulus, mat.poisson_ratio);
  }
  out.load_steps = static_cast<int>(number(job.value("load_steps", json(out.load_steps)), "load_steps"));
}

// "element", "grid" and "quadrature"; the element comes first (the default cells follow it).
void parse_grid(const NamedPart& part, const json& job, const SimulationJobOptions& options, SimulationJob& out) {
  // The basis on the grid: "hex27" (triquadratic Lagrange) or "hex8" (trilinear with
  // incompatible modes); the rules of uncut and cut cells are raised to match.
  out.solver.element = element_of_job(job, options.default_element);
  occ::GridModelOptions& go = out.grid.options;
  const json grid = job.value("grid", json::object());
  if (options.command == JobCommand::Optimize && grid.contains("target"))
    PARAFAB_INPUT_ERROR("objective compliance: grid.target is not supported (the grid stays fixed)");
  // grid.cells and quadrature's integers: ranges are the schema's.
  go.grid.cells_longest = static_cast<int>(number(grid.value("cells", json(default_cells(out.solver.element))), "grid.cells"));
  go.grid.cell_size = number(grid.value("cell_size", json(0.0)), "grid.cell_size");
  if (grid.contains("origin")) {  // grid planes through this point (default: centred on the part)
    go.grid.anchored = true;
    go.grid.origin = vec3(grid["origin"], "grid.origin") - part.origin;
  }
  // Volume-rule tuning (thesis §6.3.3): flux refinement of curved patches.
  const json quad = job.value("quadrature", json::object());
  go.rule.max_depth = static_cast<int>(number(quad.value("max_depth", json(go.rule.max_depth)), "quadrature.max_depth"));
  go.rule.flux_tolerance = number(quad.value("flux_tolerance", json(go.rule.flux_tolerance)), "quadrature.flux_tolerance");
  go.rule.flux_degree_boost =
      static_cast<int>(number(quad.value("degree_boost", json(go.rule.flux_degree_boost)), "quadrature.degree_boost"));
  if (!(go.rule.flux_tolerance >= 0))
    PARAFAB_INPUT_ERROR("quadrature.flux_tolerance must be >= 0, got " << go.rule.flux_tolerance);
  // Cut by face; a grid the face route cannot cut is shifted and cut again
  // (GridOptions::shift_retries), the reason in the result's grid.retry_reason. The optimizer's
  // perturbed models are re-cut by cell on the run's fixed grid.
  cut_of_job(grid, go.grid);
  go = occ::rules_for_element(out.solver.element, go);
}

// "supports", "loads" (a traction per area, or a total force spread evenly over the face) and
// "gravity".
void parse_conditions(const NamedPart& part, const json& job, const SimulationJobOptions& options, SimulationJob& out) {
  const bool simulate = options.command == JobCommand::Simulate;
  SimulationJob::Conditions& c = out.conditions;
  const json supports = job.value("supports", json::array());
  if (!supports.is_array() || supports.empty()) {
    if (simulate)
      PARAFAB_INPUT_ERROR("supports must list at least one face ({\"face\": i} or {\"point\": [x,y,z]}), "
                          "or the part floats freely");
    PARAFAB_INPUT_ERROR("objective compliance needs supports (a list of {\"face\": i} or {\"point\": [x,y,z]})");
  }
  for (size_t i = 0; i < supports.size(); ++i) {
    const std::string path = "supports[" + std::to_string(i) + "]";
    xfem::DirichletCondition d;
    d.face = face_index(part, supports[i], path);
    if (supports[i].contains("displacement")) d.offset = vec3(supports[i]["displacement"], path + ".displacement");
    c.supports.push_back(d);
  }
  const json loads = job.value("loads", json::array());
  for (size_t i = 0; i < loads.size(); ++i) {
    const std::string path = "loads[" + std::to_string(i) + "]";
    xfem::TractionCondition t;
    t.face = face_index(part, loads[i], path);
    xfem::Vec3 force = xfem::Vec3::Zero();
    if (loads[i].contains("traction")) {
      t.traction = vec3(loads[i]["traction"], path + ".traction");
    } else if (loads[i].contains("force")) {
      force = vec3(loads[i]["force"], path + ".force");
      t.traction = force / occ::face_area(part.part, t.face);
    } else {
      PARAFAB_INPUT_ERROR(path << " needs \"traction\" (per area) or \"force\" (total, spread evenly)");
    }
    c.loads.push_back(t);
    c.forces.push_back(force);
  }
  refuse_loaded_supports(c.supports, c.loads);
  if (job.contains("gravity")) out.solver.gravity = vec3(job["gravity"], "gravity");
  if (!simulate && loads.empty() && !job.contains("gravity"))
    PARAFAB_INPUT_ERROR("objective compliance needs loads or gravity");
}

// The Nitsche penalty, "incompatible_modes" and "reuse" (its keys and types are the schema's).
void parse_solver_options(const json& job, SimulationJob& out) {
  xfem::LinearXfemOptions& so = out.solver;
  // Fixed β·E/h or the local penalty (default: local for the linear model on hex27).
  nitsche_of_job(job, so, out.material.linear());
  solver_of_job(job, so);  // CHOLMOD, PETSc, or auto (xfem::LinearXfemOptions::Solver)
  // Linear model only; Newton uses plain hexahedra (and hex27 has none).
  if (job.contains("incompatible_modes")) so.incompatible_modes = job["incompatible_modes"].get<bool>();
  // What an update (a re-solve after a re-cut) reuses of the previous solve: element matrices
  // of unchanged elements, and the factorization as CG preconditioner (xfem::LinearXfemOptions::Reuse).
  if (job.contains("reuse")) {
    const json& ru = job["reuse"];
    if (ru.contains("elements")) so.reuse.elements = ru["elements"].get<bool>();
    if (ru.contains("factorization")) so.reuse.factorization = ru["factorization"].get<bool>();
    so.reuse.pcg.tolerance = number(ru.value("tolerance", json(so.reuse.pcg.tolerance)), "reuse.tolerance");
    if (!(so.reuse.pcg.tolerance > 0 && so.reuse.pcg.tolerance < 1))
      PARAFAB_INPUT_ERROR("reuse.tolerance must be in (0, 1) (a relative residual), got " << so.reuse.pcg.tolerance);
    so.reuse.pcg.max_iterations =
        static_cast<int>(number(ru.value("max_iterations", json(so.reuse.pcg.max_iterations)), "reuse.max_iterations"));
  }
}

// "threads", grid.target and grid.max_cells, "memory_limit_mb" (into solver.memory_limit_mb:
// the exact check before the factorization).
void parse_run(const json& job, SimulationJob& out) {
  SimulationJob::Run& run = out.run;
  run.threads = static_cast<int>(number(job.value("threads", json(run.threads)), "threads"));
  // An accuracy target instead of a fixed grid: grids refined by 1.5 from grid.cells (default half
  // the default grid: 8 hex8 or 4 hex27 cells) until the estimated relative error of the results
  // is below the target (SimulationSession::run).
  const json grid = job.value("grid", json::object());
  occ::GridOptions& g = out.grid.options.grid;
  run.target = number(grid.value("target", json(run.target)), "grid.target");
  run.max_cells = static_cast<int>(number(grid.value("max_cells", json(run.max_cells)), "grid.max_cells"));
  if (run.target < 0 || run.target >= 1) PARAFAB_INPUT_ERROR("grid.target must be in (0, 1) (a relative error), got " << run.target);
  if (run.target > 0 && g.cell_size > 0) PARAFAB_INPUT_ERROR("grid.target chooses the cells: drop grid.cell_size");
  if (run.target > 0 && !grid.contains("cells")) g.cells_longest = default_cells(out.solver.element) / 2;
  out.solver.memory_limit_mb = xfem::SparseCholesky::default_memory_limit_mb();  // 70% of the memory
  if (job.contains("memory_limit_mb")) {
    out.solver.memory_limit_mb = number(job["memory_limit_mb"], "memory_limit_mb");
    if (!(out.solver.memory_limit_mb > 0))
      PARAFAB_INPUT_ERROR("memory_limit_mb must be positive (MB), got " << job["memory_limit_mb"].dump());
  }
}

}  // namespace

SimulationJob parse_simulation_job(const NamedPart& part, const json& job, const SimulationJobOptions& options) {
  SimulationJob out;
  parse_material(job, options, out.material);
  parse_grid(part, job, options, out);
  parse_conditions(part, job, options, out);
  parse_solver_options(job, out);
  parse_run(job, out);
  return out;
}

occ::PartInfo size_info(const occ::PartBoxArea& size) {
  occ::PartInfo info;
  info.bbox_min = size.min, info.bbox_max = size.max, info.area = size.area, info.volume = size.volume;
  return info;
}

// Estimate before running, from the part's box, volume V and area A only. Calibrated on the
// eight sample parts, hex8 on 16–48 and hex27 on 8–24 cells (resources/doc/simulation.md,
// "Estimate first, then the exact factor size"):
// - DOF nodes m³V/h³ inside plus b·m²A/h² along the surface (the cut cells' outer nodes and the
//   enriched copies), m = 1 (hex8) or 2 (hex27): b was 0.5 (the aligned box) to 1.4 for hex8
//   and 1.2 to 2.0 for hex27 (2.9 once, the wrench on 8 cells: 1,152 unknowns). b = 1.5 / 2.0.
// - The factor: 8 bytes · C · n^{4/3} (nested-dissection fill), C = 5.1–15 on the thin-walled
//   parts (the wrench's coarse grids lowest) and 17.6–25.8 on the compact ones. The box and the
//   area do not tell which: factor_mb takes C = 26, factor_mb_min C = 7.
// - The rest of the run: 5 (hex8) or 9 (hex27) kB per unknown above about 50 MB.
// - With PETSc: linear in the unknowns instead (estimate_solve, iterative).
JobSize estimate_job_size(const occ::PartInfo& info, const occ::GridOptions& grid, const xfem::LinearXfemOptions& solver) {
  JobSize s;
  const double h = grid.cell_size > 0 ? grid.cell_size : (info.bbox_max - info.bbox_min).maxCoeff() / grid.cells_longest;
  s.solve = estimate_solve(info, h, solver.element);
  // The iterative path's memory (linear in the unknowns) where the solve will take it.
  if (iterative_solve(solver, s.solve.dofs)) s.solve = estimate_solve(info, h, solver.element, true);
  s.cut = estimate_grid(info, grid);
  s.limit_mb = solver.memory_limit_mb;
  s.physical_mb = static_cast<double>(sysconf(_SC_PHYS_PAGES)) * sysconf(_SC_PAGE_SIZE) / 1e6;
  return s;
}

void refuse_if_too_big(const JobSize& size, JobCommand command) {
  const SolveEstimate& e = size.solve;
  if (e.peak_mb_min > size.limit_mb) {
    if (command == JobCommand::Simulate)
      PARAFAB_INPUT_ERROR("this grid needs at least about " << amount(e.peak_mb_min) << " MB (" << amount(e.dofs)
                          << " unknowns; " << amount(e.peak_mb) << " MB for a compact part), more than the "
                          << amount(size.limit_mb) << " MB allowed (memory_limit_mb; default 70% of the "
                          << amount(size.physical_mb) << " MB of memory): use fewer cells");
    PARAFAB_INPUT_ERROR("this grid needs at least about " << amount(e.peak_mb_min) << " MB per evaluation ("
                        << amount(e.dofs) << " unknowns), more than the " << amount(size.limit_mb)
                        << " MB allowed (70% of the memory): use fewer cells (grid.cells) or a larger grid.cell_size");
  }
  refuse_if_too_big(size.cut, "this grid", "use fewer cells (grid.cells) or a larger grid.cell_size");
}

}  // namespace parafab::entry
