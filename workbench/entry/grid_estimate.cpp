#include "grid_estimate.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <sstream>

#include "common/error.h"
#include "json_fields.h"

namespace parafab::entry {

// Measured with `/usr/bin/time -f %M parafab integrate PART --cells 16|32` (l_bracket, ring,
// housing; 2026-11-23): peak memory grows by 0.006–0.009 MB per cut cell above a base of about
// 45 MB, and the cut plus rules take 2.5 ms per cut cell on a quiet machine (the cut-cell
// benchmark of that day, when the splitter dominated; current figures in tests/bench/README.md).
// The cut-cell count 1.0 · area / h² was 1.4–1.6× the cells actually cut at 32 cells (2.2× at
// 16 on the housing): on the safe side.
constexpr double kBaseMb = 45;
constexpr double kMbPerCutCell = 0.012;
constexpr double kMbPerCell = 0.0005;
constexpr double kSecondsPerCutCell = 3e-3;

xfem::ElementType element_of_job(const nlohmann::json& job, xfem::ElementType default_element) {
  if (!job.contains("element")) return default_element;
  if (!job["element"].is_string()) PARAFAB_INPUT_ERROR("element must be \"hex8\" or \"hex27\", got " << job["element"].dump());
  return xfem::element_type_from_name(job["element"].get<std::string>(), "element");
}

// The iterative path's memory per unknown above "the rest of the run" (hex8; hex27 rows hold
// about 2.4× the entries, not measured): PETSc's copy of the matrix (about 81 entries of 12
// bytes per row) with GAMG's hierarchy. Measured peaks (tests/bench/README.md, "The solve at
// scale"): 4.3–5.2 kB per unknown in all (turned L-bracket 369,192 and 822,012 unknowns, turned
// box 1,333,296), against 6 kB estimated with this figure: on the safe side.
constexpr double kIterativeMbPerDof = 1.0e-3;

SolveEstimate estimate_solve(const occ::PartInfo& part, double h, xfem::ElementType element, bool iterative) {
  const Eigen::Vector3d ext = part.bbox_max - part.bbox_min;
  const bool quadratic = element == xfem::ElementType::Hex27;
  const double m = quadratic ? 2 : 1;
  const double box_nodes = (m * std::ceil(ext.x() / h) + 1) * (m * std::ceil(ext.y() / h) + 1) * (m * std::ceil(ext.z() / h) + 1);
  const double nodes = m * m * m * part.volume / (h * h * h) + (quadratic ? 2.0 : 1.5) * m * m * part.area / (h * h);
  SolveEstimate e;
  e.dofs = 3 * std::min(box_nodes, nodes);
  auto factor = [&](double C) { return 8.0 * C * e.dofs * std::cbrt(e.dofs) / 1e6; };
  e.factor_mb = factor(26), e.factor_mb_min = factor(7);
  const double rest = 50 + (quadratic ? 9e-3 : 5e-3) * e.dofs;
  e.peak_mb = rest + e.factor_mb, e.peak_mb_min = rest + e.factor_mb_min;
  if (iterative) {
    e.iterative = true;
    e.factor_mb = e.factor_mb_min = 0;
    e.peak_mb = e.peak_mb_min = rest + (quadratic ? 2.4 : 1.0) * kIterativeMbPerDof * e.dofs;
  }
  return e;
}

void solver_of_job(const nlohmann::json& job, xfem::LinearXfemOptions& options) {
  if (!job.contains("solver")) return;
  const nlohmann::json& s = job["solver"];
  if (!s.is_object()) PARAFAB_INPUT_ERROR("solver must be an object {type, ksp, pc, rtol, max_iterations, petsc_from}, got " << s.dump());
  using Type = xfem::LinearXfemOptions::Solver::Type;
  xfem::LinearXfemOptions::Solver& o = options.solver;
  if (s.contains("type")) {
    const nlohmann::json& t = s["type"];
    if (t == "auto") o.type = Type::Auto;
    else if (t == "cholmod") o.type = Type::Cholmod;
    else if (t == "petsc") o.type = Type::Petsc;
    else PARAFAB_INPUT_ERROR("solver.type must be \"auto\", \"cholmod\" or \"petsc\", got " << t.dump());
  }
  if (o.type == Type::Petsc && !xfem::petsc_available()) xfem::petsc_initialize();  // throws: says why not
  auto text = [&](const char* key, std::string& out) {
    if (!s.contains(key)) return;
    if (!s[key].is_string() || s[key].get<std::string>().empty())
      PARAFAB_INPUT_ERROR("solver." << key << " must be a PETSc type name such as \"" << out << "\", got " << s[key].dump());
    out = s[key].get<std::string>();
  };
  text("ksp", o.krylov.ksp);
  text("pc", o.krylov.pc);
  if (s.contains("rtol")) {
    o.krylov.rtol = fields::number(s["rtol"], "solver.rtol");
    if (!(o.krylov.rtol > 0 && o.krylov.rtol < 1)) PARAFAB_INPUT_ERROR("solver.rtol must be in (0, 1), got " << o.krylov.rtol);
  }
  if (s.contains("max_iterations")) o.krylov.max_iterations = fields::integer(s["max_iterations"], "solver.max_iterations", 1, 1000000000);
  if (s.contains("petsc_from")) o.petsc_from = fields::integer(s["petsc_from"], "solver.petsc_from", 0, 2147483647);
}

bool iterative_solve(const xfem::LinearXfemOptions& options, double unknowns) {
  using Type = xfem::LinearXfemOptions::Solver::Type;
  if (options.solver.type != Type::Auto) return options.solver.type == Type::Petsc;
  return (unknowns >= options.solver.petsc_from || xfem::launched_ranks() > 1) && xfem::petsc_available();
}

void cut_of_job(const nlohmann::json& grid, occ::GridOptions& options) {
  if (grid.contains("method") && grid["method"] != "face")
    PARAFAB_INPUT_ERROR("grid.method: the only route is \"face\" (cut by face); OCCT's Boolean splitter is kept "
                        "only as the tests' reference, got "
                        << grid["method"].dump());
  if (grid.contains("block_cells"))
    PARAFAB_INPUT_ERROR("grid.block_cells: blocks belonged to the splitter route, which is kept only as the tests' "
                        "reference; the face route cuts and re-cuts by cell (remove the field)");
  options.method = occ::CutMethod::FaceCut;
}

void nitsche_of_job(const nlohmann::json& job, xfem::LinearXfemOptions& options, bool linear_model) {
  using Penalty = xfem::LinearXfemOptions::NitschePenalty;
  // The default where the job names no penalty: local where it was measured better (the linear
  // model on hex27), fixed elsewhere (resources/doc/simulation.md, "Local Nitsche penalty").
  options.nitsche_penalty =
      linear_model && options.element == xfem::ElementType::Hex27 ? Penalty::Local : Penalty::Fixed;
  if (job.contains("nitsche_penalty")) {
    const nlohmann::json& np = job["nitsche_penalty"];
    if (np == "fixed") options.nitsche_penalty = Penalty::Fixed;
    else if (np == "local") options.nitsche_penalty = Penalty::Local;
    else PARAFAB_INPUT_ERROR("nitsche_penalty must be \"fixed\" (beta E/h) or \"local\" (from each clamped cut cell's eigenvalue), got " << np.dump());
  } else if (job.contains("nitsche_beta")) {
    options.nitsche_penalty = Penalty::Fixed;  // a β names the fixed penalty β E/h
  }
  const bool local = options.nitsche_penalty == Penalty::Local;
  if (job.contains("nitsche_beta")) {
    if (local)
      PARAFAB_INPUT_ERROR("nitsche_beta sets the fixed penalty beta E/h; with \"nitsche_penalty\": \"local\" it would not be used (give nitsche_local_factor instead)");
    options.nitsche_beta = fields::number(job["nitsche_beta"], "nitsche_beta");
    if (!(options.nitsche_beta > 0))  // the solver would read 0 as "default 100"
      PARAFAB_INPUT_ERROR("nitsche_beta must be positive, got " << options.nitsche_beta);
  }
  if (job.contains("nitsche_surface_degree"))  // patch rules on curved clamped faces (default 8)
    options.dirichlet_surface_degree = fields::integer(job["nitsche_surface_degree"], "nitsche_surface_degree", 2, 20);
  if (job.contains("nitsche_local_factor")) {
    if (!local)
      PARAFAB_INPUT_ERROR("nitsche_local_factor applies to \"nitsche_penalty\": \"local\" only (the fixed penalty is set by nitsche_beta)");
    options.nitsche_local_factor = fields::number(job["nitsche_local_factor"], "nitsche_local_factor");
    if (!(options.nitsche_local_factor > 1))
      PARAFAB_INPUT_ERROR("nitsche_local_factor must be > 1 (below, the clamped cut cells' terms may be indefinite), got " << options.nitsche_local_factor);
  }
}

void refuse_loaded_supports(const std::vector<xfem::DirichletCondition>& supports,
                            const std::vector<xfem::TractionCondition>& loads) {
  for (size_t i = 0; i < supports.size(); ++i)
    for (size_t j = 0; j < loads.size(); ++j)
      if (supports[i].face == loads[j].face)
        PARAFAB_INPUT_ERROR("supports[" << i << "] and loads[" << j << "] are both on face " << supports[i].face
                                        << ": a supported face takes no load (clamp one face, load another)");
}

std::string amount(double x) {
  if (!std::isfinite(x)) return x > 0 ? "infinitely many" : "an undefined number of";
  if (std::fabs(x) < 1e15) return std::to_string(std::llround(x));
  std::ostringstream os;
  os.precision(2);
  os << x;
  return os.str();
}

int default_cells(xfem::ElementType element) { return element == xfem::ElementType::Hex27 ? 8 : 16; }

GridEstimate estimate_grid(const occ::PartInfo& part, const occ::GridOptions& grid) {
  GridEstimate e;
  const Eigen::Vector3d ext = part.bbox_max - part.bbox_min;
  const double h = grid.cell_size > 0 ? grid.cell_size : ext.maxCoeff() / std::max(grid.cells_longest, 1);
  e.cells_total = 1;
  for (int a = 0; a < 3; ++a) {
    e.cells[a] = std::max(1.0, std::ceil(ext[a] / h - 1e-9) + (grid.anchored ? 1 : 0));
    e.cells_total *= e.cells[a];
  }
  e.cut_cells = std::min(e.cells_total, part.area / (h * h));
  e.memory_mb = kBaseMb + kMbPerCutCell * e.cut_cells + kMbPerCell * e.cells_total;
  e.seconds = kSecondsPerCutCell * e.cut_cells;
  e.physical_mb = static_cast<double>(sysconf(_SC_PHYS_PAGES)) * sysconf(_SC_PAGE_SIZE) / 1e6;
  e.fits = e.memory_mb <= 0.7 * e.physical_mb;
  return e;
}

nlohmann::json to_json(const GridEstimate& e) {
  return {{"cells", e.cells},         {"cells_total", e.cells_total}, {"cut_cells", e.cut_cells},
          {"memory_mb", e.memory_mb}, {"seconds", e.seconds},         {"physical_mb", e.physical_mb},
          {"fits", e.fits}};
}

void refuse_if_too_big(const GridEstimate& e, const std::string& what, const std::string& override_hint) {
  if (e.fits) return;
  PARAFAB_INPUT_ERROR(what << " has about " << amount(e.cells_total) << " cells (" << amount(e.cells[0]) << " x "
                           << amount(e.cells[1]) << " x " << amount(e.cells[2]) << ", about " << amount(e.cut_cells)
                           << " of them cut) and needs about " << amount(e.memory_mb) << " MB and "
                           << amount(e.seconds) << " s for cutting, more than 70% of the " << amount(e.physical_mb)
                           << " MB of memory: " << override_hint);
}

}  // namespace parafab::entry
